"""The default semantics' Blender look in the core alone: units, one-sided area lights,
Fresnel, Snell's law and total internal reflection, energy conservation, scene-linear output,
and that the article semantics does not see any of it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import core
from core.bsdf import light_response, scatter, surface_arrays
from core.colour import linear_to_srgb

LOOK_DOWN_Y = ((1, 0, 0, 0), (0, 0, -1, -10), (0, 1, 0, 0), (0, 0, 0, 1))  # camera at -10 Y


def camera(size=16, lens=200.0):
    return core.BlenderCamera(LOOK_DOWN_Y, resolution_x=size, resolution_y=size, lens=lens)


def centre(scene, **settings):
    # A narrow pixel filter: every sample at the pixel's centre, so the units are exact.
    settings = {"filter_type": "BOX", "filter_width": 0.01, **settings}
    image = core.render(scene, core.RenderSettings(**settings)).image
    h, w = image.shape[:2]
    return image[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1, :3].mean(axis=(0, 1))


def grey_ball(material=None):
    return (core.Sphere((0, 0, 0), 1.0, material or core.SurfaceMaterial(diffuse=(0.5,) * 3)),)


def test_a_point_light_gives_a_p_cos_over_4_pi_squared_d_squared():
    scene = core.Scene(camera(), grey_ball(), (core.SphereLight((0, -5, 0), power=1000.0),))
    # Facing the light at d = 4; the 2 x 2 centre pixels see cos(theta) within 0.5 % of 1.
    assert centre(scene)[0] == pytest.approx(0.5 * 1000 / (4 * math.pi ** 2 * 16), rel=6e-3)


def test_a_sun_gives_a_e_cos_over_pi_and_an_area_light_p_over_pi_a():
    sun = core.Scene(camera(), grey_ball(), (core.SunLight((0, 1, 0), strength=3.0),))
    assert centre(sun)[0] == pytest.approx(0.5 * 3 / math.pi, rel=6e-3)
    small = core.AreaLight((0, -5, 0), (0, 1, 0), (1, 0, 0), (0, 0, 1), size_x=0.05,
                           power=1000.0)
    area = core.Scene(camera(), grey_ball(), (small,))
    assert centre(area)[0] == pytest.approx(0.5 * 1000 / (math.pi ** 2 * 16), rel=6e-3)


def test_area_lights_are_one_sided():
    away = core.AreaLight((0, -5, 0), (0, -1, 0), (1, 0, 0), (0, 0, 1), power=1000.0)
    scene = core.Scene(camera(), grey_ball(), (away,))
    assert core.render(scene).image[..., :3].max() == 0.0


def test_a_spot_light_is_a_point_light_inside_its_cone_and_dark_outside():
    point = core.Scene(camera(), grey_ball(), (core.SphereLight((0, -5, 0), power=1000.0),))
    inside = core.SpotLight((0, -5, 0), (0, 1, 0), power=1000.0, spot_size=1.0, spot_blend=0.0)
    outside = core.SpotLight((0, -5, 0), (0, -1, 0), power=1000.0, spot_size=1.0)
    assert centre(core.Scene(camera(), grey_ball(), (inside,)))[0] == centre(point)[0]
    assert centre(core.Scene(camera(), grey_ball(), (outside,)))[0] == 0.0


def test_default_semantics_output_is_unclipped_scene_linear_and_display_encodes_it():
    scene = core.Scene(camera(), grey_ball(), (core.SphereLight((0, -5, 0), power=20000.0),))
    result = core.render(scene)
    assert result.image[..., :3].max() > 10
    shown = result.display()
    np.testing.assert_allclose(shown[..., :3],
                               linear_to_srgb(np.clip(result.image[..., :3], 0, 1)))


def test_the_article_semantics_ignores_blenders_lights():
    spheres = grey_ball(core.Material())
    with_sun = core.Scene(camera(), spheres, (core.PointLight((0, -5, 0)),
                                              core.SunLight((0, 1, 0), strength=100.0)))
    without = core.Scene(camera(), spheres, (core.PointLight((0, -5, 0)),))
    article = core.RenderSettings(semantics="article")
    np.testing.assert_array_equal(core.render(with_sun, article).image,
                                  core.render(without, article).image)


def _hit(material, cos_in, front=True):
    surfaces = surface_arrays([material], np.float64)
    sin_in = math.sqrt(1 - cos_in ** 2)
    directions = np.array([[sin_in], [0.0], [cos_in]])  # towards -normal-ish
    normals = np.array([[0.0], [0.0], [-1.0]])          # faces the incoming ray
    cos = np.array([float(directions[:, 0] @ normals[:, 0])])
    return scatter(surfaces, normals, directions, cos, np.array([0]), np.array([front]))


def test_refraction_follows_snells_law_and_total_internal_reflection_returns_everything():
    glass = core.SurfaceMaterial(diffuse=(0, 0, 0), specular_f0=(0.04,) * 3,
                                 specular_f90=(1,) * 3, roughness=0.0,
                                 transmission=(1, 1, 1), ior=1.5)
    entering = _hit(glass, math.cos(math.radians(30)), front=True)
    mirror, refracted = entering
    sin_t = math.hypot(refracted.directions[0, 0], refracted.directions[1, 0])
    assert sin_t == pytest.approx(math.sin(math.radians(30)) / 1.5, rel=1e-12)
    # Energy: reflected + refracted = 1 for a clear dielectric (Schlick on both).
    assert mirror.weights[0, 0] + refracted.weights[0, 0] == pytest.approx(1.0, abs=1e-12)
    # Leaving the glass beyond the critical angle (41.8 deg): no refraction, all reflected.
    (inside,) = _hit(glass, math.cos(math.radians(45)), front=False)
    assert not inside.through and inside.weights[0, 0] == pytest.approx(1.0, abs=1e-12)
    # Just inside it, some light still leaves.
    assert len(_hit(glass, math.cos(math.radians(40)), front=False)) == 2


def test_the_glossy_lobe_conserves_energy_at_every_roughness():
    """The directional albedo of the GGX lobe with f0 = f90 = 1 (a white metal), seen at
    normal incidence, integrated over the hemisphere: 1 within 3 % at every roughness (the
    multiple-scattering compensation restores what single-scattering GGX loses: 31 % at
    roughness 1), never above."""
    theta = (np.arange(400) + 0.5) / 400 * (math.pi / 2)
    phi = (np.arange(64) + 0.5) / 64 * 2 * math.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    towards = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]).reshape(3, -1)
    d_omega = (np.sin(t) * (math.pi / 2 / 400) * (2 * math.pi / 64)).ravel()
    m = towards.shape[1]
    for roughness in (0.2, 0.5, 0.8, 1.0):
        surfaces = surface_arrays([core.SurfaceMaterial(
            diffuse=(0, 0, 0), specular_f0=(1,) * 3, specular_f90=(1,) * 3,
            roughness=roughness)], np.float64)
        normals = np.tile([[0.0], [0.0], [1.0]], (1, m))
        radiance = light_response(surfaces, np.zeros(m, int), normals, normals, towards,
                                  towards[2])
        albedo = float((radiance[0] * d_omega).sum())
        assert albedo <= 1.0 + 2e-3, (roughness, albedo)
        assert albedo > 0.97, (roughness, albedo)


def test_surface_material_errors_name_the_field():
    with pytest.raises(core.SceneError, match="roughness"):
        core.SurfaceMaterial(roughness=1.5)
    with pytest.raises(core.SceneError, match="spot_size"):
        core.SpotLight((0, 0, 0), (0, 0, -1), spot_size=4.0)
    with pytest.raises(core.SceneError, match="shape"):
        core.AreaLight((0, 0, 0), (0, 0, -1), (1, 0, 0), (0, 1, 0), shape="TRIANGLE")
    with pytest.raises(core.SceneError, match="direction"):
        core.SunLight((0, "down", 0))


def test_the_articles_material_under_blenders_lights_reads_its_intensities_as_e_over_pi():
    """Default semantics, an article Material (kd) lit by a SphereLight: kd E cos / pi, i.e.
    the article's kd Id cos with Id = E / pi, and no highlight where N.H is small."""
    material = core.Material(ambient=(0, 0, 0), diffuse=(0.5, 0.25, 0.1), specular=(0, 0, 0),
                             reflection=0.0)
    scene = core.Scene(camera(), grey_ball(material), (core.SphereLight((0, -5, 0), power=1000),))
    expected = np.array([0.5, 0.25, 0.1]) * 1000 / (4 * math.pi ** 2 * 16)
    np.testing.assert_allclose(centre(scene), expected, rtol=6e-3)


def test_world_light_is_occluded_by_other_spheres_unless_world_samples_is_0():
    spheres = (core.Sphere((0, 0, 0), 1.0, core.SurfaceMaterial(diffuse=(0.5,) * 3)),
               core.Sphere((0, -2.2, 0), 1.0, core.SurfaceMaterial(diffuse=(0.5,) * 3)))
    side = core.BlenderCamera(((0, 0, 1, 10), (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 0, 1)),
                              resolution_x=32, resolution_y=32, lens=60)   # from +X
    scene = core.Scene(side, spheres, background=(1, 1, 1), ambient=(1, 1, 1))
    # (World Samples are the Whitted integrator's.)
    occluded = core.render(scene, core.RenderSettings(integrator="whitted")).image
    open_sky = core.render(scene, core.RenderSettings(integrator="whitted",
                                                      world_samples=0)).image
    covered = open_sky[..., 3] == 1
    np.testing.assert_allclose(open_sky[covered, :3], 0.5)   # albedo x world, unoccluded
    assert (occluded[covered, :3] <= 0.5 + 1e-12).all()
    assert occluded[covered, 0].min() < 0.4                   # where the balls face each other


def test_the_tabulated_ggx_albedo_is_its_quadrature():
    from core.bsdf import (_ALBEDO_COSINES, _ALBEDO_TABLE, _SCHLICK_TABLE, _schlick_rise,
                           dielectric_rise, dielectric_table, directional_albedo_quadrature)

    np.testing.assert_allclose(_ALBEDO_TABLE, directional_albedo_quadrature(), atol=6e-6)
    # alpha = 1 at normal incidence: 1 - ln 2, the closed form of the single-scattering lobe.
    assert _ALBEDO_TABLE[-1, -1] == pytest.approx(1 - math.log(2), abs=2e-3)
    np.testing.assert_allclose(_SCHLICK_TABLE, directional_albedo_quadrature(_schlick_rise),
                               atol=6e-6)
    np.testing.assert_allclose(dielectric_table(1.5), directional_albedo_quadrature(
        lambda c: dielectric_rise(c, 1.5)), atol=6e-6)
    # Another index is integrated on first use; water's curve rises less than glass's.
    assert (dielectric_table(1.33) < dielectric_table(1.5))[:, :-1].all()
    # A near-mirror (alpha 1e-3) reflects V about N itself: (1 - N.V)^5 of E.
    np.testing.assert_allclose(_SCHLICK_TABLE[0], (1 - _ALBEDO_COSINES) ** 5 * _ALBEDO_TABLE[0],
                               atol=1e-3)


def test_a_white_principled_ball_under_a_white_world_reflects_it_unchanged_to_its_rim():
    """White furnace: what the specular layer reflects (its directional albedo A(N.V)) the
    diffuse under it loses (Cycles' layering: base x (1 - A)), so a white Principled ball in
    a world of radiance 1 is 1 from its centre to its grazing rim, through the ambient,
    glossy-world and layering terms together.  (With the glossy lobe reflecting Schlick's
    F(N.V) over an unlayered diffuse, its rim pixels were 1.5 and more.)  A white Diffuse
    BSDF ball is 1 too, its diffuse not layered."""
    principled = core.SurfaceMaterial.principled(base_color=(1.0, 1.0, 1.0), roughness=0.5)
    for material in (principled, core.SurfaceMaterial(diffuse=(1.0, 1.0, 1.0))):
        scene = core.Scene(camera(size=48, lens=120.0), grey_ball(material),
                           background=(1, 1, 1), ambient=(1, 1, 1))
        # Whitted integrates the world in closed form: exactly 1.
        image = core.render(scene, core.RenderSettings(integrator="whitted")).image
        covered = image[..., 3] == 1
        assert covered.sum() > 300
        np.testing.assert_allclose(image[covered, :3], 1.0, atol=2e-3)
        # Paths sample it: 1 within their noise, over the ball and over its rim.
        image = core.render(scene, core.RenderSettings(samples=64, noise_threshold=0)).image
        covered = image[..., 3] == 1
        rim = covered & ~np.pad(covered[1:-1, 1:-1] & covered[2:, 1:-1] & covered[:-2, 1:-1]
                                & covered[1:-1, 2:] & covered[1:-1, :-2], 1)
        assert rim.sum() > 30
        assert image[covered, :3].mean() == pytest.approx(1.0, abs=0.01)
        assert image[rim, :3].mean() == pytest.approx(1.0, abs=0.03)
