"""The article preset reproduces the article's image, and the default semantics' fixes hold."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import core
from core.context import make_context
from core.png import decode_png
from core.precision import choose_precision
from core.tiles import render_tile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The image the article's own program produces (a copy of shared/reference/article_300x200.npy).
REFERENCE = os.path.join(REPO, "tests", "data", "article_300x200.npy")


@pytest.fixture(scope="module")
def reference():
    return np.load(REFERENCE)


@pytest.fixture(scope="module")
def article_render():
    return core.render(core.article_scene(), core.article_settings())


def test_article_preset_matches_reference_within_1e9(article_render, reference):
    image = article_render.image
    assert image.shape == (200, 300, 4) and image.dtype == np.float64
    assert np.abs(image[..., :3] - reference).max() <= 1e-9
    assert int((image[..., :3].max(axis=2) == 0).sum()) == 29019


def test_alpha_is_coverage_of_camera_rays(article_render, reference):
    alpha = article_render.image[..., 3]
    assert set(np.unique(alpha)) <= {0.0, 1.0}
    # Above the horizon nothing is hit: transparent and black.
    assert alpha[0].max() == 0 and reference[0].max() == 0
    assert alpha[-1].min() == 1


def _render_with_root_formula(scene, settings, root_formula):
    """The whole image as one tile, through a context built with ``root_formula``."""
    dtype = choose_precision(scene, settings.precision)
    ctx = make_context(scene, settings, dtype, root_formula=root_formula)
    assert ctx.geometry.root_formula == root_formula
    width, height = scene.camera.width, scene.camera.height
    rgba, _ = render_tile(ctx, scene.camera, (0, height, 0, width))
    return rgba


def test_stable_intersection_agrees_with_textbook_on_reference(reference):
    """The article's scene with the stable root formula instead of the article's textbook one
    (same hit rules) gives the article's image within 1e-9.  The formula is a parameter of
    the geometry; the two images must differ somewhere in their last bits, so the test
    fails if the parameter stopped reaching the root kernels."""
    scene, settings = core.article_scene(), core.article_settings()
    textbook = _render_with_root_formula(scene, settings, "textbook")
    stable = _render_with_root_formula(scene, settings, "stable")
    assert np.abs(textbook[..., :3] - reference).max() <= 1e-9
    assert np.abs(stable[..., :3] - reference).max() <= 1e-9
    assert (stable[..., :3] != textbook[..., :3]).any()
    # The article's semantics picks the textbook formula by default.
    assert make_context(scene, settings, np.float64).geometry.root_formula == "textbook"
    with pytest.raises(ValueError, match="root_formula"):
        make_context(scene, settings, np.float64, root_formula="quadratic")


@pytest.mark.slow
def test_command_writes_npy_matching_reference(tmp_path, reference):
    out = tmp_path / "article.npy"
    done = subprocess.run([sys.executable, "-m", "core", "--scene", "article", "--width", "300",
                           "--height", "200", "--output", str(out)], cwd=REPO,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    image = np.load(out)
    assert image.shape == (200, 300, 4)
    assert np.abs(image[..., :3] - reference).max() <= 1e-9


def test_command_writes_rgba_png(tmp_path, reference):
    out = tmp_path / "article.png"
    done = subprocess.run([sys.executable, "-m", "core", "--width", "300", "--height", "200",
                           "--output", str(out)], cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    pixels = decode_png(out.read_bytes())
    assert pixels.shape == (200, 300, 4)
    expected = np.round(reference * 255).astype(np.uint8)
    assert np.abs(pixels[..., :3].astype(int) - expected).max() == 0


@pytest.mark.parametrize("argument", [["--width", "0"], ["--output", "x.jpg"],
                                      ["--semantics", "bogus"]])
def test_command_rejects_bad_input_clearly(tmp_path, argument):
    args = [sys.executable, "-m", "core", "--output", str(tmp_path / "a.png")] + argument
    done = subprocess.run(args, cwd=REPO, capture_output=True, text=True)
    assert done.returncode != 0
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "a.png").exists()


# ---- the default semantics, fix by fix ---------------------------------------------------

def _render(scene, **settings):
    return core.render(scene, core.RenderSettings(**{"precision": "float64", **settings})).image


def _one_sphere_scene(camera_eye=(0, 0, 1), light=(5, 5, 5), background=(0, 0, 0), **sphere):
    material = core.Material(**sphere.pop("material", {}))
    return core.Scene(
        camera=core.ScreenCamera(width=40, height=40, eye=camera_eye),
        spheres=(core.Sphere(sphere.get("center", (0, 0, -2)), sphere.get("radius", 0.8),
                             material, "ball"),),
        lights=(core.PointLight(light),), background=background)


def test_default_keeps_ambient_in_shadow_article_drops_it():
    scene = core.article_scene(60, 40)
    article = _render(scene, semantics="article")
    default = _render(scene, semantics="default")
    hit = article[..., 3] == 1
    # Article: shadowed hits are exactly black; default: never black where a sphere was hit.
    assert (article[hit][:, :3].max(axis=1) == 0).any()
    assert (default[hit][:, :3].max(axis=1) > 0).all()


def test_default_clamps_dot_products_article_does_not():
    # Light behind the sphere: the visible side faces away from it.
    scene = _one_sphere_scene(light=(0, 0, -10), material=dict(reflection=0.0))
    article = _render(scene, semantics="article", max_depth=1)
    default = _render(scene, semantics="default", max_depth=1)
    hit = default[..., 3] == 1
    ambient = 0.1
    # Article: the ray from the shifted point runs into the sphere itself, so it is shadowed.
    assert article[hit][:, :3].max() == 0
    # Default: ambient only, never below it.
    assert np.allclose(default[hit][:, :3], ambient)


def test_default_ray_from_inside_hits_far_side_article_sees_nothing():
    scene = _one_sphere_scene(center=(0, 0, 0), radius=5.0, light=(0, 0, 0),
                              material=dict(reflection=0.0))
    article = _render(scene, semantics="article")
    default = _render(scene, semantics="default")
    assert article.max() == 0
    assert default[..., 3].min() == 1 and default[..., :3].min() > 0


def test_default_background_colour_and_its_reflection():
    scene = _one_sphere_scene(background=(0.2, 0.3, 0.4), material=dict(reflection=0.5))
    image = _render(scene, semantics="default")
    missed = image[..., 3] == 0
    assert np.allclose(image[missed][:, :3], (0.2, 0.3, 0.4))
    article = _render(scene, semantics="article")
    assert article[article[..., 3] == 0][:, :3].max() == 0


def test_default_specular_follows_the_ray_not_the_camera():
    """A ray arriving along the light's mirror direction sees the full highlight in default
    semantics; the article aims the half vector at the camera position instead."""
    from core.context import RayStats, make_context
    scene = core.Scene(camera=core.ScreenCamera(width=4, height=4, eye=(0, 0, 5)),
                       spheres=(core.Sphere((0, -100, 0), 100.0, core.Material(), "floor"),),
                       lights=(core.PointLight((3, 3, 0)),))
    # (3, 1) bundles: one point.
    point = np.array([[0.0], [0.0], [0.0]])
    normal = np.array([[0.0], [1.0], [0.0]])
    incoming = np.array([[1.0], [-1.0], [0.0]]) / np.sqrt(2)   # mirror of the way to the light
    ks_term = {}
    for semantics in ("default", "article"):
        ctx = make_context(scene, core.RenderSettings(semantics=semantics), np.float64)
        colour, _, _ = ctx.shading.shade(ctx, point, normal, incoming, np.array([0]),
                                         np.array([True]), RayStats())
        ks_term[semantics] = colour[0, 0] - 0.1 - 0.6 * np.sqrt(0.5)
    assert ks_term["default"] == pytest.approx(1.0, abs=1e-12)
    assert ks_term["article"] < 0.01


def test_render_in_float32_and_float64_returns_that_precision():
    scene = core.article_scene(30, 20)
    assert _render(scene, precision="float32").dtype == np.float32
    assert core.render(scene, core.RenderSettings(precision="float64")).image.dtype == np.float64


def test_written_files_get_the_usual_permissions(tmp_path):
    import stat
    from core.png import write_png
    out = tmp_path / "small.png"
    write_png(str(out), np.zeros((2, 3, 4)))
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask
