"""The article's scene and settings, exactly as docs/article.md states them ("Scene",
"Camera and screen"), and its shading model (``ArticleShading``: the Whitted integrator's
shading in article semantics).

The article works in its own coordinates (Y up, camera looking down -Z); Glint keeps them.

The article's shading is Blinn-Phong (``core.shading``), every quirk kept:
  * dot products are not clamped (a point facing away from the light gets negative diffuse);
  * H = normalize(L + V) with V towards the CAMERA position, on every bounce;
  * the shadow ray starts at P + 1e-5 N and the point is in shadow if a sphere is hit (both
    roots positive) nearer than |light - P|; a shadowed point adds nothing, not even ambient,
    and ends the path (with several lights: a light that is blocked adds nothing, and the path
    ends where every light is blocked);
  * the lights' radii are ignored (the article's light is a point).
"""

from __future__ import annotations

import numpy as np

from .camera import ScreenCamera
from .light_sources import PointLight
from .materials import Material
from .rays import ARTICLE_OFFSET, RayBatch, RayStats, timed
from .scene import Scene, Sphere
from .settings import RenderSettings
from .shading import SHADOW_CODE_BASE, WhittedShading, column, specular_power
from .vectors import dot, length, normalize_in_place

ARTICLE_WIDTH, ARTICLE_HEIGHT = 300, 200
ARTICLE_MAX_DEPTH = 3
ARTICLE_LIGHT = (5.0, 5.0, 5.0)
ARTICLE_EYE = (0.0, 0.0, 1.0)


def _material(ambient, diffuse) -> Material:
    return Material(ambient=ambient, diffuse=diffuse, specular=(1.0, 1.0, 1.0),
                    shininess=100.0, reflection=0.5)


def article_spheres() -> tuple[Sphere, ...]:
    """The four spheres in the article's order (the order breaks ties)."""
    return (
        Sphere((-0.2, 0.0, -1.0), 0.7, _material((0.1, 0, 0), (0.7, 0, 0)), "red"),
        Sphere((0.1, -0.3, 0.0), 0.1, _material((0.1, 0, 0.1), (0.7, 0, 0.7)), "magenta"),
        Sphere((-0.3, 0.0, 0.0), 0.15, _material((0, 0.1, 0), (0, 0.6, 0)), "green"),
        Sphere((0.0, -9000.0, 0.0), 9000.0 - 0.7,
               _material((0.1, 0.1, 0.1), (0.6, 0.6, 0.6)), "floor"),
    )


def article_scene(width: int = ARTICLE_WIDTH, height: int = ARTICLE_HEIGHT) -> Scene:
    """The article's scene seen through its screen camera at width x height."""
    return Scene(
        camera=ScreenCamera(width=width, height=height, eye=ARTICLE_EYE),
        spheres=article_spheres(),
        lights=(PointLight(ARTICLE_LIGHT, name="light"),),
    )


def article_settings(**overrides) -> RenderSettings:
    """The article's semantics, depth 3, float64 (the reference's precision)."""
    values = dict(semantics="article", precision="float64", max_depth=ARTICLE_MAX_DEPTH)
    values.update(overrides)
    return RenderSettings(**values)


def article_light_blocked(ctx, origin, directions, distance, start,
                          stats: RayStats):
    """Whether the article's shadow rays of m points are blocked, (m,) bool.  origin: the
    light's ``SharedOrigin``; directions: (3, m) unit vectors from the light towards the
    shifted points S; distance: (m,) how far they are; start: (m,) |light - P|.  Blocked
    if the reversed ray S -> light meets a sphere (both roots positive) nearer than
    ``start``, i.e. its far root from the light lies in (distance - start, distance)
    (``ArticleRules.blocks``)."""
    light = origin.position[:, None]      # float64: the geometry's culling works in it
    segments = RayBatch(light, directions, distance - start, distance, origin)
    return ctx.geometry.occluded(segments, stats)


@timed("seconds_shading")
def shade_article(ctx, points, normals, directions, materials, exclude,
                  stats: RayStats, *, shares=None, terminator=None, world_shift=None,
                  world_noise=None):
    """The article's shading (module docstring) at m points, with ``core.shading.shade``'s
    arguments and answer; directions, exclude, shares, terminator, world_shift and
    world_noise play no part (the camera sets the half vector, the article's rules exclude
    nothing and lift nothing, its lights are points, and it has no world).  Per light, every
    product of a material's coefficient and the light's intensity comes from the table
    (``LightTerms``), the vectors are normalised in place, and the terms are summed row by
    row: the same values as the article's expression, in fewer passes."""
    lights = ctx.lights
    dtype = points.dtype
    m = points.shape[1]
    shifted = ARTICLE_OFFSET * normals
    shifted += points
    to_camera = column(ctx.eye, dtype) - points
    normalize_in_place(to_camera)
    colour = None
    goes_on = np.zeros(m, bool)
    shadow_code = np.zeros(m, np.uint64)
    exponents = ctx.materials.exponent
    for light in range(len(lights)):
        position = column(lights.positions[light], dtype)
        from_light = shifted - position
        shifted_distance = normalize_in_place(from_light)
        blocked = article_light_blocked(ctx, lights.origins[light][0], from_light,
                                        shifted_distance, length(position - points), stats)
        # H = normalize(to_light + to_camera), with to_light = -from_light.
        half = to_camera - from_light
        normalize_in_place(half)
        lit = -dot(from_light, normals)        # the article's -(L.N) with L from the light
        spread = specular_power(materials, exponents, dot(normals, half))
        table = ctx.light_terms[light]
        unblocked = ~blocked
        term = np.empty_like(points)
        for row in range(3):
            # ka Ia - kd Id (from_light . N) + ks Is (N.H)^e, as the article adds them
            part = table.ambient[row].take(materials)
            diffuse = table.diffuse[row].take(materials)
            diffuse *= lit
            part += diffuse   # (- kd Id (f.N) is + kd Id (-(f.N)) exactly)
            specular = table.specular[row].take(materials)
            specular *= spread
            part += specular
            np.multiply(part, unblocked, out=term[row])
        colour = term if colour is None else np.add(colour, term, out=colour)
        goes_on |= unblocked
        shadow_code = shadow_code * np.uint64(SHADOW_CODE_BASE) + unblocked.astype(np.uint64)
    if colour is None:
        colour = np.zeros_like(points)
    return colour, goes_on, shadow_code


class ArticleShading(WhittedShading):
    """The Whitted integrator's shading model in article semantics (module docstring),
    where it differs from Glint's own (``WhittedShading``)."""

    sees_background = False    # the article's rays that escape add nothing
    shades_seen_side = False   # the outward normal, from inside a sphere too
    display_values = True      # each sample clipped to [0, 1], as the article's pixels are
    shade = staticmethod(shade_article)


ARTICLE_SHADING = ArticleShading()
