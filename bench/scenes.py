"""The bench's scenes: the article's, and many small random spheres over the article's floor
(as ``core.Sphere`` objects, or as one ``core.SphereSet`` for counts up to millions), and
triangles and spheres under the path integrator (``mesh_and_spheres_scene``).

The sphere scenes use the article's ScreenCamera (eye (0, 0, 1), screen [-1, 1] on z = 0), its
light and its floor sphere, so that the only thing that changes between them is the sphere
count.
"""

from __future__ import annotations

import math

import numpy as np

from core import (AreaLight, BlenderCamera, Material, PointLight, Scene, ScreenCamera, Sphere,
                  SphereSet, SurfaceMaterial, TriangleMesh, article_scene)
from core.article import ARTICLE_EYE, ARTICLE_LIGHT, article_spheres

__all__ = ["article_scene", "random_spheres_scene", "random_sphere_set_scene",
           "mesh_and_spheres_scene", "SEED"]

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



def _look_at(eye, target) -> tuple:
    """A Blender camera's matrix_world at ``eye`` looking at ``target`` (+Z up)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross((0.0, 0.0, 1.0), back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    rows = np.column_stack([right, up, back, eye])
    return tuple(map(tuple, rows)) + ((0.0, 0.0, 0.0, 1.0),)


def _icosphere(subdivisions: int):
    """(corners (T, 3, 3)) of a unit icosphere: an icosahedron's faces split in four
    ``subdivisions`` times, projected onto the sphere."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                  (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)],
                 float)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
                  (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
                  (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
                  (8, 6, 7), (9, 8, 1)])
    corners = v[f]
    for _ in range(subdivisions):
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        corners = np.concatenate([np.stack(x, 1) for x in
                                  ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return corners / np.linalg.norm(corners, axis=2, keepdims=True)


def _mesh(corners, material, name):
    """A flat-shaded mesh of triangles ``corners`` (T, 3, 3)."""
    count = len(corners)
    return TriangleMesh(corners.reshape(-1, 3), np.arange(3 * count).reshape(-1, 3), None,
                        np.zeros(count, np.int64), (material,), name=name)


def mesh_and_spheres_scene(spheres: int = 2000, grid: int = 48, subdivisions: int = 4,
                           width: int = 160, height: int = 120, seed: int = SEED) -> Scene:
    """Triangles and spheres under the path integrator (``bench.rays``): a rolling terrain
    of ``grid`` x ``grid`` quads (two triangles each) and, on it, an icosphere of
    20 * 4^subdivisions triangles among ``spheres`` small spheres (one ``SphereSet``),
    lit by a square area light and a grey world, seen by a Blender camera."""
    rng = np.random.default_rng(seed)
    edge = np.linspace(-8, 8, grid + 1)
    x, y = np.meshgrid(edge, edge, indexing="ij")
    z = 0.4 * np.sin(0.7 * x) * np.cos(0.5 * y)
    points = np.stack([x, y, z], -1)
    a, b = points[:-1, :-1].reshape(-1, 3), points[1:, :-1].reshape(-1, 3)
    c, d = points[1:, 1:].reshape(-1, 3), points[:-1, 1:].reshape(-1, 3)
    terrain = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    ball = _icosphere(subdivisions) * 1.5 + (0.0, 0.0, 1.8)
    grey = SurfaceMaterial(diffuse=(0.6, 0.6, 0.6))
    red = SurfaceMaterial(diffuse=(0.7, 0.2, 0.15))
    centres = np.column_stack([rng.uniform(-7, 7, spheres), rng.uniform(-7, 7, spheres),
                               rng.uniform(0.3, 1.5, spheres)])
    colours = tuple(SurfaceMaterial(diffuse=tuple(float(v) for v in rng.uniform(0.1, 0.9, 3)))
                    for _ in range(8))
    field = SphereSet(centres, rng.uniform(0.04, 0.12, spheres),
                      rng.integers(0, len(colours), spheres), colours, name="field")
    light = AreaLight((2.0, -3.0, 7.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                      size_x=3.0, size_y=3.0, power=800.0, name="area")
    camera = BlenderCamera(_look_at((0.0, -13.0, 6.5), (0.0, 0.0, 1.0)),
                           resolution_x=width, resolution_y=height)
    return Scene(camera, (), (light,), background=(0.1, 0.1, 0.12), sphere_sets=(field,),
                 meshes=(_mesh(terrain, grey, "terrain"), _mesh(ball, red, "ball")))
