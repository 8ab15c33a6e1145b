"""Direction bins (``core.geometry.bins``) answer rays that share an origin exactly as the tree
does: every box a ray passes through is listed in the ray's cell, the aggregate's hits and
occlusion are the tree's ray for ray (grazing rays included), renders are identical, and bins
are refused where they would not pay (a dense field) or would be too large."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY, bins_build
from core.geometry.bins import OriginBins
from core.geometry.cells import direction_cells
from core.rays import RayBatch
from core_scenes import dense_wall_scene

#: A policy that gives no origin bins: the tree answers every batch.
NO_BINS = dataclasses.replace(DEFAULT_POLICY, bins_max_primitives=-1)

MATERIALS = (core.Material(reflection=0.5), core.Material(diffuse=(0.8, 0.2, 0.1)))


def _unit(vectors):
    return vectors / np.linalg.norm(vectors, axis=0)


def _boxes(rng, origin, count):
    """Boxes of every kind around ``origin``: small and large, far and near, some straddling
    the faces' planes through the origin, one containing it."""
    centres = origin + rng.uniform(-4, 4, (count, 3))
    half = rng.choice([1e-4, 0.05, 0.5, 2.0], count)[:, None] * rng.uniform(0.2, 1, (count, 3))
    low, high = centres - half, centres + half
    low[0], high[0] = origin - 0.1, origin + 0.2           # contains the origin
    low[1], high[1] = origin + (0.5, -1, -1), origin + (1.0, 1, 1)   # straddles y and z
    return low, high


def _slab_hits(origin, directions, low, high):
    """(n, K) whether rays from origin (3,) along directions (3, n) meet boxes (K, 3) at
    t >= 0, by the slab test in float64."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1 / directions.astype(np.float64)
        t0 = (low.T[:, None, :] - origin[:, None, None]) * inverse[:, :, None]
        t1 = (high.T[:, None, :] - origin[:, None, None]) * inverse[:, :, None]
    near = np.fmax.reduce(np.fmin(t0, t1), axis=0)
    far = np.fmin.reduce(np.fmax(t0, t1), axis=0)
    return (near <= far) & (far >= 0)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_a_ray_finds_every_box_it_passes_through_in_its_cell(dtype):
    """Random boxes (tiny to large, straddling face planes, one around the origin) and rays:
    random ones, rays aimed at the boxes' corners and just inside and outside them, and rays
    along the cube's axes, edges and corners (where two or three faces meet).  Every box a
    ray meets is listed in the ray's cell; the cells' lists are ascending and match the
    offsets."""
    rng = np.random.default_rng(5)
    origin = np.array([0.3, -0.2, 1.1])
    low, high = _boxes(rng, origin, 300)
    grid = OriginBins.build(origin, np.arange(300) * 2 + 7, low, high, cells=64,
                            max_entries=1 << 24, max_mean=np.inf)
    corners = np.stack([np.where(np.array(bits)[None, :], high, low)
                        for bits in np.ndindex(2, 2, 2)])                     # (8, K, 3)
    aimed = (corners.reshape(-1, 3) - origin).T
    nudges = [_unit(aimed + rng.normal(scale=s, size=aimed.shape) * np.linalg.norm(aimed, axis=0))
              for s in (1e-9, 1e-6)]
    edges = np.array(list(np.ndindex(3, 3, 3)), float).T - 1
    edges = edges[:, np.abs(edges).sum(axis=0) > 0]
    directions = np.concatenate([_unit(rng.normal(size=(3, 20000))), _unit(aimed), *nudges,
                                 _unit(edges)], axis=1).astype(dtype)
    cell = direction_cells(directions, grid.cells)
    listed = np.zeros((directions.shape[1], 300), bool)
    for row, c in enumerate(cell):
        listed[row, (grid.cell_entries(c) - 7) // 2] = True
    met = _slab_hits(origin, directions, low, high)
    assert met.sum() > 2000 and met[:, 0].all()
    assert not (met & ~listed).any()
    # Listing is conservative, not everything: most (ray, box) pairs are not listed.
    assert listed.mean() < 0.2
    sizes = np.diff(grid.starts)
    owner = np.repeat(np.arange(len(sizes)), sizes)
    same_cell = owner[1:] == owner[:-1]
    assert (np.diff(grid.primitives)[same_cell] > 0).all()


def _cloud_scene(count=900, triangles=150, seed=2):
    rng = np.random.default_rng(seed)
    cloud = core.SphereSet(rng.uniform(-5, 5, (count, 3)), rng.uniform(0.02, 0.3, count),
                           rng.integers(0, 2, count), MATERIALS, name="cloud")
    corners = rng.uniform(-5, 5, (triangles, 1, 3)) + rng.normal(scale=0.3, size=(triangles, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(3 * triangles).reshape(-1, 3),
                             None, np.zeros(triangles, np.int64), MATERIALS, name="soup")
    floor = core.Sphere((0, -9000, 0), 8994.0, name="floor")
    return core.Scene(camera=core.ScreenCamera(64, 48, eye=(0, 0, 12)), spheres=(floor,),
                      sphere_sets=(cloud,), meshes=(soup,),
                      lights=(core.PointLight((3, 20, 8)),))


def _silhouette_directions(rng, origin, centres, radii, per_sphere):
    """Unit directions from origin (3,) grazing spheres' silhouettes: on the tangent cone,
    and a relative 1e-7 of its angle inside and outside it."""
    axis = centres - origin
    distance = np.linalg.norm(axis, axis=1, keepdims=True)
    axis /= distance
    side = np.cross(axis, rng.normal(size=(len(axis), 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    angle = np.arcsin(np.minimum(radii[:, None] / distance, 1))
    out = []
    for scale in (1 - 1e-7, 1.0, 1 + 1e-7):
        for _ in range(per_sphere):
            a = angle * scale
            out.append(np.cos(a) * axis + np.sin(a) * side)
    return np.concatenate(out).T


@pytest.mark.parametrize("semantics", ["default", "article"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_bins_answer_as_the_tree_does(dtype, semantics):
    """900 spheres and 150 triangles in the tree, a floor beside it: rays from the eye, from
    a light and from a point inside the cloud and a sphere's box (random and grazing the
    spheres' silhouettes) get the tree's nearest hits (distance, primitive, barycentrics) and occlusion, bit for
    bit, without a single box test."""
    scene = _cloud_scene()
    settings = core.RenderSettings(semantics=semantics)
    binned = make_context(scene, settings, dtype).geometry
    tree = make_context(scene, settings, dtype, geometry_policy=NO_BINS).geometry
    rng = np.random.default_rng(3)
    centres, radii = scene.sphere_sets[0].centers, scene.sphere_sets[0].radii
    seen = []
    for origin in ((0.0, 0.0, 12.0), (3.0, 20.0, 8.0), tuple(centres[0] + 0.95 * radii[0])):
        origin = np.array(origin)
        directions = np.concatenate([_unit(rng.normal(size=(3, 6000))),
                                     _silhouette_directions(rng, origin, centres[:300],
                                                            radii[:300], 2)], axis=1)
        directions = directions.astype(dtype)
        n = directions.shape[1]
        lengths = rng.uniform(0.5, 30, n).astype(dtype)
        answers = []
        for geometry in (binned, tree):
            shared = geometry.shared_origin(origin)
            stats = RayStats()
            t, primitive, bary = geometry.intersect(
                RayBatch(origin[:, None], directions, 0.0, np.inf, shared), stats)
            blocked = geometry.occluded(
                RayBatch(origin[:, None], directions, 1e-4, lengths, shared), stats)
            # Rays that ignore what they hit first (as shadow segments ignore their point's
            # primitive) find what lies behind it.
            behind = geometry.intersect(
                RayBatch(origin[:, None], directions, 0.0, np.inf, shared, primitive), stats)
            unblocked = geometry.occluded(
                RayBatch(origin[:, None], directions, 1e-4, lengths, shared, primitive), stats)
            answers.append((t, primitive, bary, blocked, behind[:2], unblocked, stats.node_tests))
        (t1, p1, b1, o1, e1, u1, nodes1), (t2, p2, b2, o2, e2, u2, nodes2) = answers
        assert nodes1 == 0 and nodes2 > 0
        assert np.array_equal(p1, p2) and np.array_equal(t1, t2) and np.array_equal(o1, o2)
        assert all(np.array_equal(a, b) for a, b in zip(b1, b2))
        assert np.array_equal(e1[0], e2[0]) and np.array_equal(e1[1], e2[1])
        assert np.array_equal(u1, u2)
        assert ((e1[1] != p1) | (p1 < 0)).all() and (e1[0] > t1).any()
        seen.append(((p1[6000:] >= 1).mean(), (p1 > 900).any(), o1.mean()))
    grazing, triangles, blocked = zip(*seen)
    assert min(grazing) > 0.3 and any(triangles) and 0 < min(blocked) and max(blocked) < 1


def _mesh_spot_scene():
    rng = np.random.default_rng(4)
    count = 700
    centres = np.column_stack([rng.uniform(-3, 3, count), rng.uniform(-0.5, 1.5, count),
                               rng.uniform(-8, -2, count)])
    cloud = core.SphereSet(centres, rng.uniform(0.03, 0.12, count), rng.integers(0, 2, count),
                           MATERIALS, name="cloud")
    rings = 12
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, rings), np.linspace(0.05, np.pi - 0.05, rings))
    vertices = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1) * 0.5
    grid = np.arange(rings * rings).reshape(rings, rings)
    faces = np.concatenate([
        np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:]], -1).reshape(-1, 3),
        np.stack([grid[:-1, :-1], grid[1:, 1:], grid[:-1, 1:]], -1).reshape(-1, 3)])
    transforms = np.tile(np.eye(4), (2, 1, 1))
    transforms[:, 0, 3] = (-1.0, 1.0)
    transforms[:, 2, 3] = -4.0
    mesh = core.TriangleMesh(vertices.reshape(-1, 3), faces, None,
                             np.zeros(len(faces), int), MATERIALS, transforms, "balls")
    lights = (core.SpotLight((0.5, 3.0, 1.0), (0.0, -0.8, -0.6), power=800.0, spot_size=1.2),
              core.PointLight((-2, 4, 3), radius=0.3, name="soft"))
    return core.Scene(camera=core.ScreenCamera(96, 54), meshes=(mesh,), sphere_sets=(cloud,),
                      spheres=(core.Sphere((0, -9000, 0), 8999.0, name="floor"),),
                      lights=lights)


@pytest.mark.slow
@pytest.mark.parametrize("semantics,precision", [("default", "float32"),
                                                 ("default", "float64"),
                                                 ("article", "float64")])
def test_renders_through_bins_are_the_trees(semantics, precision):
    """A cloud of spheres, a smooth mesh, a spot light and a soft light (its samples are
    origins of their own), on two threads: the image is the tree's exactly, with fewer box
    tests (camera rays and the larger batches of shadow rays went through bins)."""
    scene = _mesh_spot_scene()
    settings = core.RenderSettings(semantics=semantics, precision=precision, threads=2,
                                   parallelism="threads", light_samples=4)
    binned = core.render(scene, settings)
    tree = core.render(scene, settings, geometry_policy=NO_BINS)
    assert np.array_equal(binned.image, tree.image)
    assert binned.stats.node_tests < 0.75 * tree.stats.node_tests
    assert binned.stats.triangle_tests > 0 and (binned.image[..., 3] == 1).mean() > 0.5


def test_bins_are_refused_where_they_do_not_pay_or_would_be_too_large():
    """A dense wall of spheres seen end on (a column of hundreds per cell): no bins, the
    tree answers.  A sparse cloud gets bins, with coarser cells where the finest would exceed
    the entry cap, and none where even the coarsest would."""
    scene = dense_wall_scene(MATERIALS[0])
    geometry = make_context(scene, core.RenderSettings(), np.float64).geometry
    assert OriginBins.build((0, 0, 3), *geometry.tree.boxes) is None
    cloud = make_context(_cloud_scene(), core.RenderSettings(), np.float64).geometry
    eye = (0.0, 0.0, 12.0)
    sparse = OriginBins.build(eye, *cloud.tree.boxes)
    assert sparse is not None and sparse.cells == bins_build.CELLS
    coarser = OriginBins.build(eye, *cloud.tree.boxes, max_entries=sparse.entries - 1)
    assert coarser.cells == bins_build.CELLS // 2 and coarser.entries < sparse.entries
    assert OriginBins.build(eye, *cloud.tree.boxes, max_entries=1000) is None


def test_a_batch_with_too_many_candidates_goes_to_the_tree():
    """The per-batch rule: rays whose cells average more than ``max_pairs_per_ray``
    candidates are answered by the tree (box tests happen), with the same hits."""
    geometry = make_context(_cloud_scene(), core.RenderSettings(), np.float64).geometry
    origin = np.array([0.0, 0.0, 12.0])
    directions = _unit(np.random.default_rng(6).normal(size=(3, 3000)))
    batch = RayBatch(origin[:, None], directions, 0.0, np.inf, geometry.shared_origin(origin))
    stats = RayStats()
    t, primitive, _ = geometry.intersect(batch, stats)
    assert stats.node_tests == 0
    geometry = make_context(_cloud_scene(), core.RenderSettings(), np.float64,
                            geometry_policy=dataclasses.replace(DEFAULT_POLICY,
                                                                max_pairs_per_ray=0.0)).geometry
    batch = RayBatch(origin[:, None], directions, 0.0, np.inf, geometry.shared_origin(origin))
    stats = RayStats()
    t2, primitive2, _ = geometry.intersect(batch, stats)
    assert stats.node_tests > 0
    assert np.array_equal(t, t2) and np.array_equal(primitive, primitive2)


def test_an_aggregate_travels_to_a_worker_with_the_bins_it_holds():
    """Pickled for a worker process, the aggregate takes the bins it holds (the frame's,
    ``Aggregate.build_frame_tables``) and leaves their lock behind: the copy answers the
    same with them, building none; a copy made before any bins builds its own."""
    import pickle

    geometry = make_context(_cloud_scene(), core.RenderSettings(), np.float64).geometry
    fresh = pickle.loads(pickle.dumps(geometry))
    origin = np.array([0.0, 0.0, 12.0])
    directions = _unit(np.random.default_rng(7).normal(size=(3, 3000)))

    def nearest(g):
        batch = RayBatch(origin[:, None], directions, 0.0, np.inf, g.shared_origin(origin))
        return g.intersect(batch, RayStats())[:2]

    t, primitive = nearest(geometry)
    assert len(geometry.bins.store.held) == 1
    copy = pickle.loads(pickle.dumps(geometry))
    assert copy.bins.store.held.keys() == geometry.bins.store.held.keys()
    assert copy.bins.store.bytes == geometry.bins.store.bytes > 0
    held = list(copy.bins.store.held.values())
    t2, primitive2 = nearest(copy)
    assert list(copy.bins.store.held.values()) == held
    assert np.array_equal(t, t2) and np.array_equal(primitive, primitive2)
    assert fresh.bins.store.held == {}
    t2, primitive2 = nearest(fresh)
    assert len(fresh.bins.store.held) == 1
    assert np.array_equal(t, t2) and np.array_equal(primitive, primitive2)
