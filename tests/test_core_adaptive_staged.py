"""Adaptive AA's staged supersampling (``core.tiles._staged_supersample``): edge pixels get
FIRST_SAMPLES samples first and more only while their estimated error is too large, so a
faint edge costs fewer samples than a contrasted one; a thin line on one surface is an edge
(``LINE_CONTRAST``); and on a dense field of small spheres the sampler reaches fixed AA's
error with fewer camera rays, the same image for any tiling or thread count."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

import core
from core.tiles import FIRST_SAMPLES, LINE_CONTRAST, SAMPLE_ERROR, _edges

tiles_module = importlib.import_module("core.tiles")


def _flat(ambient: float):
    """A material of one colour everywhere (ambient only: no light, no reflection)."""
    return core.Material(ambient=(ambient,) * 3, diffuse=(0, 0, 0), specular=(0, 0, 0),
                         reflection=0.0)


def _ball(ambient: float, backdrop: float, size: int = 48):
    """A flat-coloured ball before a flat-coloured backdrop that fills the view (alpha 1
    everywhere), at pixel size ``size``: its silhouette steps by ambient - backdrop."""
    return core.Scene(camera=core.ScreenCamera(size, size, eye=(0, 0, 1)),
                      spheres=(core.Sphere((0.05, 0.02, -2), 0.9, _flat(ambient), "ball"),
                               core.Sphere((0, 0, -60), 55, _flat(backdrop), "backdrop")),
                      lights=(core.PointLight((0, 0, 1)),))  # at the eye: no shadow in view


def _adaptive(scene, samples=16, **settings):
    settings = {"semantics": "article", "precision": "float64", **settings}
    return core.render(scene, core.RenderSettings(anti_aliasing="adaptive", samples=samples,
                                                  **settings))


def _centres(scene, semantics="article"):
    return core.render(scene, core.RenderSettings(anti_aliasing="off", semantics=semantics,
                                                  precision="float64"))


def _fixed(scene, samples):
    return core.render(scene, core.RenderSettings(anti_aliasing="fixed", samples=samples,
                                                  semantics="article", precision="float64"))


def test_a_faint_edge_costs_fewer_samples_than_a_contrasted_one():
    faint, bright = _adaptive(_ball(0.3, 0.25)), _adaptive(_ball(0.95, 0.05))
    # The same silhouette is found in both ...
    assert faint.stats.supersampled_pixels == bright.stats.supersampled_pixels > 0
    edge_pixels = faint.stats.supersampled_pixels
    extra = [r.stats.camera_rays - 48 * 48 for r in (faint, bright)]
    # ... a 13-level step over 4 samples is within SAMPLE_ERROR, so those pixels stop after
    # the first round (the centre is sample 0 in article semantics: 3 more rays a pixel) ...
    assert 0.05 / FIRST_SAMPLES <= SAMPLE_ERROR
    assert extra[0] == (FIRST_SAMPLES - 1) * edge_pixels
    # ... while a 230-level step goes on to all 16 samples in nearly every pixel.
    assert extra[1] > 0.9 * 15 * edge_pixels


def test_stopping_early_keeps_a_faint_edge_within_the_error_it_allows():
    scene = _ball(0.3, 0.25)
    reference = _fixed(scene, 64).image
    staged = _adaptive(scene).image
    # Every edge pixel stopped after the first round: fixed 4's value (the same positions,
    # the centre the first of them), everywhere else the centre's, which is exact here.
    assert np.allclose(staged, _fixed(scene, FIRST_SAMPLES).image, rtol=0, atol=1e-12)
    # Off by what 4 samples miss of a 0.05 step: within twice SAMPLE_ERROR, and about half
    # the centres' error.
    error = np.abs(staged - reference)[..., :3]
    assert 0 < error.max() <= 2 * SAMPLE_ERROR
    centres = np.abs(_fixed(scene, 1).image - reference)[..., :3]
    assert np.sqrt(np.mean(error ** 2)) < 0.6 * np.sqrt(np.mean(centres ** 2))


def test_a_thin_bright_line_on_one_surface_is_an_edge():
    display = np.full((7, 9, 4), 0.4)
    display[..., 3] = 1
    display[3, :, :3] = 0.4 + 2 * LINE_CONTRAST           # one bright row, same surface
    signature = np.zeros((7, 9), np.uint64)
    edge, step = _edges(signature, display)
    assert edge[2:5].all() and not edge[:2].any() and not edge[5:].any()
    assert np.allclose(step[3], 2 * LINE_CONTRAST)
    display[3, :, :3] = 0.4 + LINE_CONTRAST / 2           # a faint line is left to the centres
    assert not _edges(signature, display)[0].any()


def _field(size=(96, 54), count=1500, seed=7):
    """Small random spheres (2-6 pixels across) over the article's floor: nearly every pixel
    holding one is an edge, as in the bench's aa-dense field."""
    rng = np.random.default_rng(seed)
    depth = rng.uniform(3, 12, count)
    centres = np.column_stack([rng.uniform(-1, 1, count) * depth * 0.9,
                               rng.uniform(-0.3, 0.6, count) * depth * 0.5, 1 - depth])
    colours = rng.uniform(0.1, 0.9, (6, 3))
    materials = tuple(core.Material(ambient=tuple(0.1 * c), diffuse=tuple(c),
                                    specular=(1, 1, 1), shininess=100.0, reflection=0.5)
                      for c in colours)
    spheres = core.SphereSet(centres, rng.uniform(0.05, 0.15, count),
                             rng.integers(0, 6, count), materials, name="field")
    floor = core.Sphere((0, -9000, 0), 8999.3, core.Material(reflection=0.5), "floor")
    return core.Scene(camera=core.ScreenCamera(*size, eye=(0, 0.35, 1)), spheres=(floor,),
                      sphere_sets=(spheres,), lights=(core.PointLight((5, 5, 5)),))


@pytest.mark.slow
def test_on_a_dense_field_staged_samples_cost_fewer_rays_for_the_same_error(monkeypatch):
    scene = _field()
    reference = _fixed(scene, 64).image
    fixed = _fixed(scene, 16)
    staged = _adaptive(scene, samples=32)
    monkeypatch.setattr(tiles_module, "SAMPLE_ERROR", -1.0)  # every edge pixel to 32
    full = _adaptive(scene, samples=32)

    def rms(image):
        return float(np.sqrt(np.mean((image[..., :3] - reference[..., :3]) ** 2)))

    # Most pixels are edges here (spheres 1-3 pixels across), and most of those have the
    # contrast to need every sample; the rest stop early, for the same error within 5 %.
    assert staged.stats.supersampled_pixels == full.stats.supersampled_pixels > 0.5 * 96 * 54
    assert staged.stats.camera_rays < 0.95 * full.stats.camera_rays
    assert rms(staged.image) < 1.05 * rms(full.image)
    assert rms(staged.image) < rms(fixed.image)


@pytest.mark.slow
def test_staged_samples_do_not_depend_on_tiles_or_threads():
    scene = _field(size=(40, 30), count=600)
    images = [_adaptive(scene, tile_size=tile, threads=threads).image
              for tile, threads in ((128, 1), (8, 1), (16, 2), (12, 2))]
    for image in images[1:]:
        assert np.array_equal(images[0], image)
    default = [_adaptive(scene, semantics="default", tile_size=tile, threads=threads).image
               for tile, threads in ((128, 1), (8, 2))]
    assert np.array_equal(*default)


@pytest.mark.slow
def test_a_centre_is_sample_zero_where_the_light_shares_change_nothing(monkeypatch):
    # Default semantics with point lights only: a sample's share of the lights' samples
    # changes nothing, so the centres already traced are the edge pixels' sample 0 (as in
    # article semantics); a light with a radius samples by shares, so there sample 0 is
    # traced again, with its share.  Every edge pixel goes to the end here.
    monkeypatch.setattr(tiles_module, "SAMPLE_ERROR", -1.0)
    point = _field(size=(40, 30), count=600)
    soft = dataclasses.replace(point, lights=(core.PointLight((5, 5, 5), radius=0.5),))
    for scene, again in ((point, 0), (soft, 1)):
        for semantics in ("default", "article") if scene is point else ("default",):
            staged = _adaptive(scene, semantics=semantics)
            edges = staged.stats.supersampled_pixels
            assert edges > 100
            assert staged.stats.camera_rays == 40 * 30 + (15 + again) * edges
            # ... and a pixel that goes to the end has fixed AA's value either way.
            fixed = core.render(scene, core.RenderSettings(
                anti_aliasing="fixed", samples=16, semantics=semantics, precision="float64"))
            sampled = np.abs(staged.image - _centres(scene, semantics).image).max(-1) > 0
            assert sampled.sum() > 0.5 * edges
            assert np.allclose(staged.image[sampled], fixed.image[sampled], rtol=0, atol=1e-12)


def test_adaptive_with_one_sample_is_the_centres():
    scene = _field(size=(40, 30), count=600)
    for semantics in ("article", "default"):
        one = _adaptive(scene, samples=1, semantics=semantics)
        assert one.stats.camera_rays == 40 * 30
        assert np.array_equal(one.image, _centres(scene, semantics).image)
