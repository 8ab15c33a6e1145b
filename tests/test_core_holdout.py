"""Holdouts and the film's alpha in the core alone (``RenderSettings.film``, ``core.trace``);
``test_holdout_cycles`` checks the same rules against Cycles through Blender."""

from __future__ import annotations

import numpy as np
import pytest

import core

LOOK_DOWN_Y = ((1, 0, 0, 0), (0, 0, -1, -10), (0, 1, 0, 0), (0, 0, 0, 1))  # camera at -10 Y
BACKGROUND = (0.2, 0.3, 0.4)


def scene(front_material, size=24):
    """A small ball of ``front_material`` in front of a large grey one, under a light, on a
    blue-grey world; the big ball leaves the frame's corners to the world."""
    camera = core.BlenderCamera(LOOK_DOWN_Y, resolution_x=size, resolution_y=size, lens=100.0)
    grey = core.SurfaceMaterial(diffuse=(0.5, 0.5, 0.5))
    spheres = (core.Sphere((0, -2, 0), 0.5, front_material, "front"),
               core.Sphere((0, 3, 0), 1.5, grey, "back"))
    return core.Scene(camera, spheres, (core.SphereLight((0, -6, 3), power=1000.0),),
                      background=BACKGROUND, ambient=BACKGROUND)


def render(scene, **settings):
    return core.render(scene, core.RenderSettings(**settings)).image


def test_a_holdout_is_black_and_transparent_whatever_the_film():
    held = scene(core.SurfaceMaterial(diffuse=(0, 0, 0), holdout=1.0))
    coverage, opaque, transparent = (render(held, film=f)
                                     for f in ("coverage", "opaque", "transparent"))
    centre = (slice(10, 14), slice(10, 14))
    for image in (coverage, opaque, transparent):
        assert (image[centre] == 0).all()
    corner = (0, 0)
    # Where the camera sees the world: coverage and opaque show it, opaque with alpha 1.
    np.testing.assert_allclose(coverage[corner], (*BACKGROUND, 0.0))
    np.testing.assert_allclose(opaque[corner], (*BACKGROUND, 1.0))
    np.testing.assert_array_equal(transparent[corner], 0.0)
    # The big ball around the hole is untouched by the film.
    ring = (opaque[..., 3] == 1) & (coverage[..., 3] == 1)
    assert ring.sum() > 50
    np.testing.assert_array_equal(opaque[ring], transparent[ring])


def test_a_partial_holdout_scales_alpha_and_leaves_the_rest_shaded():
    shaded = render(scene(core.SurfaceMaterial(diffuse=(0.6, 0.6, 0.6))), film="opaque")
    mixed = render(scene(core.SurfaceMaterial(diffuse=(0.42, 0.42, 0.42), holdout=0.3)),
                   film="opaque")
    centre = (slice(10, 14), slice(10, 14))
    np.testing.assert_allclose(mixed[centre][..., 3], 0.7)
    np.testing.assert_allclose(mixed[centre][..., :3], 0.7 * shaded[centre][..., :3],
                               rtol=1e-6)  # float32 (precision auto)


def test_a_holdout_object_is_held_out_only_for_the_camera():
    green = core.SurfaceMaterial(diffuse=(0.1, 0.7, 0.1))
    held = render(scene(core.SurfaceMaterial(diffuse=(0.1, 0.7, 0.1), holdout_object=True)),
                  film="opaque")
    plain = render(scene(green), film="opaque")
    centre = (slice(10, 14), slice(10, 14))
    assert (held[centre] == 0).all()
    # Its shadow on the big ball stays: away from the front ball, the images agree exactly.
    around = plain[..., 3] == held[..., 3]
    assert around.sum() > 100
    np.testing.assert_array_equal(held[around], plain[around])


def test_anti_aliased_holdout_edges_have_fractional_alpha_and_stay_premultiplied():
    fixed = dict(anti_aliasing="fixed", samples=16)
    held = render(scene(core.SurfaceMaterial(diffuse=(0, 0, 0), holdout=1.0)),
                  film="transparent", **fixed)
    black = render(scene(core.SurfaceMaterial(diffuse=(0, 0, 0))), film="transparent", **fixed)
    alone = scene(core.SurfaceMaterial(diffuse=(0, 0, 0)))
    alone = core.Scene(alone.camera, alone.spheres[:1], alone.lights)
    front = render(alone, **fixed)[..., 3]     # the share of samples on the front ball
    edge = (front > 0.05) & (front < 0.95)
    assert edge.sum() >= 8
    # The held samples add no colour (the same as a black ball's) and take their share of
    # alpha away.
    np.testing.assert_array_equal(held[..., :3], black[..., :3])
    np.testing.assert_allclose(held[edge, 3], 1 - front[edge], atol=1e-6)


def test_the_article_semantics_keeps_coverage_alpha():
    article = core.article_scene(30, 20)
    coverage = render(article, semantics="article")
    assert set(np.unique(coverage[..., 3])) == {0.0, 1.0}
    np.testing.assert_array_equal(render(article, semantics="article", film="transparent"),
                                  coverage)
    assert (render(article, semantics="article", film="opaque")[..., 3] == 1).all()


@pytest.mark.parametrize("bad, field", [(dict(film="clear"), "settings.film")])
def test_bad_film_is_named(bad, field):
    with pytest.raises(core.SceneError, match=field):
        core.RenderSettings(**bad)


def test_bad_holdout_object_is_named():
    with pytest.raises(core.SceneError, match="holdout_object"):
        core.SurfaceMaterial(holdout_object="yes")
