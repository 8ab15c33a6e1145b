"""The path integrator on scenes whose answer is known in closed form (furnaces), its
determinism, its sampler and its settings' validation.  (Against Cycles:
``test_path_cycles.py``.)"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import core
from core import sampler, workers
from core.path import filter_offsets
from core.camera import BlenderCamera
from core.light_sources import AreaLight
from core.materials import SurfaceMaterial
from core.progressive import converged
from core.scene import Scene, Sphere, TriangleMesh
from core.settings import RenderSettings
from core.validation import SceneError


def _camera(position, width=32, height=24, lens=50.0) -> BlenderCamera:
    """A camera at ``position`` looking along +Y (Blender's camera rotated 90 degrees about X)."""
    matrix = np.eye(4)
    matrix[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    matrix[:3, 3] = position
    return BlenderCamera(matrix_world=tuple(map(tuple, matrix)), resolution_x=width,
                         resolution_y=height, lens=lens)


def _diffuse(albedo, emission=(0.0, 0.0, 0.0)) -> SurfaceMaterial:
    return SurfaceMaterial(diffuse=(albedo,) * 3, roughness=1.0, emission=emission)


def test_convex_diffuse_ball_in_a_uniform_world_reflects_albedo_times_the_world():
    # Every BSDF ray of a convex ball escapes: cosine sampling makes the estimate exact
    # (zero variance), so every pixel on the ball is a L.
    world = (0.7, 1.1, 1.6)
    scene = Scene(camera=_camera((0, -5, 0)), spheres=(Sphere((0, 0, 0), 1.0, _diffuse(0.4)),),
                  background=world, ambient=world)
    image = core.render(scene, RenderSettings(samples=4, threads=1)).image
    centre = image[9:15, 13:19, :3].reshape(-1, 3)
    np.testing.assert_allclose(centre, np.tile(np.multiply(0.4, world), (len(centre), 1)),
                               rtol=1e-5)


@pytest.mark.parametrize("bounces", [0, 1, 3])
def test_inside_an_emitting_diffuse_sphere_bounces_add_up_to_the_truncated_series(bounces):
    # Camera inside a closed sphere of albedo a emitting E: each bounce adds a^k E.  With
    # Cycles' counting, max bounces b still lets the last bounce's ray collect emission, so
    # the pixel is E (1 + a + ... + a^(b + 1)) = E (1 - a^(b + 2)) / (1 - a).
    a, emitted = 0.5, 1.0
    ball = Sphere((0, 0, 0), 10.0, _diffuse(a, (emitted,) * 3))
    scene = Scene(camera=_camera((0, 0, 0)), spheres=(ball,))
    settings = RenderSettings(samples=64, threads=1, max_bounces=bounces,
                              diffuse_bounces=bounces)
    mean = core.render(scene, settings).image[..., :3].mean()
    expected = emitted * (1 - a ** (bounces + 2)) / (1 - a)
    # 768 pixels x 64 samples: the mean's noise is far below 0.5 %.
    assert mean == pytest.approx(expected, rel=0.005)


@pytest.mark.slow
def test_inside_an_emitting_sphere_many_bounces_converge_to_the_geometric_sum():
    a = 0.5
    scene = Scene(camera=_camera((0, 0, 0)),
                  spheres=(Sphere((0, 0, 0), 10.0, _diffuse(a, (1.0, 1.0, 1.0))),))
    settings = RenderSettings(samples=64, threads=1, max_bounces=64, diffuse_bounces=64)
    assert core.render(scene, settings).image[..., :3].mean() == pytest.approx(
        1 / (1 - a), rel=0.01)


def _box_scene(width=24, height=18):
    """A small closed room under an area light, with a ball: light that bounces."""
    white, red = _diffuse(0.7), SurfaceMaterial(diffuse=(0.7, 0.1, 0.1), roughness=1.0)
    corners = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float) * 3
    quads = [(0, 1, 2, 3), (4, 7, 6, 5), (3, 2, 6, 7), (0, 3, 7, 4), (1, 5, 6, 2)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    materials = np.array([0, 0, 0, 0, 0, 0, 1, 1, 0, 0])
    room = TriangleMesh(corners, triangles, None, materials, (white, red), name="room")
    light = AreaLight((0, 0, 2.9), (0, 0, -1), (1, 0, 0), (0, 1, 0), size_x=1.5,
                      power=300.0)
    return Scene(camera=_camera((0, -8, 0), width, height), meshes=(room,), lights=(light,),
                 spheres=(Sphere((0.8, 0.5, -1.8), 1.2, white),))


@pytest.mark.slow
def test_the_image_is_the_same_for_any_tiles_threads_and_processes(monkeypatch):
    monkeypatch.setattr(workers, "MIN_PIXELS", 0)   # (a frame this small stays in-process)
    scene = _box_scene(40, 30)
    base = RenderSettings(samples=4, threads=1, tile_size=64, parallelism="threads")
    reference = core.render(scene, base).image
    for settings in (dataclasses.replace(base, tile_size=16),
                     dataclasses.replace(base, threads=2, tile_size=16),
                     dataclasses.replace(base, threads=2, tile_size=16,
                                         parallelism="processes")):
        result = core.render(scene, settings)
        assert result.parallelism == settings.parallelism
        np.testing.assert_array_equal(result.image, reference)


@pytest.mark.slow
def test_more_samples_bring_the_image_closer_to_a_converged_one():
    scene = _box_scene()
    reference = core.render(scene, RenderSettings(samples=1024, threads=2)).image[..., :3]
    errors = [np.sqrt(((core.render(scene, RenderSettings(samples=s, threads=2)).image[..., :3]
                        - reference) ** 2).mean()) for s in (4, 16, 64)]
    # Monte Carlo: error ~ 1 / sqrt(samples), so each 4x step about halves it.
    assert errors[1] < 0.7 * errors[0] and errors[2] < 0.7 * errors[1], errors


@pytest.mark.slow
def test_bounces_add_light_to_a_room():
    scene = _box_scene()
    direct = core.render(scene, RenderSettings(samples=64, threads=2, max_bounces=0)).image
    bounced = core.render(scene, RenderSettings(samples=64, threads=2, max_bounces=4)).image
    # The walls facing away from the light (the floor's shadowed corners, the ceiling) get
    # light only by bouncing.
    assert bounced[0:2, :, :3].mean() > 2 * direct[0:2, :, :3].mean()


@pytest.mark.slow
def test_clamping_indirect_light_darkens_only_what_bounced():
    scene = _box_scene()
    settings = RenderSettings(samples=16, threads=2, max_bounces=0, clamp_indirect=0.01)
    # With no bounce there is nothing indirect to clamp (direct light, found by light
    # samples and by the BSDF alike, is clamp_direct's).
    np.testing.assert_array_equal(
        core.render(scene, settings).image,
        core.render(scene, dataclasses.replace(settings, clamp_indirect=0.0)).image)
    bounced = dataclasses.replace(settings, max_bounces=4)
    assert (core.render(scene, bounced).image[..., :3].mean()
            < core.render(scene, dataclasses.replace(bounced, clamp_indirect=0.0))
            .image[..., :3].mean())


def test_sobol_samples_are_stratified_in_one_and_two_dimensions_per_pixel():
    seeds = sampler.pixel_seeds(np.arange(4), np.zeros(4, int))
    for seed in seeds:
        points = sampler.sample_group(np.full(16, seed), np.arange(16), 3, bits=4)
        for dimension in range(4):
            assert len(np.unique((points[dimension] * 16).astype(int))) == 16
        for first, second in ((0, 1), (2, 3)):
            cells = (points[first] * 4).astype(int) * 4 + (points[second] * 4).astype(int)
            assert len(np.unique(cells)) == 16


def test_bit_reversal_reverses_every_bit():
    values = np.random.default_rng(3).integers(0, 2 ** 32, 1000, dtype=np.uint64).astype(np.uint32)
    expected = [int(f"{int(v):032b}"[::-1], 2) for v in values]
    assert sampler.reverse_bits(values).tolist() == expected
    assert sampler.reverse_bits(np.array([[1]], np.uint32)).tolist() == [[2 ** 31]]


def test_ggx_albedo_is_bilinear_in_its_table():
    from core import bsdf
    cosines, alphas, table = bsdf._ALBEDO_COSINES, bsdf._ALBEDO_ALPHAS, bsdf._ALBEDO_TABLE
    # On the grid's nodes the table's own values; halfway, the mean of the four corners;
    # outside it, the edge's values.
    c, a = np.meshgrid(cosines, alphas)
    assert np.allclose(bsdf.directional_albedo(c.ravel(), a.ravel()), table.ravel())
    mid_c, mid_a = (cosines[3] + cosines[4]) / 2, (alphas[7] + alphas[8]) / 2
    assert bsdf.directional_albedo(np.array([mid_c]), np.array([mid_a]))[0] == pytest.approx(
        table[7:9, 3:5].mean())
    assert bsdf.directional_albedo(np.array([0.0, 2.0]), np.array([-1.0, 5.0])).tolist() == (
        pytest.approx([table[0, 0], table[-1, -1]]))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_a_rectangle_light_is_sampled_uniformly_in_its_solid_angle(dtype):
    from core.emitters import light_hit, prepare_lights, sample_light
    light, = prepare_lights([AreaLight((0.3, 0.2, 2.0), (0, 0, -1), (1, 0, 0), (0, 1, 0),
                                       size_x=1.5, size_y=0.7, shape="RECTANGLE",
                                       power=100.0)], 1.0)
    n = 100000
    rng = np.random.default_rng(1)
    points = np.tile(np.array([[0.1], [-0.4], [0.0]], dtype), n)
    drawn = sample_light(light, points, rng.random(n).astype(dtype), rng.random(n).astype(dtype))
    on_light = points + drawn.towards * drawn.distance - light.position[:, None]
    assert np.abs(on_light[2]).max() < 1e-5
    assert np.abs(on_light[0]).max() <= 0.75 + 1e-5 and np.abs(on_light[1]).max() <= 0.35 + 1e-5
    # The density is 1 / solid angle, the solid angle being the integral of cos / d^2 over
    # the rectangle (a midpoint sum here), and BSDF rays finding the light see the same.
    x, y = np.meshgrid((np.arange(300) + 0.5) / 300 - 0.5, (np.arange(140) + 0.5) / 140 - 0.5)
    offset = np.stack([0.2 + 1.5 * x.ravel(), 0.6 + 0.7 * y.ravel(), np.full(x.size, 2.0)])
    distance = np.linalg.norm(offset, axis=0)
    solid_angle = (offset[2] / distance ** 3).mean() * 1.5 * 0.7
    np.testing.assert_allclose(drawn.pdf, 1 / solid_angle, rtol=1e-4)
    found = light_hit(light, points, drawn.towards, np.full(n, np.inf, dtype))
    assert found[0].all()
    np.testing.assert_allclose(found[3], drawn.pdf, rtol=1e-4)
    # Irradiance: the estimate of the integral of L cos over the solid angle.
    irradiance = light.radiance[0] * (offset[2] ** 2 / distance ** 4).mean() * 1.5 * 0.7
    estimate = (drawn.over_pdf[0] * drawn.towards[2]).mean()
    assert estimate == pytest.approx(irradiance, rel=3e-3)
    # Behind its emitting side: nothing.
    behind = sample_light(light, np.tile(np.array([[0.0], [0.0], [3.0]], dtype), 4),
                          np.full(4, 0.5, dtype), np.full(4, 0.5, dtype))
    assert (behind.over_pdf == 0).all() and (behind.pdf == 0).all()


def test_pixels_draw_different_samples():
    points = sampler.sample_group(sampler.pixel_seeds(np.arange(1000), np.zeros(1000, int)),
                                  np.zeros(1000, int), 1, bits=4)
    # The first sample of each pixel: spread uniformly over the pixels, not one value.
    histogram = np.histogram(points[0], bins=10, range=(0, 1))[0]
    assert histogram.min() > 60 and histogram.max() < 140


def test_pixel_filter_offsets_follow_the_filter():
    u = (np.arange(10000) + 0.5) / 10000
    box = filter_offsets(u, "BOX", 1.0)
    assert box.min() >= -0.5 and box.max() <= 0.5 and abs(box.std() - 1 / math.sqrt(12)) < 0.01
    # Blackman-Harris spans twice its width, as in Cycles, and is narrow within it.
    wide = filter_offsets(u, "BLACKMAN_HARRIS", 1.5)
    assert abs(wide.mean()) < 1e-3 and 0.75 < wide.max() <= 1.5 and 0.38 < wide.std() < 0.45
    assert np.abs(filter_offsets(u, "BLACKMAN_HARRIS", 0.01)).max() <= 0.01
    # Cycles' Gaussian spans three times its width with a standard deviation of a quarter
    # of it (exp(-2 (6 x / 3 w)^2)).
    gaussian = filter_offsets(u, "GAUSSIAN", 1.5)
    assert 1.5 < gaussian.max() <= 2.25 and abs(gaussian.std() - 1.5 / 4) < 0.01


def test_adaptive_sampling_converges_where_the_halves_agree():
    total = np.array([[10.0, 10.0], [10.0, 10.0], [10.0, 10.0]])
    half = np.array([[10.0, 14.0], [10.0, 14.0], [10.0, 14.0]])
    assert converged(total, half, np.array([16.0, 16.0]), 0.01).tolist() == [True, False]


def test_noise_threshold_stops_flat_pixels_early():
    scene = Scene(camera=_camera((0, -5, 0)), spheres=(Sphere((0, 0, 0), 1.0, _diffuse(0.4)),),
                  background=(0.5, 0.5, 0.5), ambient=(0.5, 0.5, 0.5))
    adaptive = core.render(scene, RenderSettings(samples=64, threads=1, noise_threshold=0.01,
                                                 min_samples=4))
    full = core.render(scene, RenderSettings(samples=64, threads=1))
    # The noise-free ball and background stop after the minimum, where the image is the
    # same; pixels on the silhouette take more samples.
    assert adaptive.stats.camera_rays < full.stats.camera_rays / 4
    flat = np.isclose(full.image[..., 0], 0.2) | np.isclose(full.image[..., 0], 0.5)
    np.testing.assert_allclose(adaptive.image[flat], full.image[flat], atol=1e-6)
    assert adaptive.stats.camera_rays > 4 * adaptive.image.shape[0] * adaptive.image.shape[1]


@pytest.mark.parametrize("field, value", [
    ("samples", 0), ("samples", -3), ("noise_threshold", -0.1), ("clamp_indirect", math.nan),
    ("clamp_direct", math.inf), ("max_bounces", -1), ("filter_width", 0.0),
    ("filter_type", "TRIANGLE"), ("integrator", "bidirectional"), ("time_limit", -1.0),
    ("samples", 10 ** 9),
])
def test_bad_settings_give_one_line_naming_the_field(field, value):
    with pytest.raises(SceneError) as error:
        RenderSettings(**{field: value})
    message = str(error.value)
    assert f"settings.{field}" in message and "\n" not in message


def test_nested_glass_at_any_depth_keeps_the_memory_of_a_shallow_render_and_cancels():
    # A path follows one branch at glass, so its cost grows with the bounces it takes, never
    # as 2^depth, and its memory is its tile's arrays at any depth.
    import threading
    import tracemalloc

    from bench.nested_glass import nested_glass_scene, settings_at
    scene = nested_glass_scene(48, 27, layers=5)
    peaks, rays = {}, {}
    for bounces in (4, 256):
        core.render(scene, settings_at(bounces, 2))
        tracemalloc.start()
        try:
            result = core.render(scene, settings_at(bounces, 2))
            peaks[bounces] = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        rays[bounces] = result.stats.reflection_rays
    assert peaks[256] < 1.5 * peaks[4]
    assert rays[4] < rays[256] < 4 * rays[4]
    # A cancel asked during a deep render ends it within seconds (a generous bound: the
    # machine may be shared; bench.nested_glass reports the figure).
    import time
    asked_at = []
    timer = threading.Timer(0.5, lambda: asked_at.append(time.perf_counter()))
    timer.start()
    try:
        with pytest.raises(core.RenderCancelled):
            core.render(scene, settings_at(256, 4096), should_cancel=lambda: bool(asked_at))
        assert time.perf_counter() - asked_at[0] < 10.0
    finally:
        timer.cancel()
