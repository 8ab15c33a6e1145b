"""The BVH behind the aggregate gives exactly the hits of the flat paths, stops rays early,
and is not built for small scenes."""

from __future__ import annotations

import numpy as np
import pytest

import core
from core import aggregate
from core.context import RayStats, make_context
from core.rays import RayBatch

MATERIALS = (core.Material(reflection=0.5), core.Material(diffuse=(0.8, 0.2, 0.1)))


def _cloud(count, seed=0):
    rng = np.random.default_rng(seed)
    return core.SphereSet(rng.uniform(-5, 5, (count, 3)), rng.uniform(0.02, 0.3, count),
                          rng.integers(0, 2, count), MATERIALS, name="cloud")


def _scene(count, floor=True, meshes=()):
    spheres = (core.Sphere((0, -9000, 0), 8999.3, name="floor"),) if floor else ()
    return core.Scene(camera=core.ScreenCamera(64, 48, eye=(0, 0, 12)), spheres=spheres,
                      sphere_sets=(_cloud(count),), meshes=meshes,
                      lights=(core.PointLight((3, 20, 8)),))


def _contexts(scene, monkeypatch, dtype=np.float64):
    """(with a tree, flat) contexts of the same scene; fails if either is not what it says."""
    tree = make_context(scene, core.RenderSettings(), dtype)
    monkeypatch.setattr(aggregate, "BVH_MIN_SPHERES", 10 ** 9)
    monkeypatch.setattr(aggregate, "BVH_MIN_TRIANGLES", 10 ** 9)
    flat = make_context(scene, core.RenderSettings(), dtype)
    assert tree.geometry._tree is not None and flat.geometry._tree is None
    return tree, flat


def _rays(rng, n, dtype, shared_origin=None):
    directions = rng.normal(size=(3, n))
    directions /= np.linalg.norm(directions, axis=0)
    if shared_origin is not None:
        return np.asarray(shared_origin, float)[:, None], directions.astype(dtype)
    return rng.uniform(-6, 6, (3, n)).astype(dtype), directions.astype(dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_tree_finds_exactly_the_flat_paths_hits(monkeypatch, dtype):
    """3,000 spheres, a floor kept out of the tree, 200 triangles: nearest hits (distance and
    primitive) and occlusion agree with the flat paths ray for ray, for rays with their own
    origins, rays sharing one (with its terms) and rays that exclude what they leave."""
    rng = np.random.default_rng(1)
    corners = rng.uniform(-5, 5, (200, 1, 3)) + rng.normal(scale=0.3, size=(200, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(600).reshape(200, 3), None,
                             np.zeros(200, np.int64), MATERIALS)
    scene = _scene(3000, meshes=(soup,))
    tree, flat = _contexts(scene, monkeypatch, dtype)
    assert 0 in tree.geometry._flat_ids            # the floor stays flat beside the tree
    for shared in (None, (0.5, 1.0, 11.0)):
        origins, directions = _rays(rng, 4000, dtype, shared)
        exclude = rng.integers(-1, 3201, 4000)
        lengths = rng.uniform(0.1, 8, 4000).astype(dtype)
        results = []
        for ctx in (tree, flat):
            origin = ctx.geometry.shared_origin(shared) if shared is not None else None
            batch = RayBatch(origins, directions, 0.0, np.inf, origin, exclude)
            t, primitive, _ = ctx.geometry.intersect(batch, RayStats())
            segments = RayBatch(origins, directions, 0.0, lengths, origin, exclude)
            results.append((t, primitive, ctx.geometry.occluded(segments, RayStats())))
        (t1, p1, o1), (t2, p2, o2) = results
        assert np.array_equal(p1, p2)
        assert np.array_equal(t1, t2)
        assert np.array_equal(o1, o2)
        assert (p1 >= 3001).any() and ((p1 >= 1) & (p1 < 3001)).any() and o1.any() and not o1.all()


def test_sphere_set_renders_the_same_through_the_tree_and_flat(monkeypatch):
    scene = _scene(1500)
    tree = core.render(scene, core.RenderSettings(precision="float64"))
    monkeypatch.setattr(aggregate, "BVH_MIN_SPHERES", 10 ** 9)
    flat = core.render(scene, core.RenderSettings(precision="float64"))
    # Box tests happen only in the tree: without them this would compare the tree with itself.
    assert tree.stats.node_tests > 0 and flat.stats.node_tests == 0
    assert np.array_equal(tree.image, flat.image)
    assert (tree.image[..., 3] == 1).mean() > 0.5


def test_rays_stop_at_their_nearest_hit():
    """A dense wall of 40,000 spheres: camera rays that hit the wall's front test a small,
    bounded number of spheres, not every sphere along their line through it."""
    grid = np.stack(np.meshgrid(np.linspace(-2, 2, 20), np.linspace(-2, 2, 20),
                                np.linspace(-1, -20, 100)), -1).reshape(-1, 3)
    wall = core.SphereSet(grid, np.full(len(grid), 0.12), np.zeros(len(grid), np.int64),
                          MATERIALS[:1])
    scene = core.Scene(camera=core.ScreenCamera(40, 40, eye=(0, 0, 3), left=-0.3, right=0.3),
                       sphere_sets=(wall,), lights=(core.PointLight((0, 0, 10)),))
    result = core.render(scene, core.RenderSettings(max_depth=1, precision="float64"))
    assert (result.image[..., 3] == 1).all()
    assert result.stats.sphere_tests / result.stats.camera_rays < 200   # of 40,000 spheres


def test_small_scenes_build_no_tree():
    ctx = make_context(core.article_scene(30, 20), core.article_settings(), np.float64)
    assert ctx.geometry._tree is None
    stats = core.render(core.article_scene(30, 20), core.article_settings()).stats
    assert stats.node_tests == 0


def test_morton_tree_bounds_contain_their_primitives():
    from core.bvh import BVH, LEAF_SIZE, WIDTH
    rng = np.random.default_rng(3)
    low = rng.normal(size=(1000, 3))
    high = low + rng.uniform(0, 0.5, (1000, 3))
    tree = BVH.build(np.arange(1000), low, high)
    assert sorted(tree.primitives[tree.primitives >= 0]) == list(range(1000))
    leaf_low, leaf_high = tree.levels[0]
    slots = tree.primitives.reshape(-1, LEAF_SIZE)
    for leaf, members in enumerate(slots):
        members = members[members >= 0]
        assert (leaf_low[:, leaf, None] <= low[members].T).all()
        assert (leaf_high[:, leaf, None] >= high[members].T).all()
    for level in range(1, len(tree.levels)):
        below_low, below_high = tree.levels[level - 1]
        up_low, up_high = tree.levels[level]
        parent = np.arange(below_low.shape[1]) // WIDTH
        assert (up_low[:, parent] <= below_low).all() and (up_high[:, parent] >= below_high).all()
    assert tree.levels[-1][0].shape[1] == 1
