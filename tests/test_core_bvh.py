"""The BVH behind the aggregate gives exactly the hits of the flat paths, stops rays early,
and is not built for small scenes."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY, bvh, bvh_build, bvh_traverse, cells
from core.geometry.kernels import OcclusionPairs
from core.geometry.tree import TreeAccelerator
from core.rays import RayBatch
from core_scenes import dense_wall_scene

MATERIALS = (core.Material(reflection=0.5), core.Material(diffuse=(0.8, 0.2, 0.1)))
#: A policy under which no scene gets a tree: every primitive is tested flat.
FLAT = dataclasses.replace(DEFAULT_POLICY, tree_min_spheres=10 ** 9,
                           tree_min_triangles=10 ** 9, tree_saved_tests=np.inf)


def _cloud(count, seed=0):
    rng = np.random.default_rng(seed)
    return core.SphereSet(rng.uniform(-5, 5, (count, 3)), rng.uniform(0.02, 0.3, count),
                          rng.integers(0, 2, count), MATERIALS, name="cloud")


def _scene(count, floor=True, meshes=()):
    spheres = (core.Sphere((0, -9000, 0), 8999.3, name="floor"),) if floor else ()
    return core.Scene(camera=core.ScreenCamera(64, 48, eye=(0, 0, 12)), spheres=spheres,
                      sphere_sets=(_cloud(count),), meshes=meshes,
                      lights=(core.PointLight((3, 20, 8)),))


def _contexts(scene, dtype=np.float64, policy=DEFAULT_POLICY):
    """(with a tree under ``policy``, flat) contexts of the same scene; fails if either is
    not what it says."""
    tree = make_context(scene, core.RenderSettings(), dtype, geometry_policy=policy)
    flat = make_context(scene, core.RenderSettings(), dtype, geometry_policy=FLAT)
    assert tree.geometry.tree is not None and flat.geometry.tree is None
    return tree, flat


def _rays(rng, n, dtype, shared_origin=None):
    directions = rng.normal(size=(3, n))
    directions /= np.linalg.norm(directions, axis=0)
    if shared_origin is not None:
        return np.asarray(shared_origin, float)[:, None], directions.astype(dtype)
    return rng.uniform(-6, 6, (3, n)).astype(dtype), directions.astype(dtype)


@pytest.mark.slow
@pytest.mark.parametrize("sorts", ["treelets", "widest", "unsorted"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_tree_finds_exactly_the_flat_paths_hits(dtype, sorts):
    """3,000 spheres, a floor kept out of the tree, 200 triangles: nearest hits (distance and
    primitive) and occlusion agree with the flat paths ray for ray, for rays with their own
    origins, rays sharing one (with its terms) and rays that exclude what they leave; with
    nearest hits found front to back (sorting down to the treelets or to the widest depth,
    ``BVH.nearest_levels``) and level by level unsorted (``BVH.sorts_nearest``)."""
    rng = np.random.default_rng(1)
    corners = rng.uniform(-5, 5, (200, 1, 3)) + rng.normal(scale=0.3, size=(200, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(600).reshape(200, 3), None,
                             np.zeros(200, np.int64), MATERIALS)
    scene = _scene(3000, meshes=(soup,))
    # (Sorted for rays that share an origin and rays that do not alike.)
    policy = dataclasses.replace(DEFAULT_POLICY,
                                 sorted_from=10 ** 9 if sorts == "unsorted" else 0,
                                 deep_sort_crossings=0.0 if sorts == "widest" else np.inf,
                                 coherent_sort_crossings=0.0, incoherent_sort_crossings=0.0)
    tree, flat = _contexts(scene, dtype, policy)
    levels = tree.geometry.tree.bvh.nearest_levels
    widest = int(np.argmax(np.bincount(tree.geometry.tree.bvh.depths)))
    assert (levels is None) == (sorts == "unsorted")
    assert sorts == "unsorted" or (levels[-1] == widest) == (sorts == "widest")
    assert 0 in tree.geometry.flat_spheres.ids      # the floor stays flat beside the tree
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


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_rays_descend_unsorted_where_lines_meet_few_leaves(monkeypatch, dtype):
    """A mesh's tree (a line through it crosses about two leaves): rays from one point and
    rays leaving points in all directions descend it level by level, sorting nothing
    (``GeometryPolicy.coherent_sort_crossings``, ``incoherent_sort_crossings``); a dense
    field of spheres sorts both kinds front to back, and a field of fewer only the rays
    that share their origin.  The hits are the sorted traversal's either way."""
    sorted_calls = []
    rounds = bvh_traverse._rounds
    monkeypatch.setattr(bvh_traverse, "_rounds", lambda *args: sorted_calls.append(1)
                        or rounds(*args))
    scene, _ = _backdrop_and_ball()
    cloud = core.Scene(camera=scene.camera, sphere_sets=(_cloud(20_000),),
                       lights=scene.lights)
    rng = np.random.default_rng(12)
    for case, crossings in ((scene, 2.0), (cloud, 8.0)):
        contexts = [make_context(case, core.RenderSettings(), dtype, geometry_policy=policy)
                    for policy in (DEFAULT_POLICY, dataclasses.replace(
                        DEFAULT_POLICY, coherent_sort_crossings=0.0,
                        incoherent_sort_crossings=0.0))]
        assert (contexts[0].geometry.tree.bvh.leaf_crossings < crossings) == (case is scene)
        for shared in (None, (0.5, 3.0, 11.0)):
            origins, directions = _rays(rng, 3000, dtype, shared)
            answers = []
            for ctx in contexts:
                sorted_calls.clear()
                origin = None if shared is None else ctx.geometry.shared_origin(shared)
                # (Too few rays from the point for its direction bins: the tree answers.)
                answers.append(ctx.geometry.intersect(
                    RayBatch(origins, directions, 0.0, np.inf, origin), RayStats())[:2])
                sorts = bool(sorted_calls)
                if ctx is contexts[1]:
                    assert sorts
                else:
                    assert sorts == (case is cloud and shared is not None)
            assert np.array_equal(answers[0][0], answers[1][0])
            assert np.array_equal(answers[0][1], answers[1][1])
            assert (answers[0][1] >= 0).mean() > 0.1


def test_sphere_set_renders_the_same_through_the_tree_and_flat():
    scene = _scene(1500)
    tree = core.render(scene, core.RenderSettings(precision="float64"))
    flat = core.render(scene, core.RenderSettings(precision="float64"), geometry_policy=FLAT)
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
    assert ctx.geometry.tree is None
    stats = core.render(core.article_scene(30, 20), core.article_settings()).stats
    assert stats.node_tests == 0


def _quads(*quads):
    """One flat grey mesh of quads, each four corners (counter-clockwise)."""
    vertices = np.array([corner for quad in quads for corner in quad], float)
    first = 4 * np.arange(len(quads))[:, None]
    triangles = np.concatenate([first + [0, 1, 2], first + [0, 2, 3]])
    return core.TriangleMesh(vertices, triangles, None, np.zeros(len(triangles), np.intp),
                             (core.SurfaceMaterial(diffuse=(0.8, 0.8, 0.8)),))


def _cube(half=1.0):
    c = [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _quads(*[[c[i] for i in face] for face in faces])


def _floor(z=-1.0, half=10.0):
    return [[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]


@pytest.mark.parametrize("meshes, tree", [
    ((_cube(), _quads(_floor())), True),        # Blender's default cube over a plane
    ((_quads(_floor(), [[-10, 10, -1], [10, 10, -1], [10, 10, 9], [-10, 10, 9]],
             [[-10, -10, -1], [-10, 10, -1], [-10, 10, 9], [-10, -10, 9]]),), False),  # a room
    ((_quads(_floor()),), False)])
def test_a_few_compact_triangles_get_a_tree_and_the_same_image(monkeypatch, meshes, tree):
    """At most ``tree_min_triangles`` triangles get a tree where it saves a ray
    ``tree_saved_tests`` tests (a cube's faces are small beside the floor they stand on:
    12.2 of 14 saved),
    not where every triangle spans the scene (a room's floor and walls, a lone floor); the
    tree answers only rays that leave points (the suns', the world's), batches from one
    origin (the eye, a soft point light's samples) test the flat triangles, and the image
    is the flat test's."""
    scene = core.Scene(camera=core.BlenderCamera(
        matrix_world=((0.6859, -0.324, 0.6516, 7.3589), (0.7277, 0.3054, -0.6142, -6.9258),
                      (0.0, 0.8953, 0.4452, 4.9583), (0, 0, 0, 1)),
        resolution_x=48, resolution_y=27), meshes=meshes,
        spheres=(core.Sphere((2.5, 1.5, 0.0), 1.0, core.SurfaceMaterial()),),
        lights=(core.SunLight((-0.3, 0.4, -0.85), strength=3.0, angle=0.2),
                core.SphereLight((4.08, 1.0, 5.9), power=1000.0, radius=0.1)),
        ambient=(0.05, 0.05, 0.05))
    settings = core.RenderSettings(anti_aliasing="adaptive", samples=4, light_samples=4)
    ctx = make_context(scene, settings, np.float64)
    saved = ctx.geometry.triangle_shape.saved_tests(DEFAULT_POLICY.tree_min_triangles)
    assert (saved >= DEFAULT_POLICY.tree_saved_tests) == tree
    assert (ctx.geometry.tree is not None) == tree == DEFAULT_POLICY.builds_tree(
        0, scene.triangle_count, saved)
    through_tree = []     # (whether the batch shares an origin) of each batch in the tree
    for name in ("nearest_pairs", "occlusion_pairs"):
        method = getattr(TreeAccelerator, name)
        monkeypatch.setattr(TreeAccelerator, name,
                            lambda self, rays, *rest, method=method: through_tree.append(
                                rays.shared is not None) or method(self, rays, *rest))
    chosen = core.render(scene, settings)
    assert (len(through_tree) > 0) == tree and not any(through_tree)
    no_small_trees = dataclasses.replace(DEFAULT_POLICY, tree_saved_tests=np.inf)
    assert make_context(scene, settings, np.float64,
                        geometry_policy=no_small_trees).geometry.tree is None
    flat = core.render(scene, settings, geometry_policy=no_small_trees)
    assert np.array_equal(chosen.image, flat.image)
    assert (chosen.stats.triangle_tests < 0.5 * flat.stats.triangle_tests) == tree


@pytest.mark.parametrize("spheres, triangles", [(24, 0), (25, 0), (0, 16), (0, 17),
                                                (20, 10), (400, 10)])
def test_builds_tree_says_what_the_aggregate_builds(spheres, triangles):
    """The worker-process rule weighs scenes by ``builds_tree``'s counts: with a few
    triangles' saved tests it is the truth."""
    builds_tree = DEFAULT_POLICY.builds_tree
    rng = np.random.default_rng(2)
    sets = (core.SphereSet(rng.uniform(-3, 3, (spheres, 3)), rng.uniform(0.01, 0.05, spheres),
                           np.zeros(spheres, np.intp), (core.Material(),)),) if spheres else ()
    meshes = (core.TriangleMesh(rng.uniform(-3, 3, (3 * triangles, 3)),
                                np.arange(3 * triangles).reshape(-1, 3), None,
                                np.zeros(triangles, np.intp), (core.Material(),)),) \
        if triangles else ()
    scene = core.Scene(camera=core.ScreenCamera(16, 16, eye=(0, 0, 12)), sphere_sets=sets,
                       meshes=meshes, lights=(core.PointLight((3, 20, 8)),))
    ctx = make_context(scene, core.RenderSettings(), np.float64)
    saved = ctx.geometry.triangle_shape.saved_tests(DEFAULT_POLICY.tree_min_triangles)
    assert (ctx.geometry.tree is not None) == builds_tree(scene.sphere_count,
                                                            scene.triangle_count, saved)
    # By counts alone (what the rule weighs): a few triangles never make a scene heavy.
    assert builds_tree(scene.sphere_count, scene.triangle_count) == (spheres > 24
                                                                     or triangles > 16)


def _mixed_boxes(rng, small, large):
    """Boxes (P, 3) of ``small`` tiny primitives in a unit ball among ``large`` big ones."""
    centre = np.concatenate([rng.normal(scale=0.5, size=(small, 3)),
                             rng.uniform(-20, 20, (large, 3))])
    half = np.concatenate([rng.uniform(0.001, 0.02, (small, 3)), rng.uniform(1, 6, (large, 3))])
    order = rng.permutation(small + large)
    return (centre - half)[order], (centre + half)[order]


def _check_tree(tree, ids, low, high):
    """Every id in exactly one leaf; every slot's box holds what is below it."""
    from core.geometry.bvh_build import EMPTY, WIDTH
    assert sorted(tree.primitives().tolist()) == sorted(ids.tolist())
    where = {int(i): k for k, i in enumerate(ids)}
    box_low, box_high = tree.blocks[:3].astype(float), tree.blocks[3:].astype(float)
    for node in range(tree.node_count):
        for slot in range(WIDTH):
            child = tree.children[node, slot]
            if child == EMPTY:
                assert np.isnan(tree.blocks[:, node, slot]).all()
                continue
            lo, hi = box_low[:, node, slot], box_high[:, node, slot]
            if child >= 0:      # an inner node: its children's boxes
                real = tree.children[child] != EMPTY
                assert real.any()
                assert (lo[:, None] <= box_low[:, child][:, real]).all()
                assert (hi[:, None] >= box_high[:, child][:, real]).all()
            else:               # a leaf: its primitives' boxes
                members = [where[int(p)] for p in tree.leaves[-2 - child] if p >= 0]
                assert members
                assert (lo <= low[members]).all() and (hi >= high[members]).all()
    assert (tree.root_box[:3] <= low.min(axis=0)).all()
    assert (tree.root_box[3:] >= high.max(axis=0)).all()


@pytest.mark.slow
def test_leaf_crossings_count_the_leaf_boxes_random_lines_cross():
    """``BVH.leaf_crossings`` (the leaves' areas over the root's) is the mean number of leaf
    boxes crossed by isotropic random lines through the root box (Cauchy-Crofton), counted
    here by brute force over 6,000 such lines; and it tells a sparse field from a dense one
    (``nearest_levels`` sorts deeper in the dense)."""
    rng = np.random.default_rng(11)
    low, high = _mixed_boxes(rng, 600, 40)
    tree = bvh.BVH.build(np.arange(len(low)), low, high)
    leaf = tree.children < -1
    leaf_low = tree.blocks[:3][:, leaf].astype(float)          # (3, L)
    leaf_high = tree.blocks[3:][:, leaf].astype(float)
    root_low, root_high = tree.root_box[:3].astype(float), tree.root_box[3:].astype(float)
    centre, reach = (root_low + root_high) / 2, np.linalg.norm(root_high - root_low) / 2
    # Lines of uniform direction through uniform points of a disc (radius: the root's half
    # diagonal) across it, kept where they cross the root box.
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    e1 = np.cross(d, np.where(np.abs(d[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(d, e1)
    radius, angle = reach * np.sqrt(rng.uniform(size=20000)), rng.uniform(0, 2 * np.pi, 20000)
    o = centre + radius[:, None] * (np.cos(angle)[:, None] * e1 + np.sin(angle)[:, None] * e2)

    def crossed(lo, hi, o, d):          # (lines, boxes): whether each line crosses each box
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo[None] - o[:, :, None]) / d[:, :, None]
            t2 = (hi[None] - o[:, :, None]) / d[:, :, None]
        return np.fmax.reduce(np.fmin(t1, t2), axis=1) <= np.fmin.reduce(np.fmax(t1, t2), axis=1)

    through = crossed(root_low[:, None], root_high[:, None], o, d)[:, 0]
    o, d = o[through][:6000], d[through][:6000]
    counts = crossed(leaf_low, leaf_high, o, d).sum(axis=1)
    error = counts.std() / np.sqrt(len(counts))
    assert len(counts) == 6000 and counts.mean() > 0.5
    assert abs(counts.mean() - tree.leaf_crossings) < 4 * error + 0.01 * tree.leaf_crossings
    # 60,000 boxes filling a cube: a dense field, sorted down to the widest depth.
    dense_centre = rng.uniform(-1, 1, (60000, 3))
    dense = bvh.BVH.build(np.arange(60000), dense_centre - 0.03, dense_centre + 0.03)
    assert tree.leaf_crossings < DEFAULT_POLICY.deep_sort_crossings <= dense.leaf_crossings
    assert tree.nearest_levels in (None, tree.sort_levels())
    assert dense.nearest_levels[-1] == int(np.argmax(np.bincount(dense.depths)))


@pytest.mark.parametrize("cluster_from", [10 ** 9, 500])
def test_sah_tree_holds_every_primitive_once_and_bounds_its_children(cluster_from):
    """Tiny primitives among large ones, ids not 0..P-1, built over primitives and (with
    ``cluster_from`` lowered) over Morton clusters; also a single primitive and two that
    coincide (no plane separates them)."""
    policy = dataclasses.replace(DEFAULT_POLICY, cluster_from=cluster_from)
    rng = np.random.default_rng(3)
    low, high = _mixed_boxes(rng, 1500, 60)
    ids = rng.permutation(5000)[:1560]
    tree = bvh.BVH.build(ids, low, high, policy=policy)
    _check_tree(tree, ids, low, high)
    assert tree.depths.max() <= 12                  # log4 of 1,560 is 5.3
    for count in (1, 2, 9):
        same = np.zeros((count, 3)), np.ones((count, 3))
        _check_tree(bvh.BVH.build(np.arange(count), *same, policy=policy), np.arange(count),
                    *same)


def _backdrop_and_ball():
    """A 5,120-triangle ball (radius 1, at height 1.5) over a 20 x 20 backdrop of 512 large
    triangles in the plane y = 0: CLEVR's case, a fine mesh on a coarse one."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                  (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)],
                 float)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
                  (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
                  (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
                  (8, 6, 7), (9, 8, 1)])
    corners = v[f]
    for _ in range(4):       # 20 * 4^4 = 5,120 triangles
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        corners = np.concatenate([np.stack(x, 1) for x in
                                  ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    corners = corners / np.linalg.norm(corners, axis=2, keepdims=True) + (0, 1.5, 0)
    grid = np.linspace(-10, 10, 17)
    x0, z0 = np.meshgrid(grid[:-1], grid[:-1])
    x0, z0, step = x0.ravel(), z0.ravel(), grid[1] - grid[0]
    quad = [np.stack([x0 + dx, np.zeros_like(x0), z0 + dz], 1)
            for dx, dz in ((0, 0), (0, step), (step, step), (step, 0))]
    backdrop = np.concatenate([np.stack([quad[0], quad[1], quad[2]], 1),
                               np.stack([quad[0], quad[2], quad[3]], 1)])
    everything = np.concatenate([corners, backdrop])
    mesh = core.TriangleMesh(everything.reshape(-1, 3), np.arange(3 * len(everything))
                             .reshape(-1, 3), None, np.zeros(len(everything), np.int64),
                             MATERIALS)
    return core.Scene(camera=core.ScreenCamera(8, 6, eye=(0, 3, 12)), meshes=(mesh,),
                      lights=(core.PointLight((3, 20, 8)),)), len(corners)


def test_rays_away_from_a_fine_mesh_do_not_pay_for_it():
    """Vertical rays and segments onto the backdrop at least 3 from the ball's axis: every
    backdrop triangle's box is one cell, so such a ray's segment meets the boxes of at most
    4 cells (8 triangles, in at most 8 leaves of MAX_LEAF), and a tree that keeps the ball's
    small triangles in their own subtrees (SAH) lets it enter no box of theirs.  So it
    tests at most 8 * MAX_LEAF triangles, and at most WIDTH box tests per node on at most 8
    root-to-leaf paths of the tree's depth D (1 + 8 * WIDTH * (D + 1)).  A tree that mixed
    the ball's triangles into the backdrop's boxes (the Morton tree did) exceeds both."""
    from core.geometry.bvh_build import MAX_LEAF, WIDTH
    scene, ball = _backdrop_and_ball()
    ctx = make_context(scene, core.RenderSettings(), np.float64)
    tree = ctx.geometry.tree.bvh
    assert len(ctx.geometry.flat_triangles) == 0
    rng = np.random.default_rng(5)
    xz = rng.uniform(-9.5, 9.5, (20000, 2))
    xz = xz[np.hypot(*xz.T) > 3][:8000]
    n = len(xz)
    tops = np.stack([xz[:, 0], np.full(n, 5.0), xz[:, 1]])
    down = np.tile([[0.0], [-1.0], [0.0]], n)
    bound_nodes = (1 + 8 * WIDTH * (tree.depths.max() + 2)) * n
    stats = RayStats()
    t, primitive, _ = ctx.geometry.intersect(RayBatch(tops, down), stats)
    assert (primitive >= ball).all() and np.allclose(t, 5.0)
    assert stats.triangle_tests <= 8 * MAX_LEAF * n and stats.node_tests <= bound_nodes
    stats = RayStats()
    assert not ctx.geometry.occluded(RayBatch(tops, down, 0.0, np.full(n, 4.999)), stats).any()
    assert stats.triangle_tests <= 8 * MAX_LEAF * n and stats.node_tests <= bound_nodes


@pytest.mark.slow
@pytest.mark.parametrize("cluster_from", [10 ** 9, 200])
def test_tree_agrees_with_brute_force_on_mixed_sizes(cluster_from):
    """The ball on its backdrop, 600 small spheres around it and 3 large ones, against the
    flat paths (every primitive tested): nearest hits and occlusion, ray for ray."""
    mesh_scene, _ = _backdrop_and_ball()
    rng = np.random.default_rng(8)
    centres = np.concatenate([rng.normal(scale=1.5, size=(600, 3)) + (0, 1.5, 0),
                              [(6, 2, 6), (-6, 3, 0), (0, 2.5, -7)]])
    radii = np.concatenate([rng.uniform(0.02, 0.1, 600), [2.0, 3.0, 2.5]])
    balls = core.SphereSet(centres, radii, rng.integers(0, 2, 603), MATERIALS)
    scene = core.Scene(camera=mesh_scene.camera, meshes=mesh_scene.meshes,
                       sphere_sets=(balls,), lights=mesh_scene.lights)
    tree, flat = _contexts(scene, policy=dataclasses.replace(DEFAULT_POLICY,
                                                            cluster_from=cluster_from))
    for shared in (None, (0.5, 6.0, 11.0)):
        origins, directions = _rays(rng, 3000, np.float64, shared)
        origins = origins + np.array([[0], [3], [0]])
        exclude = rng.integers(-1, len(tree.geometry), 3000)
        lengths = rng.uniform(0.5, 15, 3000)
        results = []
        for ctx in (tree, flat):
            origin = ctx.geometry.shared_origin(np.add(shared, (0, 3, 0))) \
                if shared is not None else None
            batch = RayBatch(origins, directions, 0.0, np.inf, origin, exclude)
            t, primitive, _ = ctx.geometry.intersect(batch, RayStats())
            segments = RayBatch(origins, directions, 0.0, lengths, origin, exclude)
            results.append((t, primitive, ctx.geometry.occluded(segments, RayStats())))
        (t1, p1, o1), (t2, p2, o2) = results
        assert np.array_equal(p1, p2) and np.array_equal(t1, t2) and np.array_equal(o1, o2)
        assert (p1 >= 603).any() and ((p1 >= 0) & (p1 < 603)).any()
        assert o1.any() and not o1.all()


def test_single_rays_leave_the_tree_as_it_was():
    """A batch (or a last chunk) of one ray gets the same hits as the batch it came from, and
    tracing it changes none of the tree's boxes (the slab test works in place on the boxes
    it gathers, never on the tree's own)."""
    scene, _ = _backdrop_and_ball()
    ctx = make_context(scene, core.RenderSettings(), np.float64)
    tree = ctx.geometry.tree.bvh
    root, blocks = tree.root_box.copy(), tree.blocks.copy()
    rng = np.random.default_rng(2)
    origins, directions = _rays(rng, 40, np.float64)
    origins = origins + np.array([[0], [3], [0]])
    together = ctx.geometry.intersect(RayBatch(origins, directions), RayStats())[:2]
    for ray in range(40):
        one = RayBatch(origins[:, ray:ray + 1], directions[:, ray:ray + 1])
        t, primitive, _ = ctx.geometry.intersect(one, RayStats())
        assert t[0] == together[0][ray] and primitive[0] == together[1][ray]
    assert np.array_equal(tree.root_box, root)
    assert np.array_equal(tree.blocks, blocks, equal_nan=True)
    assert (together[1] >= 0).any()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shared", [False, True])
def test_box_tests_give_each_slot_the_textbook_slab_answer(dtype, shared):
    """The tree's box tests (its child boxes against spread per-ray terms, and the root box
    against every ray) give, slot for slot, the entry and the verdict of the textbook slab
    test written pair by pair: max(t_min, largest near plane) <= min(t_max, smallest far
    plane) in the slabs' precision, an empty slot never hit; with rays parallel to an axis,
    some of them lying in the planes of the boxes they meet (0 * inf), and t_max given in
    float64 (inf for some)."""
    from core.geometry.bvh import BVH
    from core.geometry.bvh_build import EMPTY, WIDTH
    from core.geometry.bvh_traverse import _ray_terms, _slabs
    rng = np.random.default_rng(5)
    centre = rng.uniform(-4, 4, (300, 3))
    tree = BVH.build(np.arange(300), centre - 0.3, centre + 0.3)
    n, m = 500, 2000
    origins = rng.uniform(-5, 5, (3, 1 if shared else n))
    directions = rng.normal(size=(3, n))
    directions[0, :50] = 0.0                      # axis-aligned rays ...
    directions[1, 25:75] = 0.0
    if not shared:                                # ... some starting on a box's planes
        origins[0, :50] = tree.blocks[0, 0, 0]
        origins[1, 25:75] = tree.blocks[4, 0, 1]
    with np.errstate(divide="ignore"):
        inverse = 1 / directions
    t_max = rng.uniform(0.5, 12, n)
    t_max[::7] = np.inf
    # Pairs: the axis-aligned rays against node 0 (whose planes some lie in), then at random.
    rays = np.concatenate([np.arange(75), np.sort(rng.integers(0, n, m - 75))])
    nodes = np.concatenate([np.zeros(75, np.intp), rng.integers(0, tree.node_count, m - 75)])
    rows = _ray_terms(origins, inverse, dtype)
    with np.errstate(invalid="ignore"):         # (as ``traverse`` runs the slab tests)
        near, hit = _slabs(tree.blocks.take(nodes, axis=1), rays, *rows, 1e-3, t_max)

    planes = tree.blocks[:, nodes, :].astype(dtype)                        # (6, m, W)
    o = np.concatenate([origins, origins]).astype(dtype)[:, rays if not shared else [0] * m]
    inv = np.concatenate([inverse, inverse]).astype(dtype)[:, rays]
    with np.errstate(invalid="ignore"):
        t = (planes - o[:, :, None]) * inv[:, :, None]
    low, high = np.fmin(t[:3], t[3:]), np.fmax(t[:3], t[3:])
    expected_near = np.maximum(np.fmax(np.fmax(low[0], low[1]), low[2]), dtype(1e-3))
    expected_far = np.minimum(np.fmin(np.fmin(high[0], high[1]), high[2]),
                              t_max[rays].astype(dtype)[:, None])
    expected_hit = expected_near <= expected_far
    assert near.shape == hit.shape == (m, WIDTH) and near.dtype == dtype
    assert np.array_equal(hit, expected_hit)
    assert np.array_equal(near[hit], expected_near[hit])
    empty = tree.children[nodes] == EMPTY
    assert empty.any() and not hit[empty].any()
    assert hit.any() and not hit.all()
    assert (hit & np.isin(rays, np.arange(75))[:, None]).any()
    # The root box against every ray: the same test, for one box.
    root = tree.root_box[:, None, None].copy()
    with np.errstate(invalid="ignore"):
        root_near, root_hit = _slabs(root, np.arange(n), *rows, 1e-3, t_max)
    all_o = np.concatenate([origins, origins]).astype(dtype)
    all_inv = np.concatenate([inverse, inverse]).astype(dtype)
    with np.errstate(invalid="ignore"):
        t = (tree.root_box.astype(dtype)[:, None] - all_o) * all_inv
    near_root = np.maximum(np.fmax.reduce(np.fmin(t[:3], t[3:]), axis=0), dtype(1e-3))
    far_root = np.minimum(np.fmin.reduce(np.fmax(t[:3], t[3:]), axis=0), t_max.astype(dtype))
    assert np.array_equal(root_hit[:, 0], near_root <= far_root)
    assert np.array_equal(root_near[root_hit[:, 0], 0], near_root[near_root <= far_root])


def _leaving_rays(ctx, rng, n):
    """n occlusion rays leaving the surfaces that random rays hit (as shading makes them:
    ``Aggregate.spawn``, offsets, exclusions, sources), each into the hemisphere it leaves."""
    origins, directions = _rays(rng, n, ctx.geometry.dtype)
    hits = ctx.geometry.nearest(RayBatch(origins, directions), RayStats())
    out = rng.normal(size=hits.normals.shape)
    out /= np.linalg.norm(out, axis=0)
    front = hits.front
    side = np.where(front, 1.0, -1.0) * np.sign((out * hits.normals).sum(axis=0))
    out = (out * side).astype(ctx.geometry.dtype)     # on the side each ray arrived from
    return ctx.geometry.spawn(hits.points, hits.normals, hits.primitive, out, front)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_occlusion_trails_block_exactly_the_rays_the_flat_paths_do(monkeypatch, dtype):
    """Rays leaving the hit surfaces of 3,000 spheres, a floor kept out of the tree and 200
    triangles start at their primitive's leaf and climb (``bvh_traverse._trail``): the same blocked
    rays as the flat paths (every primitive tested) and as the root-down traversal, with
    sources in the tree, out of it (the floor) and none (-1), short segments and infinite."""
    rng = np.random.default_rng(3)
    corners = rng.uniform(-5, 5, (200, 1, 3)) + rng.normal(scale=0.3, size=(200, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(600).reshape(200, 3), None,
                             np.zeros(200, np.int64), MATERIALS)
    tree, flat = _contexts(_scene(3000, meshes=(soup,)), dtype)
    rays = _leaving_rays(tree, rng, 6000)
    n = len(rays)
    source = rays.source.copy()
    source[rng.random(n) < 0.1] = -1
    kinds = np.bincount(np.searchsorted([1, 3001], source, side="right"), minlength=3)
    assert kinds[0] > 0 and kinds[1] > 1000 and kinds[2] > 100   # none or floor, spheres, triangles
    for length in (np.inf, rng.uniform(0.05, 3, n).astype(dtype)):
        segments = RayBatch(rays.origins, rays.directions, rays.t_min, length, None,
                            rays.exclude, source)
        root_down = RayBatch(rays.origins, rays.directions, rays.t_min, length, None,
                             rays.exclude)
        trail_stats, root_stats = RayStats(), RayStats()
        blocked = tree.geometry.occluded(segments, trail_stats)
        assert np.array_equal(blocked, flat.geometry.occluded(segments, RayStats()))
        assert np.array_equal(blocked, tree.geometry.occluded(root_down, root_stats))
        assert blocked.mean() > 0.1 and not blocked.all()
        assert trail_stats.node_tests != root_stats.node_tests     # the trail was taken


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_trails_by_leaf_block_exactly_the_rays_every_sphere_does(monkeypatch, dtype):
    """A tree of spheres alone (a floor kept out of it) visits its trails' leaves through the
    leaf-ordered spheres (``OcclusionPairs.slot_blocks``): the same blocked rays as the flat path
    (every sphere tested) and as the visit by primitive, with the same sphere tests, for
    rays leaving spheres, the floor and nothing, short segments and infinite, with fewer
    sphere tests (the spheres the rays leave are not tested)."""
    from core.geometry.bvh import BVH
    rng = np.random.default_rng(8)
    tree, flat = _contexts(_scene(3000), dtype)
    rays = _leaving_rays(tree, rng, 6000)
    n = len(rays)
    source = rays.source.copy()
    source[rng.random(n) < 0.1] = -1
    assert (source >= 1).sum() > 1000 and (source < 1).sum() > 100
    traverse, leaf_blocks = BVH.traverse, OcclusionPairs.slot_blocks
    calls = []

    def by_primitive(self, *args, leaf_blocks=None, **kwargs):
        return traverse(self, *args, **kwargs)

    def counted(*args):
        calls.append(1)
        return leaf_blocks(*args)

    monkeypatch.setattr(OcclusionPairs, "slot_blocks", counted)

    for length in (np.inf, rng.uniform(0.05, 3, n).astype(dtype)):
        segments = RayBatch(rays.origins, rays.directions, rays.t_min, length, None,
                            rays.exclude, source)
        leaf_stats, prim_stats = RayStats(), RayStats()
        blocked = tree.geometry.occluded(segments, leaf_stats)
        assert calls                                       # the leaf path was taken
        monkeypatch.setattr(BVH, "traverse", by_primitive)
        calls.clear()
        assert np.array_equal(blocked, tree.geometry.occluded(segments, prim_stats))
        assert not calls
        monkeypatch.setattr(BVH, "traverse", traverse)
        assert np.array_equal(blocked, flat.geometry.occluded(segments, RayStats()))
        # (The leaf path drops the pairs of the sphere a ray excludes before testing them.)
        assert 0 < leaf_stats.sphere_tests < prim_stats.sphere_tests
        assert leaf_stats.node_tests == prim_stats.node_tests
        assert blocked.mean() > 0.1 and not blocked.all()
    # Segments from random points to the centres of the spheres they leave and ignore:
    # blocked only by another sphere.
    aimed = rng.integers(1, 3001, n)
    centers = tree.geometry.spheres.centers[aimed].T
    start = rng.uniform(-6, 6, (3, n))
    towards = centers - start
    length = np.linalg.norm(towards, axis=0)
    segments = RayBatch(start.astype(dtype), (towards / length).astype(dtype), 0.0,
                        length.astype(dtype), None, aimed, aimed)
    blocked = tree.geometry.occluded(segments, RayStats())
    assert np.array_equal(blocked, flat.geometry.occluded(segments, RayStats()))
    assert 0.1 < blocked.mean() < 0.9


def test_leaf_ordered_spheres_hold_each_leafs_spheres_in_its_slots():
    scene = _scene(2000)
    geometry = make_context(scene, core.RenderSettings(), np.float32).geometry
    x, y, z, radii, ids = geometry.tree.leaf_spheres()
    assert np.array_equal(ids, geometry.tree.bvh.leaves.ravel())
    held = ids >= 0
    assert held.sum() == 2000
    for k, column in enumerate((x, y, z, radii)):
        assert column.dtype == np.float32 and column.shape == ids.shape
        shape = geometry.sphere_shape
        values = shape.centers_t[k] if k < 3 else shape.radii
        assert np.array_equal(column[held], values[ids[held]])
        assert np.isnan(column[~held]).all()


@pytest.mark.parametrize("count", [30, 70_000])
def test_leaf_boxes_hold_each_slots_primitive_within_its_leafs_box(count):
    """Each leaf slot's box (``BVH.leaf_boxes``) holds its primitive's box (float32, padded),
    lies within the leaf's own box in its node, and is NaN in a padding slot: with and
    without the Morton clusters (``GeometryPolicy.cluster_from``)."""
    from core.geometry.bvh import BVH
    rng = np.random.default_rng(9)
    low = rng.uniform(-5, 5, (count, 3))
    high = low + rng.uniform(0.001, 0.05, (count, 3))
    ids = rng.permutation(count) + 3
    tree = BVH.build(ids, low, high)
    boxes = tree.leaf_boxes
    assert boxes.shape == (6,) + tree.leaves.shape and boxes.dtype == np.float32
    held = tree.leaves >= 0
    where = np.empty(count + 3, np.intp)
    where[ids] = np.arange(count)
    prim = where[tree.leaves[held]]
    assert (boxes[:3, held] <= low[prim].T).all() and (boxes[3:, held] >= high[prim].T).all()
    assert np.isnan(boxes[:, ~held]).all()
    node, slot = np.nonzero(tree.children <= -2)
    leaf = -2 - tree.children[node, slot]
    own = tree.blocks[:, node, slot]                                  # (6, L)
    inside = (boxes[:3, leaf] >= own[:3, :, None]) & (boxes[3:, leaf] <= own[3:, :, None])
    assert (inside | ~held[leaf][None]).all()


def test_trail_tables_hold_each_primitives_leaf_and_each_nodes_parent():
    from core.geometry.bvh import BVH
    from core.geometry.bvh_build import EMPTY
    rng = np.random.default_rng(4)
    low = rng.uniform(-5, 5, (5000, 3))
    ids = rng.permutation(6000)[:5000]
    tree = BVH.build(ids, low, low + rng.uniform(0.01, 0.2, (5000, 3)))
    home, parent = tree.trail_tables
    assert home.dtype == parent.dtype == np.int32
    assert np.array_equal(np.flatnonzero(home >= 0), np.sort(ids))
    slots = tree.children[home[ids]]                               # (5000, WIDTH)
    leaves = np.where(slots <= -2, -2 - slots, 0)
    holds = (tree.leaves[leaves] == ids[:, None, None]).any(axis=2) & (slots <= -2)
    assert (holds.sum(axis=1) == 1).all()      # each primitive in one leaf slot of its home
    assert parent[0] == -1 and (parent[1:] >= 0).all()
    inner = tree.children[parent[1:]]
    assert ((inner == np.arange(1, tree.node_count)[:, None]) & (inner != EMPTY)).any(axis=1).all()
    assert (tree.depths[parent[1:]] == tree.depths[1:] - 1).all()


def test_sibling_tables_hold_each_nodes_parents_other_slots():
    """A trail's climbing step from a node meets its parent's other slots (boxes and
    references), and counts the real ones as box tests."""
    from core.geometry.bvh import BVH
    from core.geometry.bvh_build import EMPTY, WIDTH
    rng = np.random.default_rng(5)
    low = rng.uniform(-5, 5, (4000, 3))
    tree = BVH.build(np.arange(4000), low, low + rng.uniform(0.01, 0.2, (4000, 3)))
    parent = tree.trail_tables[1]
    planes, children, counts = tree.sibling_tables
    assert planes.shape == (6, tree.node_count, WIDTH - 1) and children.shape[1] == WIDTH - 1
    assert (children[0] == EMPTY).all() and np.isnan(planes[:, 0]).all() and counts[0] == 0
    for node in range(1, tree.node_count):
        up = parent[node]
        others = np.flatnonzero(tree.children[up] != node)
        assert np.array_equal(children[node], tree.children[up, others])
        assert np.array_equal(planes[:, node], tree.blocks[:, up, others], equal_nan=True)
        assert counts[node] == tree.child_counts[up] - 1


def test_rays_leaving_a_dense_wall_are_blocked_near_their_leaf():
    """Rays leaving the spheres of a dense wall into it meet fewer boxes from their leaves up
    than from the root down, and are blocked the same."""
    scene = dense_wall_scene(MATERIALS[0])
    ctx = make_context(scene, core.RenderSettings(), np.float64)
    rng = np.random.default_rng(6)
    rays = _leaving_rays(ctx, rng, 3000)
    trail_stats, root_stats = RayStats(), RayStats()
    blocked = ctx.geometry.occluded(rays, trail_stats)
    assert np.array_equal(blocked, ctx.geometry.occluded(
        RayBatch(rays.origins, rays.directions, rays.t_min, rays.t_max, None, rays.exclude),
        root_stats))
    assert blocked.mean() > 0.3
    assert trail_stats.node_tests < 0.8 * root_stats.node_tests


@pytest.mark.slow
@pytest.mark.parametrize("count", [1, 3, 40, 3000])
def test_trails_find_every_blocker_a_brute_force_finds(count):
    """Boxes as the primitives themselves (a pair blocks where the ray's segment crosses the
    primitive's own box): from the trails (sources in the tree, out of it, none) exactly
    the rays a test of every primitive blocks, in trees of one leaf to many levels."""
    from core.geometry.bvh import BVH
    rng = np.random.default_rng(count)
    low = rng.uniform(-5, 5, (count, 3))
    high = low + rng.uniform(0.05, 1.0, (count, 3))
    ids = np.arange(count) + 7                        # ids need not start at 0
    tree = BVH.build(ids, low, high)
    n = 3000
    source = rng.integers(0, count, n)
    origins = (low[source] + high[source]).T / 2      # inside the box each ray leaves
    directions = rng.normal(size=(3, n))
    directions /= np.linalg.norm(directions, axis=0)
    with np.errstate(divide="ignore"):
        inverse = 1 / directions
    lengths = rng.uniform(0.1, 6, n)
    sources = ids[source]
    sources[:300] = -1
    sources[300:400] = 10 ** 6                       # not a primitive of the tree

    def crosses(r, prims):
        k = prims - 7
        with np.errstate(invalid="ignore", divide="ignore"):
            a = (low[k].T - origins[:, r]) * inverse[:, r]
            b = (high[k].T - origins[:, r]) * inverse[:, r]
        near = np.maximum(np.fmin(a, b).max(axis=0), 0.0)
        far = np.minimum(np.fmax(a, b).min(axis=0), lengths[r])
        # Each ray ignores the box it leaves (as a ray ignores its own primitive).
        return np.where((near <= far) & (prims != ids[source][r]), 0.0, np.inf)

    every = np.repeat(np.arange(n), count), np.tile(ids, n)
    expected = np.zeros(n, bool)
    expected[every[0][crosses(*every) < np.inf]] = True
    trailed = tree.traverse(origins, inverse, 0.0, lengths.copy(), crosses, any_hit=True,
                            sources=sources)
    root_down = tree.traverse(origins, inverse, 0.0, lengths.copy(), crosses, any_hit=True)
    assert np.array_equal(trailed, expected) and np.array_equal(root_down, expected)
    if count > 1:
        assert expected.any() and not expected.all()


@pytest.mark.parametrize("median_up_to, max_leaf", [(1, 4), (16, 1), (6, 2)])
def test_binary_tree_boxes_are_exactly_their_primitives_bounds(median_up_to, max_leaf):
    """Every node of the binary build holds exactly the boxes order[start:start + count]:
    its box is their exact minimum and maximum (nodes split by SAH take their children's
    boxes from their bins; parked ones, of at most median_up_to primitives, are made
    bottom up), its children split its range (small nodes at count // 2), and its leaves
    hold at most max_leaf; mixed sizes and a few coincident boxes (no plane splits them)."""
    rng = np.random.default_rng(5)
    low, high = _mixed_boxes(rng, 3000, 80)
    low[:40], high[:40] = low[40], high[40]
    low, high = np.ascontiguousarray(low.T), np.ascontiguousarray(high.T)
    tree = bvh_build.build_binary_sah(low, high, max_leaf=max_leaf, median_up_to=median_up_to)
    assert sorted(tree.order.tolist()) == list(range(low.shape[1]))
    for node in range(len(tree.left)):
        members = tree.order[tree.start[node]:tree.start[node] + tree.count[node]]
        assert np.array_equal(tree.low[:, node], low[:, members].min(axis=1))
        assert np.array_equal(tree.high[:, node], high[:, members].max(axis=1))
        left = tree.left[node]
        if left < 0:
            assert tree.count[node] <= max_leaf
            continue
        assert tree.start[left] == tree.start[node]
        assert tree.start[left + 1] == tree.start[node] + tree.count[left]
        assert tree.count[left] + tree.count[left + 1] == tree.count[node]
        assert tree.depth[left] == tree.depth[left + 1] == tree.depth[node] + 1
        if tree.count[node] <= median_up_to:
            assert tree.count[left] == tree.count[node] // 2


def test_morton_codes_interleave_each_coordinates_21_bits_and_cells_cut_at_prefixes():
    """``morton_codes`` (spread by table) against bit-by-bit interleaving of the cells,
    and ``morton_cells`` (by bisection) against trying every 3-bit prefix in turn."""
    rng = np.random.default_rng(2)
    points = rng.uniform(-3, 7, (3, 500))
    points[:, :5] = points[:, 5:6]
    codes = cells.morton_codes(points)
    low, extent = points.min(axis=1), np.ptp(points, axis=1).max()
    grid = ((points - low[:, None]) / extent * (2 ** 21 - 1)).astype(np.int64)
    expected = [sum(((int(grid[axis, i]) >> bit) & 1) << (3 * bit + axis)
                    for bit in range(21) for axis in range(3)) for i in range(500)]
    assert codes.tolist() == expected
    ordered = np.sort(codes)
    for per_cell in (1, 2, 4, 30, 499, 10 ** 6):
        for shift in range(0, 64, 3):
            start = np.r_[True, (ordered[1:] >> np.uint64(shift))
                          != (ordered[:-1] >> np.uint64(shift))]
            if start.sum() * per_cell <= len(ordered):
                break
        assert np.array_equal(cells.morton_cells(ordered, per_cell), start)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_front_to_back_orders_pairs_by_ray_then_entry(dtype):
    """``bvh_traverse.front_to_back``: pairs by ray (up to the last of a chunk), then by entry
    distance, negative, signed zero and huge entries included; in float32 (one sort of
    packed keys) equal entries keep their order, as a stable sort by (ray, entry) has them."""
    rng = np.random.default_rng(3)
    count = 30_000
    local = rng.integers(0, bvh_traverse.RAY_CHUNK, count)
    local[:3] = bvh_traverse.RAY_CHUNK - 1
    near = rng.choice(np.array([-3.5, -1e-30, -0.0, 0.0, 1e-30, 0.25, 2.0, 7.5, 3e38],
                               dtype), count)
    near[::7] = rng.uniform(-10, 10, len(near[::7]))
    order = bvh_traverse.front_to_back(local, near)
    assert np.array_equal(np.sort(order), np.arange(count))     # a permutation
    expected = np.lexsort((near, local))                         # stable: ties by position
    if dtype == np.float32:
        assert np.array_equal(order, expected)
    else:
        assert np.array_equal(local[order], local[expected])
        assert np.array_equal(near[order], near[expected])


@pytest.mark.slow
@pytest.mark.parametrize("semantics", ["default", "article"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_nearest_hits_by_leaf_slot_match_the_flat_paths(monkeypatch, dtype, semantics):
    """A tree of spheres alone visits its leaves by slot on the leaf-ordered spheres
    (``slot_visit``), dropping the pairs of each ray's own sphere before their roots, front
    to back and unsorted alike.  Distances and primitives agree ray for ray with the flat
    paths, for rays with their own origins and rays from one point (the same roots), in
    both hit rules (the article's textbook roots) and precisions; and the two traversals
    agree for rays sharing an origin without per-sphere terms."""
    scene = _scene(3000)
    settings = core.RenderSettings(semantics=semantics)
    no_terms = dataclasses.replace(DEFAULT_POLICY, shared_terms_limit=0)
    # Sorted front to back and unsorted (``BVH.sorts_nearest``).
    contexts = [make_context(scene, settings, dtype, geometry_policy=dataclasses.replace(
        no_terms, sorted_from=sorted_from)) for sorted_from in (0, 10 ** 9)]
    slot_visits = []
    for ctx in contexts:
        leaf_spheres = ctx.geometry.tree.leaf_spheres
        monkeypatch.setattr(ctx.geometry.tree, "leaf_spheres",
                            lambda f=leaf_spheres: slot_visits.append(1) or f())
    flat = make_context(scene, settings, dtype,
                        geometry_policy=dataclasses.replace(FLAT, shared_terms_limit=0))
    rng = np.random.default_rng(4)
    for case in ("own origins", "one point", "shared origin"):
        origins, directions = _rays(rng, 4000, dtype, None if case == "own origins"
                                    else (0.5, 1.0, 11.0))
        share = case == "shared origin"
        if case == "one point":     # (per-ray origins, all equal: no shared terms)
            origins = np.repeat(origins, 4000, axis=1).astype(dtype)
        # Half the rays exclude the sphere they would hit first, the rest random ones.
        origin = flat.geometry.shared_origin(origins[:, 0]) if share else None
        first = flat.geometry.intersect(RayBatch(origins, directions, 0.0, np.inf, origin),
                                        RayStats())[1]
        exclude = rng.integers(-1, 3001, 4000)
        exclude[:2000] = first[:2000]
        assert (first[:2000] >= 1).sum() > 100
        results = []
        for ctx in contexts + [flat]:
            origin = ctx.geometry.shared_origin(origins[:, 0]) if share else None
            assert origin is None or origin.tree_terms is None
            batch = RayBatch(origins, directions, 0.0, np.inf, origin, exclude)
            results.append(ctx.geometry.intersect(batch, RayStats())[:2])
        (t1, p1), (t2, p2), (t3, p3) = results
        assert np.array_equal(p1, p2) and np.array_equal(t1, t2)
        if not share:       # (a shared origin's flat spheres take its extended terms)
            assert np.array_equal(p1, p3) and np.array_equal(t1, t3)
        assert ((p1 >= 1) & (p1 < 3001)).any() and (p1 == 0).any() and (p1 < 0).any()
    assert contexts[0].geometry.tree.bvh.sorts_nearest
    assert not contexts[1].geometry.tree.bvh.sorts_nearest
    assert slot_visits


def _same_arrays(a, b, fields):
    """Every field of a and b the same array, bit for bit (NaN padding included)."""
    for field in fields:
        x, y = np.asarray(getattr(a, field)), np.asarray(getattr(b, field))
        assert x.dtype == y.dtype and x.shape == y.shape, field
        assert x.tobytes() == y.tobytes(), field


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("case", ["mixed", "coincident", "one huge"])
def test_a_binary_build_in_parts_is_the_tree_one_build_makes(monkeypatch, threads, case):
    """``build_binary_sah`` on a thread pool cuts the tree's top into parts (the root, then
    the largest part again, until each is small enough), builds them apart and joins them:
    the same nodes in the same order, boxes, children, ranges, depths and order, for leaves
    of one and of four, parked small nodes, coincident boxes (median splits) and a root
    split that leaves almost everything on one side (cut again)."""
    from concurrent.futures import ThreadPoolExecutor
    rng = np.random.default_rng(7)
    low, high = _mixed_boxes(rng, 3000, 80)
    if case == "coincident":
        low[:900], high[:900] = low[900], high[900]
    elif case == "one huge":
        low[0], high[0] = -1e4, 1e4
    low, high = np.ascontiguousarray(low.T), np.ascontiguousarray(high.T)
    joins = []
    joined = bvh_build._joined
    monkeypatch.setattr(bvh_build, "_joined", lambda *a: joins.append(1) or joined(*a))
    fields = ("low", "high", "left", "start", "count", "depth", "order")
    for max_leaf, median_up_to in ((4, 1), (1, 16)):
        one = bvh_build.build_binary_sah(low, high, max_leaf=max_leaf,
                                         median_up_to=median_up_to)
        with ThreadPoolExecutor(threads) as pool:
            parts = bvh_build.build_binary_sah(low, high, max_leaf=max_leaf,
                                               median_up_to=median_up_to, pool=pool,
                                               threads=threads, parallel_from=500)
        _same_arrays(parts, one, fields)
    assert len(joins) >= 2 * (threads - 1)     # it was cut (twice a build at least)


@pytest.mark.parametrize("cluster_from", [10 ** 9, 2000])
def test_a_tree_built_on_threads_is_the_tree_one_thread_builds(monkeypatch, cluster_from):
    """``BVH.build`` on 2 threads (the primitives' planes and the leaves' beside the rest,
    the SAH build in parts) gives the one-thread tree, bit for bit, over primitives and over
    Morton clusters of mixed sizes."""
    policy = dataclasses.replace(DEFAULT_POLICY, parallel_from=500, cluster_from=cluster_from)
    rng = np.random.default_rng(8)
    low, high = _mixed_boxes(rng, 6000, 100)
    ids = rng.permutation(9000)[:6100]
    calls = []
    parallel = bvh_build._parallel_sah
    monkeypatch.setattr(bvh_build, "_parallel_sah", lambda *a: calls.append(1) or parallel(*a))
    one = bvh.BVH.build(ids, low, high, policy=policy)
    assert not calls
    two = bvh.BVH.build(ids, low, high, threads=2, policy=policy)
    assert calls
    _same_arrays(two, one, ("root_box", "blocks", "children", "leaves", "child_counts",
                            "depths", "leaf_boxes"))
    assert two.origin_reach == one.origin_reach


def test_a_render_builds_its_tree_on_its_threads(monkeypatch):
    """``core.render`` builds the tree on as many threads as it renders tiles with (the
    workers wait for the context meanwhile), one thread for threads=1; the same image."""
    policy = dataclasses.replace(DEFAULT_POLICY, parallel_from=500)
    calls = []
    parallel = bvh_build._parallel_sah
    monkeypatch.setattr(bvh_build, "_parallel_sah",
                        lambda *a: calls.append(a[-1]) or parallel(*a))
    scene = _scene(3000)
    one = core.render(scene, core.RenderSettings(threads=1, tile_size=32),
                      geometry_policy=policy)
    assert calls == []
    two = core.render(scene, core.RenderSettings(threads=2, tile_size=32),
                      geometry_policy=policy)
    assert calls == [2]
    assert np.array_equal(one.image, two.image)
