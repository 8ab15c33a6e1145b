"""Depth of field: a thin lens (Cycles' model: an aperture of radius lens / (2 F-stop), rays
meeting on the focus plane), sampled with the anti-aliasing samples.  Checked against the
geometry of a thin lens: every ray of a pixel meets the pinhole ray on the focus plane, and
an edge out of focus spreads over the circle of confusion the lens equation predicts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import Material, PointLight, RenderSettings, Scene, Sphere, render
from core.camera import BlenderCamera, aperture_points, camera_rays

IDENTITY = tuple(tuple(float(r == c) for c in range(4)) for r in range(4))


def camera(**kwargs):
    # At the origin looking down -Z; lens 50 mm on a 36 mm sensor: half width 0.36 at depth 1.
    return BlenderCamera(matrix_world=IDENTITY, resolution_x=200, resolution_y=100,
                         sensor_fit='HORIZONTAL', **kwargs)


def test_a_pinhole_ignores_lens_samples():
    xs, ys = np.array([0.5, 37.2, 199.5]), np.array([0.5, 50.0, 99.5])
    lens = np.random.default_rng(1).random((2, 3))
    pinhole = camera()
    a, b = camera_rays(pinhole, xs, ys), camera_rays(pinhole, xs, ys, lens=lens)
    np.testing.assert_array_equal(a.directions, b.directions)
    assert b.shared_origin


@pytest.mark.parametrize("blades", [0, 5])
def test_every_ray_of_a_pixel_meets_the_pinhole_ray_on_the_focus_plane(blades):
    lensed = camera(aperture_radius=0.3, focus_distance=7.0, aperture_blades=blades,
                    aperture_rotation=0.4)
    count = 64
    xs, ys = np.full(count, 123.25), np.full(count, 31.5)
    lens = np.random.default_rng(2).random((2, count))
    rays = camera_rays(lensed, xs, ys, lens=lens)
    pinhole = camera_rays(camera(), xs[:1], ys[:1])
    # Where each ray reaches depth 7 (z = -7).
    t = (-7.0 - rays.origins[2]) / rays.directions[2]
    meet = rays.origins + t * rays.directions
    expected = pinhole.origins[:, 0] + (7.0 / -pinhole.directions[2, 0]) * pinhole.directions[:, 0]
    np.testing.assert_allclose(meet, np.repeat(expected[:, None], count, axis=1), atol=1e-12)
    # The origins lie on the aperture: within the radius, on the lens plane z = 0.
    assert np.all(rays.origins[2] == 0)
    assert np.hypot(rays.origins[0], rays.origins[1]).max() <= 0.3 + 1e-12


def test_orthographic_rays_of_a_pixel_meet_on_the_focus_plane_from_the_camera_plane():
    """Cycles' orthographic thin lens: a pixel's rays leave its point on the camera plane
    moved by an aperture point and meet its pinhole ray on the focus plane, so the clip
    planes stay depths along the axis."""
    lensed = camera(projection='ORTHO', ortho_scale=4.0, aperture_radius=0.3,
                    focus_distance=7.0, clip_start=0.5, clip_end=20.0)
    count = 64
    xs, ys = np.full(count, 123.25), np.full(count, 31.5)
    lens = np.random.default_rng(4).random((2, count))
    rays = camera_rays(lensed, xs, ys, lens=lens)
    pinhole = camera_rays(dataclasses.replace(lensed, aperture_radius=0.0), xs[:1], ys[:1])
    start = pinhole.origins[:, 0]
    assert np.all(rays.origins[2] == 0)
    assert np.hypot(*(rays.origins[:2] - start[:2, None])).max() <= 0.3 + 1e-12
    t = (-7.0 - rays.origins[2]) / rays.directions[2]
    meet = rays.origins + t * rays.directions
    np.testing.assert_allclose(meet, np.repeat((start + [0, 0, -7.0])[:, None], count, axis=1),
                               atol=1e-12)
    # t_min, t_max reach depths 0.5 and 20 along -Z.
    np.testing.assert_allclose(rays.t_min * -rays.directions[2], 0.5)
    np.testing.assert_allclose(rays.t_max * -rays.directions[2], 20.0)


def test_aperture_points_cover_the_disc_or_the_polygon_uniformly():
    samples = np.random.default_rng(3).random((2, 200_000))
    disc = aperture_points(camera(aperture_radius=2.0), samples)
    radius = np.hypot(*disc)
    assert radius.max() <= 2.0 + 1e-12
    # Uniform over the area: P(r < 1) = 1/4, mean at the centre.
    assert abs((radius < 1.0).mean() - 0.25) < 0.005 and np.abs(disc.mean(axis=1)).max() < 0.01
    hexagon = aperture_points(camera(aperture_radius=1.0, aperture_blades=6), samples)
    angle = np.arctan2(hexagon[1], hexagon[0])
    # Inside the hexagon whose corners lie at angles k pi / 3: distance to the nearest edge.
    sector = np.mod(angle, np.pi / 3) - np.pi / 6
    apothem = np.cos(np.pi / 6)
    assert (np.hypot(*hexagon) * np.cos(sector) <= apothem + 1e-9).all()
    assert abs((np.hypot(*hexagon) < 0.5).mean() - np.pi * 0.25 / (3 * np.sqrt(3) / 2)) < 0.01


def edge_band(alpha_row, low=0.02, high=0.98):
    """Pixels of one row's left edge of a silhouette whose coverage is strictly between."""
    left = alpha_row[: len(alpha_row) // 2]
    return int(((left > low) & (left < high)).sum())


def disc_edge_band(radius_px, low=0.02, high=0.98):
    """Width (px) over which a straight edge blurred by a uniform disc of radius_px goes from
    low to high coverage: the disc's area fraction left of x, inverted."""
    x = np.linspace(-radius_px, radius_px, 20001)
    theta = np.arccos(np.clip(-x / radius_px, -1, 1))
    covered = (theta - np.sin(theta) * np.cos(theta)) / np.pi
    return float(np.interp(high, covered, x) - np.interp(low, covered, x))


@pytest.mark.slow
def test_an_edge_out_of_focus_spreads_over_the_circle_of_confusion():
    scene = Scene(camera=camera(), spheres=(Sphere((0.0, 0.0, -10.0), 1.0, Material()),),
                  lights=(PointLight((0.0, 5.0, 0.0)),))
    settings = RenderSettings(anti_aliasing="fixed", samples=256)
    row = 50
    sharp = render(dataclasses.replace(scene, camera=camera(aperture_radius=0.2,
                                                            focus_distance=10.0)),
                   settings).image[row, :, 3]
    blurred = render(dataclasses.replace(scene, camera=camera(aperture_radius=0.2,
                                                              focus_distance=5.0)),
                     settings).image[row, :, 3]
    # In focus: the silhouette stays an anti-aliased edge, one or two partial pixels.
    assert edge_band(sharp) <= 2
    # Out of focus: rays from a disc of radius R meeting at depth f spread, at depth d, over
    # R |d - f| / f; a pixel there is d * 0.72 / 200 wide.
    coc_radius = 0.2 * abs(10.0 - 5.0) / 5.0 / (10.0 * 0.72 / 200)   # 5.6 px
    # (256 samples: coverage noise ~ 0.03 at mid-band; the silhouette's curvature over the
    # band adds under half a pixel.)
    assert abs(edge_band(blurred) - disc_edge_band(coc_radius)) <= 1.5
    assert np.isclose(blurred.sum(), sharp.sum(), rtol=0.03)   # blur moves coverage, keeps it
