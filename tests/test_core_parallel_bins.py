"""A sun's shadow rays through parallel bins (``core.geometry.bins.ParallelBins``): a tree of
spheres answers rays that all leave along one direction, unbounded, from the spheres binned across
that direction, with exactly the blocked rays of the tree and of every sphere tested."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

import core
from core.context import RayStats, make_context
from core.geometry import DEFAULT_POLICY
from core.geometry.bins import ParallelBins
from core.rays import RayBatch

MATERIAL = core.SurfaceMaterial(diffuse=(0.6, 0.5, 0.4))
SUN = np.array([0.3, -0.5, 0.81])
SUN /= np.linalg.norm(SUN)


def _field(count=3000, seed=0):
    """A dense slab of spheres of one size (radius 0.1-0.15) with a floor kept out of the
    tree."""
    rng = np.random.default_rng(seed)
    field = core.SphereSet(rng.uniform((-4, -4, -1), (4, 4, 1), (count, 3)),
                           rng.uniform(0.1, 0.15, count), np.zeros(count, np.int64),
                           (MATERIAL,), name="field")
    floor = core.Sphere((0, 0, -9001.2), 9000.0, MATERIAL, name="floor")
    eye = ((1, 0, 0, 0), (0, 0, -1, -12), (0, 1, 0, 0), (0, 0, 0, 1))
    return core.Scene(core.BlenderCamera(eye, resolution_x=64, resolution_y=48, lens=30.0),
                      (floor,), (core.SunLight(tuple(-SUN), strength=3.0),),
                      background=(0.05, 0.05, 0.05), sphere_sets=(field,))


def _contexts(dtype):
    """(a tree whose sun rays go through parallel bins, the same tree without them, every
    sphere tested flat)."""
    scene = _field()
    binned = make_context(scene, core.RenderSettings(), dtype)
    binned.geometry.bins.rays_per_origin = 10 ** 9
    tree = make_context(scene, core.RenderSettings(), dtype)
    tree.geometry.bins.rays_per_origin = 0
    flat = make_context(scene, core.RenderSettings(), dtype, geometry_policy=dataclasses.replace(
        DEFAULT_POLICY, tree_min_spheres=10 ** 9))
    assert binned.geometry.tree is not None and flat.geometry.tree is None
    return binned, tree, flat


def _sun_rays(ctx, rng, n):
    """Rays towards the sun from the surfaces random rays hit (offsets, exclusions and
    sources as shading makes them), those leaving a surface that faces the sun."""
    geometry = ctx.geometry
    origins = rng.uniform(-5, 5, (3, n))
    origins[2] = rng.uniform(3, 6, n)
    directions = rng.normal(size=(3, n)) * 0.4
    directions[2] -= 1.0
    directions /= np.linalg.norm(directions, axis=0)
    hits = geometry.nearest(RayBatch(origins.astype(geometry.dtype),
                                     directions.astype(geometry.dtype)), RayStats())
    lit = np.flatnonzero((hits.normals * SUN[:, None]).sum(axis=0) > 0)
    towards = np.repeat(SUN.astype(geometry.dtype)[:, None], len(lit), axis=1)
    return geometry.spawn(hits.points[:, lit], hits.normals[:, lit], hits.primitive[lit],
                          towards, hits.front[lit])


def _grazing(rays, geometry, rng, n):
    """Rays along the sun whose lines pass within a few 1e-7 of a sphere's radius from its
    centre, or through the bins' cell corners: where a listing one cell short would show."""
    spheres = geometry.spheres
    k = rng.integers(1, len(spheres), n)          # (0 is the floor)
    side = np.cross(SUN, rng.normal(size=(n, 3)))
    side /= np.linalg.norm(side, axis=1)[:, None]
    passing = spheres.radii[k] * (1 + rng.uniform(-3e-7, 3e-7, n))
    origins = spheres.centers[k] + side * passing[:, None] - SUN * rng.uniform(0.5, 3, n)[:, None]
    bins = geometry.bins.parallel_spheres(rays)[0]
    corners = rng.integers(0, bins.shape, (n, 2)) * bins.cell + np.array(bins.corner)
    depth = rng.uniform(-3, 0, n)
    on_corners = corners[:, :1] * bins.u + corners[:, 1:] * bins.v + depth[:, None] * SUN
    origins = np.concatenate([origins, on_corners]).T.astype(geometry.dtype)
    towards = np.repeat(rays.directions[:, :1], 2 * n, axis=1)
    never = np.full(2 * n, -1)
    return RayBatch(origins, towards, 0.0, np.inf, None, never, never)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sun_rays_through_parallel_bins_block_exactly_the_rays_every_sphere_does(dtype):
    binned, tree, flat = _contexts(dtype)
    rng = np.random.default_rng(4)
    rays = _sun_rays(binned, rng, 8000)
    assert len(rays) > 2000
    for segments in (rays, _grazing(rays, binned.geometry, rng, 3000)):
        bin_stats, tree_stats = RayStats(), RayStats()
        blocked = binned.geometry.occluded(segments, bin_stats)
        assert bin_stats.node_tests == 0 and bin_stats.sphere_tests > 0   # no tree walked
        assert np.array_equal(blocked, tree.geometry.occluded(segments, tree_stats))
        assert tree_stats.node_tests > 0
        assert np.array_equal(blocked, flat.geometry.occluded(segments, RayStats()))
        assert 0.1 < blocked.mean() < 0.9
    # The rays' own spheres are left out as the tree leaves them out: leaving their
    # exclusions out blocks more of them (from the surface, into their own sphere's
    # rounding), the same in all three.
    kept = RayBatch(rays.origins, rays.directions, 0.0, np.inf, None, None, rays.source)
    blocked = binned.geometry.occluded(kept, RayStats())
    assert np.array_equal(blocked, flat.geometry.occluded(kept, RayStats()))


def test_parallel_bins_list_each_sphere_in_every_cell_its_disc_meets():
    rng = np.random.default_rng(2)
    centres = rng.uniform(-3, 3, (3, 400))
    radii = rng.uniform(0.05, 0.2, 400)
    bins = ParallelBins.build(SUN, centres, radii, 1e-6)
    u = (bins.u @ centres - bins.corner[0]) / bins.cell
    v = (bins.v @ centres - bins.corner[1]) / bins.cell
    reach = (radii + 1e-6) / bins.cell
    for cell in rng.integers(0, bins.shape[0] * bins.shape[1], 300):
        i, j = divmod(int(cell), bins.shape[1])
        listed = set(bins.entries[bins.starts[cell]:bins.starts[cell + 1]].tolist())
        # The disc's bounding square meets the cell [i, i + 1) x [j, j + 1).
        meets = np.flatnonzero((u - reach < i + 1) & (u + reach >= i)
                               & (v - reach < j + 1) & (v + reach >= j))
        assert listed == set(meets.tolist())
    # A ray's candidates: its cell's spheres whose far depth reaches its origin.
    origins = rng.uniform(-3, 3, (3, 500))
    rays, entries = bins.pairs(origins)
    spheres = bins.entries[entries]
    assert np.all(SUN @ centres[:, spheres] + radii[spheres] + 1e-6 >= SUN @ origins[:, rays]
                  - 1e-6)
    # Too many entries a sphere (one sphere far larger than the rest): not built.
    radii[0] = 50.0
    assert ParallelBins.build(SUN, centres, radii, 1e-6) is None


def test_parallel_bins_serve_only_unbounded_rays_of_one_direction():
    binned, _, _ = _contexts(np.float64)
    geometry = binned.geometry
    rays = _sun_rays(binned, np.random.default_rng(5), 2000)
    assert geometry.bins.parallel_spheres(rays) is not None
    turned = rays.directions.copy()
    turned[:, 0] = turned[::-1, 0]
    bounded = np.full(len(rays), 5.0)
    for other in (RayBatch(rays.origins, turned, rays.t_min, np.inf, None, rays.exclude,
                           rays.source),
                  RayBatch(rays.origins, rays.directions, rays.t_min, bounded, None,
                           rays.exclude, rays.source)):
        assert geometry.bins.parallel_spheres(other) is None
        stats = RayStats()
        geometry.occluded(other, stats)
        assert stats.node_tests > 0
    # A frame of fewer rays than the tree has spheres builds none.
    geometry.bins.rays_per_origin = 100
    geometry.bins.store.parallel.clear()
    assert geometry.bins.parallel_spheres(rays) is None


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_render_through_parallel_bins_is_the_trees_image(monkeypatch, precision):
    """The field under a sun and a grey world (its occlusion rays go to the tree): the same
    image with the sun's rays through parallel bins (64 x 48 pixels for 3,000 spheres: the
    frame builds them, ``parallel_rays_per_primitive`` lowered) as through the tree."""
    scene = _field()
    settings = core.RenderSettings(precision=precision, threads=1, parallelism="threads")
    built = []
    build = ParallelBins.build

    def counted(*args):
        built.append(1)
        return build(*args)

    monkeypatch.setattr(ParallelBins, "build", staticmethod(counted))
    binned = core.render(scene, settings, geometry_policy=dataclasses.replace(
        DEFAULT_POLICY, parallel_rays_per_primitive=0.5)).image
    assert built
    built.clear()
    tree = core.render(scene, settings, geometry_policy=dataclasses.replace(
        DEFAULT_POLICY, parallel_rays_per_primitive=10 ** 9)).image
    assert not built
    assert np.array_equal(binned, tree)
    assert (binned[..., 3] > 0).mean() > 0.5
