"""Depth-ordered direction bins (``OriginBins.walk``): where id-ordered bins do not pay (a
dense field, whose cells hold columns of primitives), each cell lists its primitives by the
least distance at which a ray of the cell can meet them, and a ray walks its cell front to
back until the next entry lies beyond its nearest hit.  The answers are the tree's: every
hit lies at or beyond its entry's near, the walk finds brute force's nearest hit (ties to the
lower id) however it is cut into rounds, rays it hands to the tree get the tree's answer
afresh, and renders are identical."""

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
from test_core_bins import MATERIALS, _silhouette_directions, _unit

ROUNDS = DEFAULT_POLICY.walk_rounds
#: Depth-ordered bins of as many entries a primitive as the cells make.
UNCAPPED = dataclasses.replace(DEFAULT_POLICY, max_depth_entries_per_primitive=1000)


def _dense_spheres(rng, count, duplicates=0):
    """(centres (K, 3), radii (K,)): a slab of heavily overlapping spheres in front of the
    origin (0, 0, 0) looking down -z, spilling onto the side faces, and ``duplicates`` exact
    copies of some of them at the end (ties: the same hit at the same distance)."""
    centres = np.column_stack([rng.uniform(-3, 3, count), rng.uniform(-1, 1, count),
                               rng.uniform(-4, -1.5, count)])
    radii = rng.uniform(0.05, 0.2, count)
    copies = rng.choice(count, duplicates, replace=False)
    return np.concatenate([centres, centres[copies]]), np.concatenate([radii, radii[copies]])


def _sphere_hits(origin, directions, centres, radii):
    """(n, K) float64 entry distances (inf: a miss) of rays from origin along unit
    directions (3, n) into spheres, by brute force (the origin is outside every sphere)."""
    f = origin[None, :] - centres                                   # (K, 3)
    b = directions.T @ f.T                                          # (n, K)
    c = (f * f).sum(axis=1) - radii ** 2
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    return np.where((disc > 0) & (t > 0), t, np.inf)


def _directions(rng, origin, centres, radii, count):
    return np.concatenate([_unit(rng.normal(size=(3, count)) + np.array([[0], [0], [-2]])),
                           _silhouette_directions(rng, origin, centres[:200], radii[:200], 1)],
                          axis=1)


@pytest.mark.slow
def test_every_hit_lies_beyond_its_entrys_near_in_its_cell():
    """Rays from the origin into a dense slab: every sphere a ray enters at t is listed in
    the ray's cell with near <= t (the cone bound is a lower bound, the cone culling drops
    nothing a ray meets), and each cell's entries are nearest first."""
    rng = np.random.default_rng(11)
    centres, radii = _dense_spheres(rng, 3000)
    origin = np.zeros(3)
    grid = OriginBins.build(origin, np.arange(len(radii)), centres - radii[:, None],
                            centres + radii[:, None], cells=32, by_depth=True,
                            bounds=(centres, radii), policy=UNCAPPED)
    assert grid.by_depth and grid.cells == 32
    # Random rays, rays grazing silhouettes, and rays through the cells' corners and edges
    # (on the face looking down -z, nudged into each neighbouring cell): the cones' extremes.
    edges = np.linspace(-1, 1, 2 * grid.cells + 1)   # every cell edge and centre
    u, v = (g.ravel() for g in np.meshgrid(edges, edges))
    nudged = [np.stack([u + du, v + dv, -np.ones_like(u)])
              for du in (-1e-9, 1e-9) for dv in (-1e-9, 1e-9)]
    directions = np.concatenate([_directions(rng, origin, centres, radii, 4000),
                                 *(_unit(d) for d in nudged)], axis=1)
    t = _sphere_hits(origin, directions, centres, radii)
    assert np.isfinite(t).sum() > 20000
    for row, cell in enumerate(direction_cells(directions, grid.cells)):
        met = np.flatnonzero(np.isfinite(t[row]))
        face, rest = divmod(int(cell), grid.cells ** 2)
        listed = grid.cell_entries(cell)
        place = bins_build.stored_place(grid.slots, face, np.array([rest // grid.cells]),
                                        np.array([rest % grid.cells]),
                                        grid.cells // bins_build.BLOCK,
                                        len(grid.starts) - 2)[0]
        near = grid.near[grid.starts[place]:grid.starts[place + 1]]
        assert (np.diff(near) >= 0).all()
        where = {p: k for k, p in enumerate(listed)}
        assert all(p in where for p in met)
        assert all(near[where[p]] <= t[row, p] for p in met)
    # The cones list fewer entries than the boxes would, and nears beyond the boxes'.
    boxes = OriginBins.build(origin, np.arange(len(radii)), centres - radii[:, None],
                             centres + radii[:, None], cells=32, max_mean=np.inf,
                             max_entries=1 << 24)
    assert grid.entries < boxes.entries


@pytest.mark.slow
@pytest.mark.parametrize("rounds", [ROUNDS, (1,), (1, 2)])
def test_the_walk_finds_the_nearest_hit_ties_to_the_lower_id(rounds):
    """A walk over the slab, with duplicated spheres (exact ties), in the default rounds and
    cut short (one or two rounds: the rays still walking are handed back): every ray's
    answer is brute force's nearest hit, ties to the lower id, or it is handed back; t_max
    bounds the hits (a ray already stopped nearer by something else finds nothing)."""
    rng = np.random.default_rng(12)
    centres, radii = _dense_spheres(rng, 2000, duplicates=600)
    origin = np.zeros(3)
    ids = np.arange(len(radii))
    grid = OriginBins.build(origin, ids, centres - radii[:, None], centres + radii[:, None],
                            cells=32, by_depth=True, bounds=(centres, radii), policy=UNCAPPED)
    directions = _directions(rng, origin, centres, radii, 3000)
    # Aimed at the duplicated spheres' centres: hits that tie.
    aimed = _unit((centres[-600:] - origin).T)
    directions = np.concatenate([directions, aimed], axis=1)
    t_all = _sphere_hits(origin, directions, centres, radii)
    n = directions.shape[1]
    t_max = np.where(rng.random(n) < 0.2, rng.uniform(2, 4, n), np.inf)
    chosen = np.full(n, -1)

    def visit(r, prims, reach):
        t = t_all[r, prims]
        return np.where(t < reach, t, np.inf)

    def accept(owner, pair):
        chosen[owner] = last[0][pair]

    last = [None]

    def visiting(r, prims, reach):
        last[0] = prims
        return visit(r, prims, reach)

    reach = t_max.copy()
    found, rest = grid.walk(grid.plan(directions), reach, visiting, accept, rounds=rounds)
    masked = np.where(t_all < t_max[:, None], t_all, np.inf)
    nearest = masked.min(axis=1)
    lowest = np.where(np.isfinite(nearest),
                      np.argmax(masked == nearest[:, None], axis=1), -1)   # lowest id at min
    answered = np.ones(n, bool)
    answered[rest] = False
    assert not found[rest].any()
    assert np.array_equal(found[answered], np.isfinite(nearest[answered]))
    hit = answered & found
    assert np.array_equal(reach[hit], nearest[hit])
    assert np.array_equal(chosen[hit], lowest[hit])
    ties = (masked == nearest[:, None]).sum(axis=1) > 1
    if rounds == ROUNDS:
        assert len(rest) < 0.02 * n and (hit & ties).sum() > 100
    else:
        # (A tie takes a round more than its first hit: cut short, they are handed back.)
        assert len(rest) > 0.05 * n and hit.sum() > 0.2 * n


def _slab_scene(count=4000, triangles=80, seed=13):
    rng = np.random.default_rng(seed)
    centres, radii = _dense_spheres(rng, count, duplicates=300)
    centres += (0, 0, 2)
    cloud = core.SphereSet(centres, radii, rng.integers(0, 2, len(radii)), MATERIALS,
                           name="slab")
    corners = (rng.uniform(-2, 2, (triangles, 1, 3)) + (0, 0, -1)
               + rng.normal(scale=0.3, size=(triangles, 3, 3)))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(3 * triangles).reshape(-1, 3),
                             None, np.zeros(triangles, np.int64), MATERIALS, name="soup")
    floor = core.Sphere((0, -9000, 0), 8998.5, name="floor")
    return core.Scene(camera=core.ScreenCamera(64, 40, eye=(0, 0, 2)), spheres=(floor,),
                      sphere_sets=(cloud,), meshes=(soup,),
                      lights=(core.PointLight((3, 6, 4)),))


def _depth_or_tree(depth: bool, rounds=ROUNDS):
    """A policy of depth-ordered bins for every origin of the frame, or none.  (Id-ordered
    bins are refused, as in a field dense enough from every side: the slab is kept small.)"""
    return dataclasses.replace(DEFAULT_POLICY, max_mean_candidates=0.0,
                               depth_rays_per_primitive=0.0 if depth else np.inf,
                               depth_bins_crossings=0.0, walk_rounds=rounds)


@pytest.mark.parametrize("semantics", ["default", "article"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("rounds", [ROUNDS, (1,)])
def test_depth_bins_answer_as_the_tree_does(dtype, semantics, rounds):
    """A dense slab of spheres (with duplicates) and triangles in the tree, a floor beside
    it: rays from the eye, random and grazing the spheres' silhouettes, and rays ignoring
    what they hit first, get the tree's nearest hits (distance, primitive, barycentrics)
    through depth-ordered bins, with a fraction of its box tests; cut to one round, the
    rays handed to the tree still get the tree's answer."""
    scene = _slab_scene()
    settings = core.RenderSettings(semantics=semantics)
    answers = []
    for depth in (True, False):
        geometry = make_context(scene, settings, dtype,
                                geometry_policy=_depth_or_tree(depth, rounds)).geometry
        rng = np.random.default_rng(3)
        origin = np.array([0.0, 0.0, 2.0])
        sphere_set = scene.sphere_sets[0]
        directions = _directions(rng, origin, sphere_set.centers, sphere_set.radii,
                                 6000).astype(dtype)
        shared = geometry.shared_origin(origin)
        stats = RayStats()
        t, primitive, bary = geometry.intersect(
            RayBatch(origin[:, None], directions, 0.0, np.inf, shared), stats)
        behind = geometry.intersect(
            RayBatch(origin[:, None], directions, 0.0, np.inf, shared, primitive), stats)
        used = [b for b in geometry.bins.store.held.values() if b is not None]
        answers.append((t, primitive, bary, behind, stats.node_tests, used))
    (t1, p1, b1, e1, nodes1, used1), (t2, p2, b2, e2, nodes2, used2) = answers
    assert [b.by_depth for b in used1] == [True] and used2 == []
    assert np.array_equal(p1, p2) and np.array_equal(t1, t2)
    assert all(np.array_equal(a, b) for a, b in zip(b1, b2))
    assert np.array_equal(e1[0], e2[0]) and np.array_equal(e1[1], e2[1])
    assert (p1 >= 0).mean() > 0.5 and (p1 > 4300).any()      # spheres and triangles hit
    if rounds == ROUNDS:
        assert nodes1 < 0.2 * nodes2
    else:
        assert 0 < nodes1 < nodes2


@pytest.mark.parametrize("semantics,precision", [("default", "float32"),
                                                 ("default", "float64"),
                                                 ("article", "float64")])
def test_renders_through_depth_bins_are_the_trees(semantics, precision):
    """The slab rendered on two threads with the eye's rays through depth-ordered bins is
    the tree's image exactly, with fewer box tests; shadow segments keep to the tree."""
    scene = _slab_scene()
    settings = core.RenderSettings(semantics=semantics, precision=precision, threads=2,
                                   parallelism="threads")
    images = []
    for depth in (True, False):
        result = core.render(scene, settings, geometry_policy=_depth_or_tree(depth))
        images.append((result.image, result.stats.node_tests))
    (binned, nodes1), (tree, nodes2) = images
    assert np.array_equal(binned, tree)
    assert nodes1 < 0.8 * nodes2 and (binned[..., 3] == 1).mean() > 0.5


def test_depth_bins_only_where_a_frame_has_rays_enough():
    """make_context tells the aggregate a frame's rays per origin (its pixels); a tree with
    more primitives than that gets no depth-ordered bins, and rays then go to the tree."""
    scene = _slab_scene()
    geometry = make_context(scene, core.RenderSettings(), np.float64).geometry
    assert geometry.bins.rays_per_origin == 64 * 40 < len(geometry.bins.store.boxes()[0])
    origin = np.array([0.0, 0.0, 2.0])
    directions = _unit(np.random.default_rng(4).normal(size=(3, 3000)))
    stats = RayStats()
    geometry.intersect(RayBatch(origin[:, None], directions, 0.0, np.inf,
                                geometry.shared_origin(origin)), stats)
    assert stats.node_tests > 0
    assert not any(b is not None and b.by_depth for b in geometry.bins.store.held.values())


def test_depth_bins_only_in_dense_fields():
    """With rays enough, a tree whose random lines cross few leaf boxes (a mesh's surface:
    ``BVH.leaf_crossings`` under ``depth_bins_crossings``) gets no depth-ordered bins, and a
    dense one does."""
    policy = dataclasses.replace(DEFAULT_POLICY, max_mean_candidates=0.0,
                                 depth_rays_per_primitive=0.0)
    scene = _slab_scene()
    geometry = make_context(scene, core.RenderSettings(), np.float64,
                            geometry_policy=policy).geometry
    crossings = geometry.tree.bvh.leaf_crossings
    origin = np.array([0.0, 0.0, 2.0])
    directions = _unit(np.random.default_rng(4).normal(size=(3, 3000)))
    for floor, expected in ((crossings * 1.01, False), (crossings * 0.99, True)):
        geometry = make_context(scene, core.RenderSettings(), np.float64,
                                geometry_policy=dataclasses.replace(
                                    policy, depth_bins_crossings=floor)).geometry
        geometry.intersect(RayBatch(origin[:, None], directions, 0.0, np.inf,
                                    geometry.shared_origin(origin)), RayStats())
        held = geometry.bins.store.held.values()
        assert any(b is not None and b.by_depth for b in held) == expected
