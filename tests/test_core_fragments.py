"""Long thin triangles go into the tree as fragments with tight boxes
(``Triangles.fragments``): the fragments' boxes cover their triangles, a leaf holds a
primitive once, and a tree over fragments finds exactly the hits and blockers of a tree
over whole triangles and of the flat paths, with far fewer triangle tests."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY
from core.geometry.pairs import keep_nearest
from core.rays import RayBatch

MATERIALS = (core.Material(diffuse=(0.8, 0.2, 0.1)),)
#: No triangle is split: the tree holds whole triangles.
WHOLE = dataclasses.replace(DEFAULT_POLICY, split_ratio=np.inf)
FLAT = dataclasses.replace(DEFAULT_POLICY, tree_min_spheres=10 ** 9,
                           tree_min_triangles=10 ** 9, tree_saved_tests=np.inf)


def _slivers(rng, count):
    """(count, 3, 3) long thin triangles at every angle: 6 to 12 long, about 0.05 wide."""
    start = rng.uniform(-6, 6, (count, 3))
    along = rng.normal(size=(count, 3))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    end = start + along * rng.uniform(6, 12, count)[:, None]
    side = np.cross(along, rng.normal(size=(count, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    return np.stack([start, end, end + 0.05 * side], axis=1)


def _scene(rng):
    """300 slivers, 300 small triangles and 200 small spheres in a 12-unit cube."""
    small = rng.uniform(-6, 6, (300, 1, 3)) + rng.normal(scale=0.2, size=(300, 3, 3))
    corners = np.concatenate([_slivers(rng, 300), small])
    mesh = core.TriangleMesh(corners.reshape(-1, 3), np.arange(1800).reshape(-1, 3), None,
                             np.zeros(600, np.int64), MATERIALS, name="soup")
    balls = core.SphereSet(rng.uniform(-6, 6, (200, 3)), rng.uniform(0.05, 0.3, 200),
                           np.zeros(200, np.int64), MATERIALS, name="balls")
    return core.Scene(camera=core.ScreenCamera(32, 24, eye=(0, 0, 14)), meshes=(mesh,),
                      sphere_sets=(balls,), lights=(core.PointLight((3, 20, 8)),))


def test_fragments_cover_their_triangles_with_tighter_boxes():
    """Points all over each triangle (its corners, its edges, inside) lie in a box of one of
    its fragments; the slivers are cut into several fragments whose boxes add up to a
    fraction of the whole box's area; small triangles stay whole; the budget bounds the
    fragments."""
    rng = np.random.default_rng(1)
    ctx = make_context(_scene(rng), core.RenderSettings(), np.float64)
    shape = ctx.geometry.triangle_shape
    ids = np.arange(600)
    policy = DEFAULT_POLICY
    boxes = shape.boxes(ids)
    capped = shape.fragments(ids, *boxes, policy.split_ratio, policy.split_levels, 0.5)[0]
    assert len(capped) == 900
    fragments, low, high = shape.fragments(ids, *boxes, policy.split_ratio,
                                           policy.split_levels, 20.0)
    counts = np.bincount(fragments, minlength=600)
    assert (counts[:300] >= 4).mean() > 0.9 and (counts[300:] == 1).mean() > 0.8
    t = shape.arrays
    weights = np.concatenate([np.eye(3), [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]],
                              rng.dirichlet((0.3, 0.3, 0.3), 200)])          # (W, 3)
    points = (weights[:, 0, None, None] * t.v0[None] + weights[:, 1, None, None] * t.v1[None]
              + weights[:, 2, None, None] * t.v2[None])                       # (W, 3, 600)
    covered = np.zeros(points.shape[::2], bool)                               # (W, 600)
    for k in range(len(fragments)):
        p = points[:, :, fragments[k]]
        inside = ((p >= low[:, k] - 1e-12 * (1 + np.abs(low[:, k])))
                  & (p <= high[:, k] + 1e-12 * (1 + np.abs(high[:, k])))).all(axis=1)
        covered[:, fragments[k]] |= inside
    assert covered.all()

    def half_area(lo, hi):
        size = hi - lo
        return size[0] * size[1] + size[1] * size[2] + size[2] * size[0]

    whole_low, whole_high = shape.boxes(ids[:300])
    split = np.zeros(300)
    np.add.at(split, fragments[fragments < 300],
              half_area(low[:, fragments < 300], high[:, fragments < 300]))
    assert (split < 0.5 * half_area(whole_low, whole_high)).mean() > 0.9


def test_a_leaf_holds_each_primitive_once():
    rng = np.random.default_rng(2)
    tree = make_context(_scene(rng), core.RenderSettings(), np.float64).geometry.tree.bvh
    leaves = np.sort(tree.leaves, axis=1)
    repeated = (leaves[:, 1:] == leaves[:, :-1]) & (leaves[:, 1:] >= 0)
    assert not repeated.any()
    assert len(tree.primitives()) > len(np.unique(tree.primitives()))   # split ones repeat
    # A slot left by a repeat is padding: no box a ray enters.
    assert np.isnan(tree.leaf_boxes[:, tree.leaves < 0]).all()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_a_tree_of_fragments_finds_the_hits_of_whole_triangles(dtype):
    """Rays with their own origins, from one point (with its terms), leaving the primitives
    they hit, and segments: nearest hits (distance, primitive, barycentrics) and blockers
    are the same through fragments, whole triangles and the flat paths, with fewer
    triangle tests through fragments (where the tree answers: not the direction bins
    of rays from one point, which list whole boxes)."""
    rng = np.random.default_rng(3)
    scene = _scene(rng)
    contexts = [make_context(scene, core.RenderSettings(), dtype, geometry_policy=policy)
                for policy in (DEFAULT_POLICY, WHOLE, FLAT)]
    assert contexts[2].geometry.tree is None
    n = 4000
    directions = rng.normal(size=(3, n))
    directions = (directions / np.linalg.norm(directions, axis=0)).astype(dtype)
    for shared in (None, (0.5, 1.0, 13.0)):
        origins = (rng.uniform(-7, 7, (3, n)) if shared is None
                   else np.array(shared)[:, None]).astype(dtype)
        exclude = rng.integers(-1, 800, n)
        lengths = rng.uniform(0.5, 12, n).astype(dtype)
        answers = []
        for ctx in contexts:
            geometry = ctx.geometry
            origin = None if shared is None else geometry.shared_origin(shared)
            stats = RayStats()
            t, primitive, bary = geometry.intersect(
                RayBatch(origins, directions, 0.0, np.inf, origin, exclude), stats)
            blocked = geometry.occluded(
                RayBatch(origins, directions, 0.0, lengths, origin, exclude), stats)
            answers.append((t, primitive, bary, blocked, stats.triangle_tests))
        for t, primitive, bary, blocked, _ in answers[1:]:
            assert np.array_equal(t, answers[0][0]) and np.array_equal(primitive, answers[0][1])
            assert all(np.array_equal(a, b) for a, b in zip(bary, answers[0][2]))
            assert np.array_equal(blocked, answers[0][3])
        primitive = answers[0][1]
        assert ((primitive >= 200) & (primitive < 500)).sum() > 30        # slivers hit
        if shared is None:      # (rays from one point go through bins of whole boxes)
            assert answers[0][4] < 0.7 * answers[1][4]
    # Rays leaving the surfaces they hit (trails from their leaves) are blocked alike.
    hits = contexts[0].geometry.nearest(RayBatch(rng.uniform(-7, 7, (3, n)).astype(dtype),
                                                 directions), RayStats())
    out = rng.normal(size=hits.normals.shape)
    out = out * np.sign((out * hits.normals).sum(axis=0)) * np.where(hits.front, 1, -1)
    out = (out / np.linalg.norm(out, axis=0)).astype(dtype)
    blocked = [ctx.geometry.occluded(ctx.geometry.spawn(hits.points, hits.normals,
                                                        hits.primitive, out, hits.front),
                                     RayStats()) for ctx in contexts]
    assert np.array_equal(blocked[0], blocked[1]) and np.array_equal(blocked[0], blocked[2])
    assert 0.05 < blocked[0].mean() < 0.95


def test_a_primitive_met_twice_in_a_visit_is_settled_once():
    """Two pairs of one ray with one primitive (fragments in two leaves of one visit) at
    the ray's nearest distance: the ray accepts one of them, with the lower id on a tie
    with another primitive."""
    rays = np.array([0, 0, 0, 1, 1, 1, 2])
    prims = np.array([7, 7, 3, 5, 4, 5, 9])
    t = np.array([2.0, 2.0, 3.0, 1.0, 1.0, 1.0, np.inf])
    t_max = np.full(3, np.inf)
    found = np.zeros(3, bool)
    accepted = []
    keep_nearest(rays, prims, t, t_max, found, lambda owner, pair: accepted.append(
        (owner.tolist(), prims[pair].tolist())))
    assert accepted == [([0, 1], [7, 4])]
    assert t_max.tolist() == [2.0, 1.0, np.inf] and found.tolist() == [True, True, False]
