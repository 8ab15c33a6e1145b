"""The core under docs/invalid-data.md's policy: what Blender can hold and Cycles renders, the
core renders as Cycles does, saying so in one warning line naming the part and the field
(``warnings``, collected by ``Scene.warnings``); it refuses only what rendering would lose."""

from __future__ import annotations

import math

import numpy as np
import pytest

import core

NAN, INF = float("nan"), float("inf")
FLOAT32_PI = float(np.float32(math.pi))      # Blender's 180 degrees
DOWN = (0.0, 0.0, -1.0)
X, Y = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)


@pytest.mark.parametrize("make, power", [
    (lambda p: core.SphereLight((0, 0, 3), power=p), "power"),
    (lambda p: core.SpotLight((0, 0, 3), DOWN, power=p), "power"),
    (lambda p: core.SunLight(DOWN, strength=p), "strength"),
    (lambda p: core.AreaLight((0, 0, 3), DOWN, X, Y, power=p), "power"),
])
def test_every_blender_light_takes_a_negative_power_without_a_warning(make, power):
    light = make(-250.0)
    assert getattr(light, power) == -250.0 and light.emits and not light.warnings


@pytest.mark.parametrize("make, words", [
    (lambda: core.SpotLight((0, 0, 3), (0, 0, 0), name="Spot"),
     "light 'Spot': direction is (0, 0, 0) (the light is scaled to 0): it emits nothing"),
    (lambda: core.SunLight((-0.0, 0.0, 0.0), name="Sun"),
     "light 'Sun': direction is (-0.0, 0.0, 0.0) (the light is scaled to 0): it emits nothing"),
    (lambda: core.AreaLight((0, 0, 3), DOWN, (0, 0, 0), Y, name="Area"),
     "light 'Area': axis_x is (0, 0, 0) (the light is scaled to 0): it emits nothing"),
    (lambda: core.AreaLight((0, 0, 3), DOWN, X, Y, size_x=0.0, name="Area"),
     "light 'Area': size_x is 0: it emits nothing"),
    (lambda: core.AreaLight((0, 0, 3), DOWN, X, Y, shape="RECTANGLE", size_y=0.0, name="Area"),
     "light 'Area': size_y is 0: it emits nothing"),
    (lambda: core.SphereLight((0, 0, 3), power=NAN, name="Lamp"),
     "light 'Lamp': power is nan: it emits nothing"),
    (lambda: core.SunLight(DOWN, strength=-INF, name="Sun"),
     "light 'Sun': strength is -inf: it emits nothing"),
    (lambda: core.SpotLight((NAN, 0, 3), DOWN, name="Spot"),
     "light 'Spot': position is (nan, 0, 3): it emits nothing"),
])
def test_a_light_cycles_cannot_use_emits_nothing_with_one_warning(make, words):
    """Measured in Cycles: a spot, sun or area light scaled to 0 (on all axes or on Z), an
    area light of size 0, a light at a NaN place emit nothing; a NaN power too (without the
    light tree; with it every light goes dark)."""
    light = make()
    assert light.warnings == (words,)
    assert not light.emits
    assert (light.strength if isinstance(light, core.SunLight) else light.power) == 0.0


def test_a_light_colours_channels_that_are_not_finite_emit_nothing_and_huge_ones_are_clamped():
    light = core.SphereLight((0, 0, 3), colour=(NAN, 1e13, 0.5), name="Lamp")
    assert light.colour == (0.0, 1e12, 0.5) and light.emits
    (warning,) = light.warnings
    assert warning == ("light 'Lamp': colour is (nan, 10000000000000.0, 0.5): channels that "
                       "are not finite emit nothing; colour (nan, 10000000000000.0, 0.5) is "
                       "clamped to 1e+12")


def test_a_light_that_emits_nothing_adds_nothing_and_is_not_sampled():
    camera = core.BlenderCamera(((1, 0, 0, 0), (0, 0, -1, -6), (0, 1, 0, 0), (0, 0, 0, 1)),
                                32, 24)
    ball = (core.Sphere((0, 0, 0), 1.0, core.SurfaceMaterial()),)
    lit = core.SphereLight((3, -3, 3), power=500.0)
    dark = core.SpotLight((-3, -3, 3), (0, 0, 0), power=5000.0)
    with_dark = core.render(core.Scene(camera, ball, (lit, dark)))
    without = core.render(core.Scene(camera, ball, (lit,)))
    np.testing.assert_array_equal(with_dark.image, without.image)
    assert with_dark.stats.shadow_rays == without.stats.shadow_rays


def test_angles_are_compared_with_pi_in_float32():
    """Blender's 180 degrees, float32 pi, is above Python's pi: accepted, stored as pi;
    a value past float32 pi is refused."""
    spot = core.SpotLight((0, 0, 3), DOWN, spot_size=FLOAT32_PI)
    sun = core.SunLight(DOWN, angle=FLOAT32_PI)
    assert FLOAT32_PI > math.pi and spot.spot_size == math.pi and sun.angle == math.pi
    for make in (lambda a: core.SpotLight((0, 0, 3), DOWN, spot_size=a),
                 lambda a: core.SunLight(DOWN, angle=a)):
        with pytest.raises(core.SceneError, match="must be at most pi, got 3.1416"):
            make(3.1416)


BLIND = [
    (dict(matrix_world=((0, 0, 0, 0), (0, 0, 0, -6), (0, 0, 0, 0), (0, 0, 0, 1))),
     "matrix_world is scaled to 0"),
    (dict(clip_start=10.0, clip_end=1.0), "clip_end 1.0 is not past clip_start 10.0"),
    (dict(projection="ORTHO", ortho_scale=0.0), "ortho_scale is 0"),
    (dict(aperture_radius=0.1, focus_distance=0.0), "focus_distance is 0 with depth of field"),
]


@pytest.mark.parametrize("changes, words", BLIND, ids=[w for _, w in BLIND])
def test_a_camera_cycles_sees_nothing_through_renders_a_black_frame(changes, words):
    """Measured in Cycles: each of these renders RGB 0 everywhere, alpha 1 (0 with Film >
    Transparent)."""
    fields = dict(matrix_world=((1, 0, 0, 0), (0, 0, -1, -6), (0, 1, 0, 0), (0, 0, 0, 1)),
                  resolution_x=32, resolution_y=24, name="Cam")
    fields.update(changes)
    camera = core.BlenderCamera(**fields)
    assert camera.sees_nothing
    assert camera.warnings == (f"camera 'Cam': {words}: the frame renders black, as in "
                               f"Cycles",)
    scene = core.Scene(camera, (core.Sphere((0, 0, 0), 1.0),), (core.SphereLight((3, -3, 3)),),
                       background=(0.5, 0.5, 0.5))
    assert scene.warnings == camera.warnings
    for film, alpha in (("opaque", 1.0), ("transparent", 0.0)):
        image = core.render(scene, core.RenderSettings(film=film)).image
        assert image.shape == (24, 32, 4)
        assert (image[..., :3] == 0).all() and (image[..., 3] == alpha).all()


def test_a_perspective_camera_ignores_its_ortho_scale_and_a_pinhole_its_focus():
    camera = core.BlenderCamera(((1, 0, 0, 0), (0, 0, -1, -6), (0, 1, 0, 0), (0, 0, 0, 1)),
                                32, 24, ortho_scale=0.0, focus_distance=0.0)
    assert not camera.sees_nothing and not camera.warnings


def test_scene_warnings_gather_every_parts_in_order():
    mesh = core.TriangleMesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [NAN, 0, 0]]),
                             np.array([[0, 1, 2], [1, 2, 3]]), None, np.zeros(2, np.int64),
                             (core.Material(),), name="M")
    points = core.SphereSet(np.zeros((2, 3)), np.array([1.0, 0.0]), np.zeros(2, np.int64),
                            (core.Material(),), name="P")
    scene = core.Scene(core.ScreenCamera(8, 6), lights=(core.SunLight((0, 0, 0), name="S"),),
                       sphere_sets=(points,), meshes=(mesh,))
    assert [line.split(":")[0] for line in scene.warnings] == ["light 'S'", "sphere set 'P'",
                                                               "mesh 'M'"]


def test_a_mesh_float64_cannot_resolve_is_refused_naming_what_reaches_far():
    """Rendering would lose the small sphere (MAX_SCALE_RATIO): the refusal names both the
    smallest object and the mesh whose vertex reaches 1e15 (it named only the sphere)."""
    camera = core.BlenderCamera(((1, 0, 0, 0), (0, 0, -1, -6), (0, 1, 0, 0), (0, 0, 0, 1)),
                                32, 24)
    spike = core.TriangleMesh(np.array([[0, 2, 0], [1, 2, 0], [0, 2, 1e15]]),
                              np.array([[0, 1, 2]]), None, np.zeros(1, np.int64),
                              (core.Material(),), name="spike")
    scene = core.Scene(camera, (core.Sphere((0, 0, 0), 0.5, name="ball"),), meshes=(spike,))
    with pytest.raises(core.SceneError) as raised:
        core.render(scene)
    message = str(raised.value)
    assert message.startswith("sphere 'ball' (size 0.5) is 2.0e+15 times smaller")
    assert "mesh 'spike' instance 0 reaches 1.0e+15 from the camera" in message
