"""Huge spheres beside a tree (a floor: ``Aggregate`` keeps them out of the tree and tests
them flat) are tested by every ray without the bundle's cone
(``GeometryPolicy.unculled_beside_tree``),
which nearly every bundle reaches: the hits and blocked segments are the culled path's."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY
from core.rays import RayBatch


def _scene(floors: int) -> core.Scene:
    """600 small spheres over ``floors`` huge ones (the article's kind of floor)."""
    rng = np.random.default_rng(5)
    count = 600
    cloud = core.SphereSet(np.c_[rng.uniform(-4, 4, count), rng.uniform(-1, 1, count),
                                 rng.uniform(-9, -2, count)],
                           rng.uniform(0.02, 0.1, count), np.zeros(count, np.int64),
                           (core.Material(reflection=0.5),), name="cloud")
    huge = tuple(core.Sphere((0, -9001 - 3 * k, -5), 9000.0, name=f"floor {k}")
                 for k in range(floors))
    return core.Scene(camera=core.ScreenCamera(32, 24, eye=(0, 0, 1)), spheres=huge,
                      sphere_sets=(cloud,), lights=(core.PointLight((2, 6, 1)),))


def _batches(geometry, dtype):
    """Camera rays from the eye (shared origin) over the whole sphere of directions, and
    rays from random points of the field (no shared origin), and the same rays
    turned to within about 20 degrees of straight up, away from every floor."""
    rng = np.random.default_rng(9)
    directions = rng.normal(size=(3, 4000))
    directions = (directions / np.linalg.norm(directions, axis=0)).astype(dtype)
    eye = np.array([0.0, 0.0, 1.0])
    up = directions.astype(np.float64)
    up[1] = np.abs(up[1]) + 3          # within about 20 degrees of straight up
    up = (up / np.linalg.norm(up, axis=0)).astype(dtype)
    origins = np.c_[rng.uniform(-4, 4, 4000), rng.uniform(-1, 1, 4000),
                    rng.uniform(-9, -2, 4000)].T.astype(dtype)
    return [RayBatch(eye[:, None], d, 0.0, np.inf, geometry.shared_origin(eye))
            for d in (directions, up)] + [RayBatch(origins, d, 0.0, np.inf)
                                          for d in (directions, up)]


@pytest.mark.parametrize("floors", [1, 2])
@pytest.mark.parametrize("semantics", ["default", "article"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_huge_spheres_beside_a_tree_are_tested_by_every_ray(floors, semantics, dtype):
    scene = _scene(floors)
    settings = core.RenderSettings(semantics=semantics)
    answers = {}
    for unculled in (DEFAULT_POLICY.unculled_beside_tree, 0):
        policy = dataclasses.replace(DEFAULT_POLICY, unculled_beside_tree=unculled)
        geometry = make_context(scene, settings, dtype, geometry_policy=policy).geometry
        assert geometry.tree is not None and geometry.flat_spheres.count == floors
        answers[unculled] = []
        for rays in _batches(geometry, dtype):
            candidates = geometry.flat_spheres.candidates(rays)
            if unculled:
                # Every floor, even for the rays going up, away from all of them.
                assert list(candidates) == list(range(floors))
            hits = geometry.nearest(rays, RayStats())
            segments = RayBatch(rays.origins, rays.directions, 0.0, 3.0, rays.shared)
            answers[unculled].append((hits.rays, hits.primitive_per_ray, hits.t,
                                      geometry.occluded(segments, RayStats())))
    culled_up = geometry.flat_spheres.candidates(_batches(geometry, dtype)[1])
    assert len(culled_up) == 0          # the cone leaves the floors out of the upward rays
    for new, old in zip(*answers.values()):
        for a, b in zip(new, old):
            np.testing.assert_array_equal(a, b)
