"""A frame's acceleration tables built once, in the rendering process, and shipped to the
worker processes with the scene (``Aggregate.build_frame_tables``): the eye's depth-ordered
bins, the occlusion trails' tables and the leaf-ordered spheres reach a worker as the
parent's arrays, and tracing every tile there builds none of them again; a frame builds only
the tables its rays use; images are the same however the tiles run."""

from __future__ import annotations

import dataclasses
import functools
import mmap

import numpy as np
import pytest

import core
from core import shared_memory, workers
from core.context import make_context
from core.progressive import ProgressiveFrame, WorkQueue
from core.geometry import DEFAULT_POLICY, bins, bvh
from core.geometry.spheres import Spheres
from core.geometry.threads import thread_pool
from core.render import _tiles
from core.tiles import render_tile
from core.shading import traces_from_points
from core.trace import traces_bounces
from test_core_workers import small_renders_in_processes  # noqa: F401 (a fixture)


def _cloud_scene(lights, count=3000, width=96, height=64, reflection=0.5):
    """A dense cloud of overlapping spheres in front of the eye (a random line through the
    tree crosses about 44 leaf boxes: depth-ordered bins, once the frame has a ray per
    sphere), reflective (``reflection``) and not."""
    rng = np.random.default_rng(7)
    centres = np.column_stack([rng.uniform(-3, 3, count), rng.uniform(-2, 2, count),
                               rng.uniform(-6, -3, count)])
    materials = (core.Material(reflection=reflection),
                 core.Material(diffuse=(0.8, 0.2, 0.1), reflection=reflection))
    cloud = core.SphereSet(centres, rng.uniform(0.2, 0.45, count),
                           rng.integers(0, 2, count), materials, name="cloud")
    return core.Scene(camera=core.ScreenCamera(width, height, eye=(0, 0, 2)),
                      sphere_sets=(cloud,), lights=lights, ambient=(0.1, 0.1, 0.1))


SUN = (core.SunLight((0.3, -1.0, -0.2), strength=3.0),)
POINT = (core.PointLight((3, 6, 4)),)


def _counting(monkeypatch):
    """Counts of every build of a frame table from now on (by table)."""
    counts = {}

    def counted(name, function):
        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            counts[name] = counts.get(name, 0) + 1
            return function(*args, **kwargs)
        return wrapper

    build = bins.OriginBins.build.__func__

    def built(cls, *args, by_depth=False, **kwargs):
        name = "depth bins" if by_depth else "bins (or refused)"
        counts[name] = counts.get(name, 0) + 1
        return build(cls, *args, by_depth=by_depth, **kwargs)

    monkeypatch.setattr(bins.OriginBins, "build", classmethod(built))
    for name in ("trail_tables", "sibling_tables", "leaf_fill", "nearest_levels"):
        table = counted(name, getattr(bvh.BVH, name).func)
        cached = functools.cached_property(table)
        cached.__set_name__(bvh.BVH, name)
        monkeypatch.setattr(bvh.BVH, name, cached)
    monkeypatch.setattr(Spheres, "by_slot", counted("leaf spheres", Spheres.by_slot))
    return counts


def _frame_on(ctx, camera, settings, shape, dtype):
    """The frame's image from ``render_tile`` on ``ctx`` alone, tile by tile in this thread:
    the Whitted integrator's tiles once each, the path integrator's in its progressive passes
    (``core.progressive``), as the render's workers run them."""
    image = np.zeros(shape, dtype)
    tiles = _tiles(camera.width, camera.height, settings.tile_size)
    if settings.integrator == "whitted":
        for tile in tiles:
            rgba, _ = render_tile(ctx, camera, tile)
            y0, y1, x0, x1 = tile
            image[y0:y1, x0:x1] = rgba
        return image
    queue = WorkQueue(ProgressiveFrame(settings, tiles, image, guides=False))
    while queue:
        job = queue.popleft()
        sums, _ = render_tile(ctx, camera, job)
        queue.frame.land(job, sums)
        queue.refill()
    return image


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["path", "whitted"])
def test_workers_get_the_frames_tables_and_build_none(small_renders_in_processes,
                                                       monkeypatch, integrator):
    """The render's shared payload, loaded as a worker loads it (``_shared_loads`` over a
    private mapping of its file), holds the eye's depth-ordered bins, the trails' tables and
    the leaf-ordered spheres as out-of-band arrays; every tile traced on it builds no table
    (the counts stay empty), and its image is the one the workers and threads made."""
    scene = _cloud_scene(SUN)
    settings = core.RenderSettings(threads=2, parallelism="processes", tile_size=32,
                                   precision="float64", integrator=integrator, samples=4)
    loaded = []
    real_payload = workers._SharedPayload

    def payload_as_a_worker_sees_it(obj):
        shared = real_payload(obj)
        mapping = mmap.mmap(shared.descriptor, shared.size, flags=mmap.MAP_PRIVATE,
                            prot=mmap.PROT_READ | mmap.PROT_WRITE)
        loaded.append((shared_memory._shared_loads(shared.payload, mapping, shared.layout),
                       shared.layout))
        return shared

    monkeypatch.setattr(workers, "_SharedPayload", payload_as_a_worker_sees_it)
    result = core.render(scene, settings)
    assert result.parallelism == "processes"
    (ctx, camera), layout = loaded[0]
    geometry, tree = ctx.geometry, ctx.geometry.tree.bvh
    eye = [b for b in geometry.bins.store.held.values() if b is not None]
    assert [b.by_depth for b in eye] == [True]
    assert {"trail_tables", "sibling_tables", "leaf_fill", "nearest_levels"} \
        <= set(vars(tree))
    assert geometry.tree.holds_leaf_spheres
    # The tables' large arrays travelled out of band, in the shared file.
    shipped = {size for _, size, _ in layout}
    assert eye[0].primitives.nbytes in shipped and tree.sibling_tables[0].nbytes in shipped
    assert geometry.tree.leaf_spheres()[0].nbytes in shipped

    counts = _counting(monkeypatch)
    image = _frame_on(ctx, camera, settings, result.image.shape, result.image.dtype)
    assert counts == {}
    assert np.array_equal(image, result.image)
    threads = core.render(scene, dataclasses.replace(settings, parallelism="threads"))
    assert np.array_equal(threads.image, result.image)
    assert result.stats.camera_rays == threads.stats.camera_rays


@pytest.mark.slow
def test_a_render_on_threads_builds_each_table_once(monkeypatch):
    """On threads too the frame's tables are built before the tiles, once each (the eye's
    id-ordered bins tried and refused first: a dense field)."""
    counts = _counting(monkeypatch)
    core.render(_cloud_scene(SUN), core.RenderSettings(threads=2, parallelism="threads",
                                                       tile_size=32))
    assert counts == {"bins (or refused)": 1, "depth bins": 1, "trail_tables": 1,
                      "sibling_tables": 1, "leaf_fill": 1, "nearest_levels": 1,
                      "leaf spheres": 1}


@pytest.mark.parametrize("case", ["point light", "few pixels", "mirrors off", "matte",
                                  "sun"])
def test_a_frame_builds_only_the_tables_its_rays_use(case):
    """No trails' tables without occlusion rays leaving hit points (a point light's segments
    leave the light), no eye bins for a frame with fewer rays than the tree's primitives, no
    leaf-ordered spheres where no ray leaves a sphere (point light, and depth 1 or no
    material that reflects)."""
    lights = SUN if case == "sun" else POINT
    pixels = (40, 30) if case == "few pixels" else (96, 64)
    settings = core.RenderSettings(max_depth=1 if case == "mirrors off" else 3)
    scene = _cloud_scene(lights, width=pixels[0], height=pixels[1],
                         reflection=0.0 if case == "matte" else 0.5)
    ctx = make_context(scene, settings, np.float64)
    geometry = ctx.geometry
    assert traces_bounces(ctx) == (case not in ("mirrors off", "matte"))
    geometry.build_frame_tables(ctx.camera_origin.position, bounces=traces_bounces(ctx),
                                trails=traces_from_points(ctx), threads=2)
    tree = vars(geometry.tree.bvh)
    assert ("trail_tables" in tree) == ("sibling_tables" in tree) == (case == "sun")
    assert bool(geometry.bins.store.held) == (case != "few pixels")
    assert geometry.tree.holds_leaf_spheres == (case not in ("mirrors off", "matte"))


def test_the_article_scene_builds_no_table():
    ctx = make_context(core.article_scene(64, 48), core.RenderSettings(semantics="article"),
                       np.float64)
    ctx.geometry.build_frame_tables(ctx.camera_origin.position, threads=2)
    assert ctx.geometry.tree is None and ctx.geometry.bins is None


@pytest.mark.parametrize("count", [3000, 20_000])
def test_depth_bins_built_on_threads_are_one_threads(count):
    """The eye's depth-ordered bins made on a pool of threads (faces and chunks of boxes a
    job, ``bins_chunk`` made small) are one thread's, array for array."""
    scene = _cloud_scene(POINT, count=count)
    geometry = make_context(scene, core.RenderSettings(), np.float64).geometry
    ids, low, high = geometry.bins.store.boxes()
    options = dict(by_depth=True, bounds=geometry.bins.store.bounding_spheres(ids),
                   rounding=2e-16,
                   policy=dataclasses.replace(DEFAULT_POLICY, bins_chunk=1000))
    made = []
    for threads in (1, 2):
        with thread_pool(threads) as pool:
            made.append(bins.OriginBins.build(np.array([0.0, 0.0, 2.0]), ids, low, high,
                                              pool=pool, **options))
    one, two = made
    assert one is not None and one.by_depth and one.entries > count
    for field in ("cells", "slots", "starts", "primitives", "near"):
        assert np.array_equal(getattr(one, field), getattr(two, field)), field


@pytest.mark.parametrize("surface, bounces", [
    (dict(roughness=0.5, specular_f0=(0.04,) * 3, specular_f90=(1.0,) * 3), False),
    (dict(roughness=0.0, specular_f0=(0.04,) * 3, specular_f90=(1.0,) * 3), True),
    (dict(roughness=0.5, transmission=(0.9,) * 3), True),
    (dict(roughness=0.5, transparency=(0.5,) * 3), True)])
def test_blenders_look_bounces_only_off_mirrors_and_through_surfaces(surface, bounces):
    """With Blender's look, rays leave hit points only where ``bsdf.scatter`` makes branches:
    a mirror lobe (roughness under ``MIRROR_ROUGHNESS``), transmission, transparency; a rough
    glossy lobe reflects the world instead, and the frame then builds no leaf-ordered
    spheres."""
    scene = _cloud_scene(SUN)
    cloud = scene.sphere_sets[0]
    material = core.SurfaceMaterial(**surface)
    scene = dataclasses.replace(scene, sphere_sets=(dataclasses.replace(
        cloud, materials=(material, material)),))
    ctx = make_context(scene, core.RenderSettings(max_depth=3), np.float64)
    assert ctx.physical is not None
    assert traces_bounces(ctx) == bounces
    ctx.geometry.build_frame_tables(ctx.camera_origin.position, bounces=traces_bounces(ctx),
                                    trails=False, threads=1)
    assert ctx.geometry.tree.holds_leaf_spheres == bounces
