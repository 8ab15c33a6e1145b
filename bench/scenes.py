"""The bench's scenes: the article's, and many small random spheres over the article's floor
(as ``core.Sphere`` objects, or as one ``core.SphereSet`` for counts up to millions).

All use the article's ScreenCamera (eye (0, 0, 1), screen [-1, 1] on z = 0), its light and
its floor sphere, so that the only thing that changes between them is the sphere count.
"""

from __future__ import annotations

import math

import numpy as np

from core import Material, PointLight, Scene, ScreenCamera, Sphere, SphereSet, article_scene
from core.article import ARTICLE_EYE, ARTICLE_LIGHT, article_spheres

__all__ = ["article_scene", "random_spheres_scene", "random_sphere_set_scene", "SEED"]

SEED = 20240601
RADIUS_RANGE = (0.02, 0.08)
#: Spheres lie between these depths in front of the eye (distance along -Z from it).
DEPTH_RANGE = (1.5, 6.0)
#: Largest gap between a sphere's bottom and the floor.
MAX_HEIGHT_ABOVE_FLOOR = 0.6
#: Fraction of the view's half-width (at each sphere's depth) the spheres stay within.
VIEW_MARGIN = 0.9


def _floor():
    return article_spheres()[-1]


def _floor_height(x, z, floor: Sphere) -> float:
    """The floor sphere's top surface above (x, z)."""
    cx, cy, cz = floor.center
    return cy + math.sqrt(floor.radius ** 2 - (x - cx) ** 2 - (z - cz) ** 2)


def random_spheres_scene(count: int, width: int, height: int, *, floor: bool = True,
                         seed: int = SEED) -> Scene:
    """``count`` small spheres (radius 0.02..0.08, random diffuse colours, reflection 0.5) in
    front of the article's camera, resting on or floating just above the article's floor,
    lit by the article's light; with ``floor`` the floor sphere is the last sphere.

    Without the floor the scene's extent is a few units next to radii >= 0.02, the kind of
    ordinary scene whose precision 'auto' renders in float32.  The same seed and count give
    the same spheres whatever the resolution.
    """
    rng = np.random.default_rng(seed)
    floor_sphere = _floor()
    eye_x, _, eye_z = ARTICLE_EYE
    spheres = []
    for index in range(count):
        radius = rng.uniform(*RADIUS_RANGE)
        depth = rng.uniform(*DEPTH_RANGE)
        half_width = depth * VIEW_MARGIN  # the screen spans [-1, 1] at distance 1
        x = eye_x + rng.uniform(-half_width, half_width)
        z = eye_z - depth
        y = _floor_height(x, z, floor_sphere) + radius + rng.uniform(0, MAX_HEIGHT_ABOVE_FLOOR)
        diffuse = tuple(float(v) for v in rng.uniform(0.1, 0.9, 3))
        material = Material(ambient=tuple(0.1 * v for v in diffuse), diffuse=diffuse,
                            specular=(1.0, 1.0, 1.0), shininess=100.0, reflection=0.5)
        spheres.append(Sphere((x, y, z), radius, material, f"ball {index}"))
    if floor:
        spheres.append(floor_sphere)
    return Scene(camera=ScreenCamera(width=width, height=height, eye=ARTICLE_EYE),
                 spheres=tuple(spheres), lights=(PointLight(ARTICLE_LIGHT, name="light"),))


#: Materials of the sphere-set scenes: random diffuse colours drawn once, shared by index.
SET_MATERIALS = 64


def random_sphere_set_scene(count: int, width: int, height: int, *, floor: bool = True,
                            seed: int = SEED) -> Scene:
    """``count`` spheres drawn as ``random_spheres_scene`` draws them (same ranges, same
    camera, light and floor), but with whole-array draws into one ``SphereSet`` (so a million
    take a fraction of a second), coloured by SET_MATERIALS shared materials."""
    rng = np.random.default_rng(seed)
    floor_sphere = _floor()
    eye_x, _, eye_z = ARTICLE_EYE
    radius = rng.uniform(*RADIUS_RANGE, count)
    depth = rng.uniform(*DEPTH_RANGE, count)
    x = eye_x + rng.uniform(-1, 1, count) * depth * VIEW_MARGIN
    z = eye_z - depth
    cx, cy, cz = floor_sphere.center
    top = cy + np.sqrt(floor_sphere.radius ** 2 - (x - cx) ** 2 - (z - cz) ** 2)
    y = top + radius + rng.uniform(0, MAX_HEIGHT_ABOVE_FLOOR, count)
    colours = rng.uniform(0.1, 0.9, (SET_MATERIALS, 3))
    materials = tuple(Material(ambient=tuple(0.1 * c), diffuse=tuple(c), specular=(1.0, 1.0, 1.0),
                               shininess=100.0, reflection=0.5) for c in colours)
    spheres = SphereSet(np.column_stack([x, y, z]), radius,
                        rng.integers(0, SET_MATERIALS, count), materials, name="spheres")
    return Scene(camera=ScreenCamera(width=width, height=height, eye=ARTICLE_EYE),
                 spheres=(floor_sphere,) if floor else (), sphere_sets=(spheres,),
                 lights=(PointLight(ARTICLE_LIGHT, name="light"),))

