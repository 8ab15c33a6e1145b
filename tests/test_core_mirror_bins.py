"""A floor's reflections of the camera's rays (``DirectionBins._mirror_groups``): their lines pass
near the eye's mirror image, so direction bins around that image (boxes grown by the slack)
answer them, with the tree's hits ray for ray and far fewer box tests; rays whose lines miss
the image (a wrong ``arrived_from``, no ``arrived_from``) are the tree's as before."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY
from core.rays import RayBatch

MATERIALS = (core.Material(reflection=0.5), core.Material(diffuse=(0.8, 0.2, 0.1)))
EYE = np.array([0.3, 1.0, 12.0])


def _scene(floor: str) -> core.Scene:
    """900 spheres and 150 triangles in a 10-unit cube above a floor at y = -6 (the article's
    kind of floor, a sphere of radius 8994, or a plane of two triangles) and below a
    ceiling."""
    rng = np.random.default_rng(2)
    count, triangles = 900, 150
    cloud = core.SphereSet(rng.uniform(-5, 5, (count, 3)), rng.uniform(0.02, 0.3, count),
                           rng.integers(0, 2, count), MATERIALS, name="cloud")
    corners = rng.uniform(-5, 5, (triangles, 1, 3)) + rng.normal(scale=0.3, size=(triangles, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(3 * triangles).reshape(-1, 3),
                             None, np.zeros(triangles, np.int64), MATERIALS, name="soup")
    # A ceiling (a large sphere, beside the tree as the floor is) bounds the rays going up.
    meshes, spheres = [soup], (core.Sphere((0, 506, 0), 500.0, name="ceiling"),)
    if floor == "sphere":
        spheres += (core.Sphere((0, -9000, 0), 8994.0, name="floor"),)
    else:
        plane = np.array([[-40, -6, -40], [40, -6, -40], [40, -6, 40], [-40, -6, 40]], float)
        meshes.append(core.TriangleMesh(plane, np.array([[0, 2, 1], [0, 3, 2]]), None,
                                        np.zeros(2, np.int64), MATERIALS, name="floor"))
    return core.Scene(camera=core.ScreenCamera(64, 48, eye=tuple(EYE)), spheres=spheres,
                      sphere_sets=(cloud,), meshes=tuple(meshes),
                      lights=(core.PointLight((3, 20, 8)),))


def _floor_reflections(geometry, dtype, arrived_from):
    """The floor's mirror rays of 30,000 camera rays from EYE aimed at it (spawned as the
    bounce loop spawns them), and the floor's primitive ids."""
    rng = np.random.default_rng(8)
    targets = np.stack([rng.uniform(-12, 12, 30000), np.full(30000, -6.0),
                        rng.uniform(-14, 8, 30000)])
    directions = targets - EYE[:, None]
    directions = (directions / np.linalg.norm(directions, axis=0)).astype(dtype)
    camera = RayBatch(EYE[:, None], directions, 0.0, np.inf, geometry.shared_origin(EYE))
    hits = geometry.nearest(camera, RayStats())
    floor = np.flatnonzero(geometry.spheres.radii > 1000) if geometry.sphere_count > 901 \
        else geometry.sphere_count + geometry.triangle_count - np.arange(1, 3)
    on_floor = np.flatnonzero(np.isin(hits.primitive, floor))
    assert len(on_floor) > 15000
    take = lambda a: a[:, on_floor]  # noqa: E731
    normals, d = take(hits.normals), take(hits.directions)
    reflected = d - normals * (2 * (d * normals).sum(axis=0))
    return geometry.spawn(take(hits.points), normals, hits.primitive[on_floor], reflected,
                          hits.front[on_floor], arrived_from)


@pytest.mark.parametrize("floor", ["sphere", "plane"])
@pytest.mark.parametrize("semantics", ["default", "article"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_a_floors_reflections_are_answered_as_the_tree_does(floor, semantics, dtype):
    """The floor's mirror rays get the tree's nearest hits (distance, primitive,
    barycentrics) bit for bit, with under a third of its box tests; given a wrong point or
    none, they go to the tree, with the same hits."""
    scene = _scene(floor)
    settings = core.RenderSettings(semantics=semantics)
    binned = make_context(scene, settings, dtype).geometry
    tree = make_context(scene, settings, dtype, geometry_policy=dataclasses.replace(
        DEFAULT_POLICY, bins_max_primitives=-1)).geometry
    answers = []
    for geometry, arrived_from in ((binned, EYE), (tree, EYE), (binned, EYE + (0.0, 0.5, 0.0)),
                                   (binned, None)):
        rays = _floor_reflections(geometry, dtype, arrived_from)
        stats = RayStats()
        answers.append((geometry.intersect(rays, stats), stats.node_tests))
    (mirrored, mirrored_nodes), (reference, tree_nodes) = answers[:2]
    for (t, primitive, bary), nodes in answers:
        assert np.array_equal(t, reference[0]) and np.array_equal(primitive, reference[1])
        assert all(np.array_equal(a, b) for a, b in zip(bary, reference[2]))
    assert mirrored_nodes < tree_nodes / 3
    assert answers[2][1] > 0.9 * tree_nodes and answers[3][1] == tree_nodes
    primitive = reference[1]
    small = np.flatnonzero(binned.spheres.radii < 1)
    ceiling = np.flatnonzero(binned.spheres.radii == 500)
    # Rays hit the cloud's spheres, its triangles and the ceiling.
    assert 0.03 < np.isin(primitive, small).mean() < 0.9
    assert (primitive >= binned.sphere_count).any() and np.isin(primitive, ceiling).mean() > 0.3


def test_mirror_bins_are_built_once_per_image():
    """The eye's images in a plane's two triangles are one point: one set of bins."""
    geometry = make_context(_scene("plane"), core.RenderSettings(), np.float64).geometry
    rays = _floor_reflections(geometry, np.float64, EYE)
    geometry.intersect(rays, RayStats())
    mirror_bins = [key for key in geometry.bins.store.held if key[1]]
    assert len(mirror_bins) == 1
    assert len({int(s) for s in rays.source}) == 2


@pytest.mark.slow
@pytest.mark.parametrize("semantics,precision", [("article", "float64"), ("default", "float32"),
                                                 ("default", "float64")])
def test_renders_through_mirror_bins_are_the_trees(semantics, precision):
    """A mirror floor under 600 spheres (the article's reflection, or a Principled metal of
    roughness 0 for Blender's look, whose mirror rays come from ``core.bsdf``): the image is
    the one the tree alone gives, with fewer box tests (the first bounce's floor rays went
    through bins around the eye's image)."""
    rng = np.random.default_rng(9)
    count = 600
    centres = np.column_stack([rng.uniform(-3, 3, count), rng.uniform(-1, 0.5, count),
                               rng.uniform(-8, -2, count)])
    if semantics == "article":
        floor_material = core.Material(reflection=0.5)
    else:
        floor_material = core.SurfaceMaterial.principled(base_color=(0.9, 0.9, 0.9),
                                                         metallic=1.0, roughness=0.0)
    cloud = core.SphereSet(centres, rng.uniform(0.05, 0.2, count), rng.integers(0, 2, count),
                           MATERIALS, name="cloud")
    scene = core.Scene(camera=core.ScreenCamera(160, 120), sphere_sets=(cloud,),
                       spheres=(core.Sphere((0, -9001.2, 0), 9000.0, floor_material,
                                            name="floor"),),
                       lights=(core.PointLight((2, 5, 3)),))
    # (The Whitted integrator's bounces carry the eye's position to the floor's rays.)
    settings = core.RenderSettings(semantics=semantics, precision=precision, threads=1,
                                   integrator="whitted")
    mirrored = core.render(scene, settings)
    tree = core.render(scene, settings,
                       geometry_policy=dataclasses.replace(DEFAULT_POLICY, mirror_slack=0.0))
    assert np.array_equal(mirrored.image, tree.image)
    assert mirrored.stats.node_tests < 0.8 * tree.stats.node_tests
    assert mirrored.stats.reflection_rays > 10000
