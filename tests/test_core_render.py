"""Tiles, threads, anti-aliasing, ray counts (no work for what a scene lacks) and memory."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import core
from bench import baseline


def _scene(reflection=0.5, light=(5, 5, 5), count=1, **camera):
    spheres = tuple(core.Sphere((0.4 * i - 0.2 * (count - 1), 0, -2), 0.15,
                                core.Material(reflection=reflection), f"s{i}")
                    for i in range(count))
    floor = core.Sphere((0, -9000, 0), 8999.3, core.Material(reflection=reflection), "floor")
    return core.Scene(camera=core.ScreenCamera(**{"width": 64, "height": 48, **camera}),
                      spheres=spheres + (floor,), lights=(core.PointLight(light),))


def test_no_reflection_rays_when_nothing_reflects():
    stats = core.render(_scene(reflection=0.0)).stats
    assert stats.camera_rays == 64 * 48
    assert stats.reflection_rays == 0
    assert core.render(_scene(reflection=0.5)).stats.reflection_rays > 0


def test_depth_one_traces_no_reflection_rays():
    stats = core.render(_scene(), core.RenderSettings(max_depth=1)).stats
    assert stats.reflection_rays == 0


def test_no_shadow_rays_towards_a_light_behind_every_surface():
    # The light is straight behind the ball: every point the camera sees faces away from it.
    def stats(light):
        scene = core.Scene(camera=core.ScreenCamera(48, 48, eye=(0, 0, 1)),
                           spheres=(core.Sphere((0, 0, -2), 0.5, core.Material(reflection=0)),),
                           lights=(core.PointLight(light),))
        return core.render(scene).stats

    assert stats((0, 0, -10)).shadow_rays == 0
    assert stats((0, 0, 10)).shadow_rays > 0


def test_no_shadow_rays_for_a_black_light():
    scene = _scene(reflection=0.0)
    dark = core.Scene(camera=scene.camera, spheres=scene.spheres,
                      lights=(core.PointLight((5, 5, 5), diffuse=(0, 0, 0), specular=(0, 0, 0)),))
    assert core.render(dark).stats.shadow_rays == 0


def test_paths_stop_when_their_weight_cannot_show():
    # Inside a mirror ball every ray bounces until max_depth, unless its weight runs out.
    def reflection_rays(reflection):
        scene = core.Scene(camera=core.ScreenCamera(32, 32, eye=(0, 0, 0)),
                           spheres=(core.Sphere((0, 0, 0), 5.0,
                                                core.Material(reflection=reflection)),),
                           lights=(core.PointLight((1, 1, 1)),))
        return core.render(scene, core.RenderSettings(max_depth=5)).stats.reflection_rays

    pixels = 32 * 32
    assert reflection_rays(0.5) == 4 * pixels
    # Weight 1e-4 after one bounce still shows; 1e-8 after two cannot exceed the 1e-6 cutoff.
    assert reflection_rays(1e-4) == 1 * pixels


@pytest.mark.slow
def test_culling_skips_spheres_a_tile_cannot_see():
    scene = _scene(count=40, reflection=0.0, width=256, height=192)
    settings = core.RenderSettings(max_depth=1, tile_size=32)
    stats = core.render(scene, settings).stats
    brute_force = stats.camera_rays * len(scene.spheres) + stats.shadow_rays * len(scene.spheres)
    assert stats.sphere_tests < brute_force / 5
    # And culling changes nothing: one tile covering everything culls almost nothing.
    whole = core.render(scene, core.RenderSettings(max_depth=1, tile_size=256)).image
    assert np.array_equal(core.render(scene, settings).image, whole)
    # Against no culling at all (the baseline tests every ray against every sphere), which the
    # comparison above cannot show: both of its renders cull.
    article = core.render(scene, core.article_settings(max_depth=1, tile_size=32)).image
    unculled = baseline.render(scene, max_depth=1)
    assert np.abs(article - unculled).max() <= 1e-9
    assert (article[..., 3] == 1).sum() > 100


@pytest.mark.parametrize("mode", ["off", "adaptive"])
def test_result_does_not_depend_on_threads(mode):
    scene = core.article_scene(150, 100)
    images = [core.render(scene, core.RenderSettings(threads=threads, tile_size=32,
                                                     anti_aliasing=mode, samples=4)).image
              for threads in (1, 2, 3)]
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])


def test_tile_size_does_not_change_the_image():
    scene = core.article_scene(150, 100)
    a = core.render(scene, core.RenderSettings(tile_size=16)).image
    b = core.render(scene, core.RenderSettings(tile_size=200)).image
    assert np.array_equal(a, b)


def test_fixed_supersampling_gives_fractional_coverage_at_edges():
    scene = core.article_scene(60, 40)
    image = core.render(scene, core.RenderSettings(anti_aliasing="fixed", samples=16)).image
    alpha = image[..., 3]
    assert ((alpha > 0) & (alpha < 1)).any()
    assert set(np.unique(np.round(alpha * 16, 6))) <= set(float(i) for i in range(17))


def _rms(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_adaptive_supersamples_only_edges_and_approaches_fixed():
    scene = core.article_scene(120, 80)
    reference = core.render(scene, core.RenderSettings(anti_aliasing="fixed", samples=64)).image
    plain = core.render(scene).image
    adaptive = core.render(scene, core.RenderSettings(anti_aliasing="adaptive", samples=16))
    fixed = core.render(scene, core.RenderSettings(anti_aliasing="fixed", samples=16)).image
    pixels = 120 * 80
    assert 0 < adaptive.stats.supersampled_pixels < 0.35 * pixels
    assert _rms(adaptive.image, reference) < 0.5 * _rms(plain, reference)
    assert _rms(adaptive.image, reference) < 2 * _rms(fixed, reference)


def test_sample_offsets_start_at_the_centre_and_stay_in_the_pixel():
    from core.tiles import sample_offsets
    offsets = sample_offsets(256)
    assert tuple(offsets[0]) == (0.5, 0.5)
    assert offsets.min() >= 0 and offsets.max() < 1
    # Well spread: every quarter of the pixel gets about a quarter of the samples.
    quarters = np.histogram2d(offsets[:, 0], offsets[:, 1], bins=2, range=[[0, 1], [0, 1]])[0]
    assert quarters.min() >= 60


def test_progress_reports_and_cancel_stops_between_tiles():
    seen = []
    core.render(core.article_scene(64, 64), core.RenderSettings(tile_size=16, threads=2),
                progress=seen.append)
    assert len(seen) == 16 and seen[-1] == 1.0 and seen == sorted(seen)
    calls = []

    def cancel_after_three():
        calls.append(1)
        return len(calls) > 3

    with pytest.raises(core.RenderCancelled):
        core.render(core.article_scene(64, 64), core.RenderSettings(tile_size=16, threads=2),
                    should_cancel=cancel_after_three)


@pytest.mark.slow
def test_8k_render_working_memory_stays_under_300_mb():
    """7680 x 4320, depth 3: peak traced allocations beyond the output image < 300 MB (on
    threads: tracemalloc sees this process only)."""
    scene = core.article_scene(7680, 4320)
    settings = core.RenderSettings(threads=2, parallelism="threads")
    tracemalloc.start()
    try:
        result = core.render(scene, settings)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    working = peak - result.image.nbytes
    assert result.image.shape == (4320, 7680, 4)
    assert working < 300e6, f"working memory {working / 1e6:.0f} MB"


@pytest.mark.parametrize("count", [2, 4, 7])
def test_a_frames_last_tile_is_cut_so_that_the_tiles_end_even(count):
    """``_even_tail``: the last tile cut across its longer side, at multiples of BLOCK,
    into pieces that cover it exactly, so that the tiles are a multiple of count; tile
    lists already even, and tiles too small to cut, stay as they are."""
    from core.render import _even_tail, _tiles
    from core.tiles import BLOCK

    tiles = _tiles(640, 360, 128)                   # 15: the last is 128 x 104
    even = _even_tail(tiles, count)
    assert len(even) % count == 0 and even[:14] == tiles[:14]
    pieces = even[14:]
    assert len(pieces) == 1 + len(even) - len(tiles) > 1
    assert all((y0, y1) == (256, 360) for y0, y1, _, _ in pieces)      # cut across x
    assert [x0 for _, _, x0, _ in pieces] + [pieces[-1][3]] == \
        sorted({x for _, _, x0, x1 in pieces for x in (x0, x1)})       # end to end
    assert pieces[0][2] == 512 and pieces[-1][3] == 640
    assert all((x1 - x0) % BLOCK == 0 for _, _, x0, x1 in pieces)
    tall = _even_tail(_tiles(300, 100, 128), count)        # the last is 44 x 100: across y
    assert len(tall) % count == 0 and tall[-1][2:] == (256, 300) and tall[-1][1] == 100
    assert tall[2][0] == 0 and all(a[1] == b[0] for a, b in zip(tall[2:], tall[3:]))
    assert _even_tail(tiles[:12], count) == tiles[:12] or 12 % count
    assert _even_tail([(0, 1, 0, 1), (0, 1, 1, 2), (0, 1, 2, 3)], 2) == \
        [(0, 1, 0, 1), (0, 1, 1, 2), (0, 1, 2, 3)]                   # 1 x 1: no cut
    assert _even_tail(tiles, 1) == _even_tail(tiles, 3) == _even_tail(tiles, 5) == tiles
