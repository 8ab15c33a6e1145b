"""Blinn-Phong shading and light visibility, for m shaded points at a time.

Both semantics use the article's model: for each light,
``ka Ia + kd Id (L.N) + ks Is (N.H) ** (shininess / 4)``.

Article semantics, every quirk kept:
  * dot products are not clamped (a point facing away from the light gets negative diffuse);
  * H = normalize(L + V) with V towards the CAMERA position, on every bounce;
  * the shadow ray starts at P + 1e-5 N and the point is in shadow if a sphere is hit (both
    roots positive) nearer than |light - P|; a shadowed point adds nothing, not even ambient,
    and ends the path (with several lights: a light that is blocked adds nothing, and the path
    ends where every light is blocked);
  * the lights' radii are ignored (the article's light is a point).

Default semantics, each quirk fixed:
  * L.N and N.H are clamped at 0, and a light behind the surface adds no diffuse or
    specular (and so needs no shadow ray);
  * V points back along the incoming ray (where the light is seen from), not at the camera;
  * ambient ``ka (sum Ia + scene ambient)`` is kept in shadow, and shadow never ends a path;
  * shadow rays are exact segments P -> light that ignore the sphere P lies on when P faces
    outward (a convex sphere cannot block its own lit side), and stop short of P by an
    offset that scales with |P| (Mitsuba's (1 + max|P_i|) eps), never a fixed 1e-5;
  * a light with radius > 0 casts soft shadows: visibility is the fraction of
    ``light_samples`` points on its sphere that P sees.

Shadow rays are traced from the light towards the points: every shadow ray of a light then
shares one origin, so the sphere terms are computed once per light, not once per ray.
"""

from __future__ import annotations

import numpy as np

from .context import ARTICLE_OFFSET, RAY_EPSILON, RayStats, TraceContext
from .cull import bundle_cone, reachable
from .intersect import shared_origin_roots

#: Candidate spheres intersected at once; bounds (n, k) temporaries.
SPHERE_CHUNK = 32
#: One digit of a shadow code per light: unlit (0) or visibility 0, 1/4, .., 1 (1 .. 5).
_CODE_BASE = 6


def _dot(a, b):
    return np.einsum("nc,nc->n", a, b)


def _length(v):
    return np.sqrt(_dot(v, v))


def _normalize(v):
    return v * (1 / _length(v))[:, None]


def _power(base, exponent):
    """base ** exponent per row (m,); a negative base with a non-integer exponent gives 0, not
    NaN.  A whole exponent shared by every row (the article's 25) is computed by repeated
    squaring, several times faster than pow and exact in sign for negative bases."""
    first = exponent[0] if len(exponent) else 0
    if len(exponent) and float(first).is_integer() and 0 <= first < 1024 \
            and (exponent == first).all():
        return _whole_power(base, int(first))
    with np.errstate(invalid="ignore"):
        result = np.power(base, exponent)
    return np.where(np.isnan(result), 0, result)


def _whole_power(base, n: int):
    result = np.ones_like(base)
    square = base
    while n:
        if n & 1:
            result = result * square
        n >>= 1
        if n:
            square = square * square
    return result


def light_blocked(ctx: TraceContext, terms, origin, directions, distance, exclude,
                  stats: RayStats, *, start=None, end=None):
    """Whether the segments from a light sample towards m points are blocked, (m,) bool.

    terms: OriginTerms at ``origin`` (3,), the light sample.  directions: (m, 3) unit vectors
    from the light towards the points; distance: (m,) how far the points are.  Default
    semantics: blocked if a sphere other than ``exclude`` (m,) (-1: none) is crossed in
    (0, distance - end), end (m,) the offset.  Article semantics (the points are the shifted
    points S, start (m,) = |light - P|): blocked if the reversed ray S -> light has both roots
    positive and its nearer one below ``start``.
    """
    m = len(directions)
    blocked = np.zeros(m, bool)
    if m == 0 or len(ctx.radii) == 0:
        return blocked
    stats.shadow_rays += m
    apex, spread, axis, half = bundle_cone(None, directions, apex=origin)
    candidates = np.flatnonzero(reachable(ctx.centers, ctx.radii, apex, spread, axis, half,
                                          float(distance.max())))
    distance = distance[:, None]
    for first in range(0, len(candidates), SPHERE_CHUNK):
        chunk = candidates[first:first + SPHERE_CHUNK]
        stats.sphere_tests += m * len(chunk)
        t_near, t_far, valid = shared_origin_roots(directions, terms, ctx.radii, chunk,
                                                   article=ctx.article)
        if ctx.article:
            hit = valid & (t_far < distance) & (t_far > distance - start[:, None])
        else:
            limit = distance - end[:, None]
            hit = valid & (((t_near > 0) & (t_near < limit)) | ((t_far > 0) & (t_far < limit)))
            if exclude is not None:
                hit &= exclude[:, None] != chunk[None, :]
        blocked |= hit.any(axis=1)
    return blocked


def shade(ctx: TraceContext, points, normals, directions, spheres, front, stats: RayStats):
    """(colour (m, 3), goes_on (m,), shadow_code (m,) uint64) at m hit points.

    goes_on: whether the path continues (article shadows end it).  shadow_code: which lights
    each point sees (a digit per light, soft visibility in quarters), so that adaptive
    anti-aliasing can find shadow edges.

    points, normals (facing the incoming ray in default semantics), directions (incoming, unit):
    (m, 3); spheres: (m,) scene indices; front: (m,) True where the ray hit the outside.
    """
    lights = ctx.arrays.lights
    mat = ctx.materials
    dtype = points.dtype
    ka, kd, ks, exponent = (mat.ambient[spheres], mat.diffuse[spheres], mat.specular[spheres],
                            mat.exponent[spheres])
    m = len(points)
    if ctx.article:
        return _shade_article(ctx, points, normals, ka, kd, ks, exponent, stats)
    ambient = (lights.ambient.sum(axis=0) + ctx.arrays.ambient).astype(dtype)
    colour = ka * ambient
    view = -directions
    exclude = np.where(front, spheres, -1)
    shadow_code = np.zeros(m, np.uint64)
    offset = (1 + np.abs(points).max(axis=1)) * ctx.dtype.type(RAY_EPSILON[ctx.dtype])
    for light in range(len(lights)):
        strength_d = lights.diffuse[light].astype(dtype)
        strength_s = lights.specular[light].astype(dtype)
        from_light = points - lights.positions[light].astype(dtype)
        distance = _length(from_light)
        from_light *= (1 / distance)[:, None]
        cos_light = -_dot(normals, from_light)
        # No shadow ray where the light cannot add anything.
        reflective = (kd @ strength_d > 0) | (ks @ strength_s > 0)
        lit = np.flatnonzero((cos_light > 0) & reflective)
        shadow_code *= np.uint64(_CODE_BASE)
        if len(lit) == 0:
            continue
        visibility = np.ones(len(lit), dtype)
        samples = ctx.light_samples[light]
        for sample, terms in zip(samples, ctx.light_terms[light]):
            if len(samples) == 1:
                directions_s, distance_s = from_light[lit], distance[lit]
            else:
                directions_s = points[lit] - sample.astype(dtype)
                distance_s = _length(directions_s)
                directions_s *= (1 / distance_s)[:, None]
            blocked = light_blocked(ctx, terms, sample, directions_s, distance_s, exclude[lit],
                                    stats, end=offset[lit])
            visibility -= blocked.astype(dtype) / len(samples)
        shadow_code[lit] += (1 + np.round(visibility * 4)).astype(np.uint64)
        half = _normalize(view[lit] - from_light[lit])
        cos_half = np.maximum(_dot(normals[lit], half), 0)
        colour[lit] += visibility[:, None] * (
            kd[lit] * strength_d * cos_light[lit, None]
            + ks[lit] * strength_s * _power(cos_half, exponent[lit])[:, None])
    return colour, np.ones(m, bool), shadow_code


def _shade_article(ctx, points, normals, ka, kd, ks, exponent, stats):
    lights = ctx.arrays.lights
    dtype = points.dtype
    shifted = points + ARTICLE_OFFSET * normals
    to_camera = _normalize(ctx.eye.astype(dtype) - points)
    colour = np.zeros_like(points)
    goes_on = np.zeros(len(points), bool)
    shadow_code = np.zeros(len(points), np.uint64)
    for light in range(len(lights)):
        position = lights.positions[light].astype(dtype)
        from_light = shifted - position
        shifted_distance = _length(from_light)
        from_light *= (1 / shifted_distance)[:, None]
        to_light = -from_light
        light_distance = _length(position - points)
        blocked = light_blocked(ctx, ctx.light_terms[light][0], lights.positions[light],
                                from_light, shifted_distance, None, stats, start=light_distance)
        half = _normalize(to_light + to_camera)
        term = (ka * lights.ambient[light].astype(dtype)
                + kd * lights.diffuse[light].astype(dtype) * _dot(to_light, normals)[:, None]
                + ks * lights.specular[light].astype(dtype)
                * _power(_dot(normals, half), exponent)[:, None])
        colour += np.where(blocked[:, None], 0, term)
        goes_on |= ~blocked
        shadow_code = shadow_code * np.uint64(_CODE_BASE) + (~blocked).astype(np.uint64)
    return colour, goes_on, shadow_code
