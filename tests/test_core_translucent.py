"""The Translucent BSDF in the core alone (``SurfaceMaterial.translucency``,
``core.shading.shade_translucent``): light from behind a thin surface, none from in front,
and shadow edges seen through it found by adaptive anti-aliasing.  ``test_look_cycles``
checks the same against Cycles."""

from __future__ import annotations

import math

import numpy as np
import pytest

import core

LOOK_DOWN_Y = ((1, 0, 0, 0), (0, 0, -1, -10), (0, 1, 0, 0), (0, 0, 0, 1))  # camera at -10 Y
COLOUR = (0.8, 0.6, 0.4)


def plane(material, size=4.0):
    """A square in the plane y = 0 facing the camera (-Y), two triangles."""
    h = size / 2
    vertices = np.array([(-h, 0, -h), (h, 0, -h), (h, 0, h), (-h, 0, h)], float)
    return core.TriangleMesh(vertices, np.array([(0, 1, 2), (0, 2, 3)]), None,
                             np.zeros(2, int), (material,), name="plane")


def scene(light, spheres=(), size=32):
    camera = core.BlenderCamera(LOOK_DOWN_Y, resolution_x=size, resolution_y=size, lens=100.0)
    translucent = core.SurfaceMaterial(diffuse=(0, 0, 0), translucency=COLOUR)
    return core.Scene(camera, spheres, (light,), meshes=(plane(translucent),))


def test_light_behind_a_translucent_plane_passes_through_and_light_in_front_does_not():
    power, d = 1000.0, 3.0
    behind = core.render(scene(core.SphereLight((0, d, 0), power=power))).image
    centre = behind[15:17, 15:17, :3].mean(axis=(0, 1))
    # Cycles' units: translucency x P cos / (4 pi^2 d^2), cos ~ 1 at the centre.
    np.testing.assert_allclose(centre, np.array(COLOUR) * power / (4 * math.pi ** 2 * d ** 2),
                               rtol=2e-3)
    in_front = core.render(scene(core.SphereLight((0, -d, 0), power=power))).image
    assert in_front[..., :3].max() == 0


def test_adaptive_anti_aliasing_finds_a_shadow_edge_seen_through_a_translucent_plane():
    blocker = core.Sphere((0, 1.5, 0), 0.5, core.SurfaceMaterial(), "blocker")  # behind it
    lit = scene(core.SphereLight((0, 3.0, 0), power=1000.0), spheres=(blocker,))
    settings = dict(integrator="whitted", anti_aliasing="adaptive", samples=16)
    result = core.render(lit, core.RenderSettings(**settings))
    image = result.image[..., 0]
    # The blocker's shadow is a dark disc on the plane, its rim smoothed by supersampling.
    assert image[16, 16] == 0 and image[2, 2] > 0
    assert result.stats.supersampled_pixels >= 20
    rim = (image > 0.05 * image.max()) & (image < 0.95 * image[2:6, 2:6].min())
    assert rim.sum() >= 8
