"""The IES Texture node: Cycles' parser and lookup on known values (core only), and a plane
whose Emission Strength is an IES Texture rendered by Glint and by Cycles, pixel by pixel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.shader.ies import (CANDELA_TO_WATT, MISSING_INTENSITY, IESError, ies_intensity,
                             parse_ies)

#: A type C file whose horizontal angles cover half the circle (mirrored to the other half)
#: and whose candelas differ by horizontal angle, so that a turned or mirrored lookup shows.
#: Vertical angles 0..90: the lower hemisphere; upwards is dark.
HALF_CIRCLE = """IESNA:LM-63-2002
[TEST] Glint test profile
[MANUFAC] none
TILT=NONE
1 1000 2.0 4 3 1 2 0.1 0.1 0.0
1.0 0.5 60
0 30 60 90
0 90 180
100 90 60 10
100 70 30 0
100 40 10 5
"""


def _profile_text(body: str = HALF_CIRCLE) -> str:
    return body.replace("\n", "\r\n")


# ---- core -------------------------------------------------------------------------------

def test_a_type_c_half_circle_is_mirrored_to_the_full_circle_in_watts():
    profile = parse_ies(HALF_CIRCLE)
    np.testing.assert_allclose(np.degrees(profile.h_angles), [0, 90, 180, 270, 360],
                               atol=1e-5)
    np.testing.assert_allclose(np.degrees(profile.v_angles), [0, 30, 60, 90], atol=1e-5)
    # Multiplier 2 x ballast 1 x ballast-lamp 0.5, times Cycles' candela -> watt factor.
    scale = 2.0 * 1.0 * 0.5 * CANDELA_TO_WATT
    rows = np.array([[100, 90, 60, 10], [100, 70, 30, 0], [100, 40, 10, 5]]) * scale
    np.testing.assert_allclose(profile.intensity, rows[[0, 1, 2, 1, 0]], rtol=1e-6)


def _direction(h_degrees, v_degrees):
    """The direction of Cycles' angles: v from straight down, h = atan2(x, y) + pi."""
    h, v = np.radians(h_degrees) - np.pi, np.radians(v_degrees)
    return np.array([np.sin(v) * np.sin(h), np.sin(v) * np.cos(h), -np.cos(v)])


def test_the_lookup_passes_through_the_table_at_its_angles():
    profile = parse_ies(HALF_CIRCLE)
    h, v = np.meshgrid([0.0, 90.0, 180.0, 270.0], [0.0, 30.0, 60.0])
    found = ies_intensity(profile, _direction(h.ravel(), v.ravel()).reshape(3, -1))
    rows = profile.intensity[[0, 1, 2, 3]]      # h 0, 90, 180, 270
    expected = rows[:, :3].T.ravel()
    np.testing.assert_allclose(found, expected, rtol=1e-5)


def test_between_angles_the_lookup_is_catmull_rom_along_v_then_h():
    profile = parse_ies(HALF_CIRCLE)
    table = profile.intensity.astype(np.float64)

    def cubic(a, b, c, d, x):
        # Catmull-Rom through b and c: the tangents are (c - a) / 2 and (d - b) / 2.
        return (b + 0.5 * x * (c - a) + x * x * (a - 2.5 * b + 2 * c - 0.5 * d)
                + x ** 3 * (1.5 * (b - c) + 0.5 * (d - a)))

    # h 45 (between columns 0 and 1: Cycles' float32 test does not see the table reach
    # 360 degrees, so column 0's missing predecessor repeats column 0), v 40 (between rows 1
    # and 2 of 0, 30, 60, 90).
    def column(i):
        return cubic(*table[i, 0:4], 1 / 3)

    expected = cubic(column(0), column(0), column(1), column(2), 0.5)
    found = ies_intensity(profile, _direction([45.0], [40.0]).reshape(3, 1))
    np.testing.assert_allclose(found, [expected], rtol=1e-5)
    # At the table's last vertical interval (60..90 without the pole below it) the missing
    # row after 90 repeats 90's.
    def last(i):
        return cubic(*table[i, [1, 2, 3, 3]], 0.5)
    expected = cubic(last(0), last(0), last(1), last(2), 0.5)
    found = ies_intensity(profile, _direction([45.0], [75.0]).reshape(3, 1))
    np.testing.assert_allclose(found, [expected], rtol=1e-5)
    # Between 270 and 360 the missing column after 360 repeats 270's (Cycles falls back to
    # the interval's first column there, not its second).
    expected = cubic(column(2), column(3), column(4), column(3), 0.25)
    found = ies_intensity(profile, _direction([292.5], [40.0]).reshape(3, 1))
    np.testing.assert_allclose(found, [expected], rtol=1e-5)


def test_outside_the_table_and_for_a_zero_direction_the_lookup_is_zero():
    profile = parse_ies(HALF_CIRCLE)
    directions = np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.0], [1.0, 0.1, 0.0]])
    np.testing.assert_array_equal(ies_intensity(profile, directions), [0.0, 0.0, 0.0])


def test_without_a_profile_the_lookup_is_cycles_stand_in_everywhere():
    assert ies_intensity(None, np.zeros((3, 4))).tolist() == [MISSING_INTENSITY] * 4
    assert MISSING_INTENSITY == 100.0


def test_a_quadrant_and_a_missing_360_entry_are_filled_as_cycles_does():
    quadrant = HALF_CIRCLE.replace("4 3 1 2", "4 2 1 2").replace("0 90 180\n", "0 90\n") \
        .replace("100 40 10 5\n", "")
    profile = parse_ies(quadrant)
    np.testing.assert_allclose(np.degrees(profile.h_angles), [0, 90, 180, 270, 360],
                               atol=1e-5)
    np.testing.assert_allclose(profile.intensity[[0, 2, 4]], profile.intensity[[0, 0, 0]])
    skipped = HALF_CIRCLE.replace("4 3 1 2", "4 4 1 2").replace("0 90 180\n", "0 90 180 270\n") \
        .replace("100 40 10 5\n", "100 40 10 5\n100 20 5 1\n")
    profile = parse_ies(skipped)
    np.testing.assert_allclose(np.degrees(profile.h_angles), [0, 90, 180, 270, 360],
                               atol=1e-5)
    np.testing.assert_array_equal(profile.intensity[4], profile.intensity[0])


def test_tilt_include_and_commas_are_read_as_cycles_reads_them():
    text = HALF_CIRCLE.replace("TILT=NONE\n", "TILT=INCLUDE\n1\n3\n0,45,90\n1,0.9,0.8\n")
    np.testing.assert_array_equal(parse_ies(text).intensity, parse_ies(HALF_CIRCLE).intensity)


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("IESNA\n1 2 3\n", "TILT"),
    (HALF_CIRCLE.replace("4 3 1 2", "4 3 5 2"), "photometric type 5"),
    (HALF_CIRCLE.rsplit("100 40", 1)[0], "ends before"),
])
def test_a_file_cycles_cannot_read_is_refused_in_one_line(text, words):
    with pytest.raises(IESError, match=words):
        parse_ies(text)


# ---- against Cycles -----------------------------------------------------------------------

def _ies_plane_scene(mode: str, ies_path: str | None = None, text=None):
    """A square filling the view whose Emission Strength is an IES Texture's Fac (Strength
    1.5) with its Vector unlinked (Cycles: the Incoming direction in object space).  The
    square faces the camera, but its object is turned and scaled unevenly (its mesh
    counter-transformed), so that the object-space directions the lookup reads span
    vertical angles 1..92 degrees and every horizontal angle."""
    import bpy
    from mathutils import Matrix

    import cycles_support as cs
    from glint.addon.compat import new_material

    scene = cs.cycles_scene(samples=1)
    scene.glint.samples = 1
    material = new_material("ies")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    ies = tree.nodes.new("ShaderNodeTexIES")
    ies.mode = mode
    if mode == 'EXTERNAL':
        ies.filepath = ies_path
    else:
        ies.ies = bpy.data.texts.new("profile.ies")
        ies.ies.from_string(text)
    ies.inputs["Strength"].default_value = 1.5
    emission = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(ies.outputs["Fac"], emission.inputs["Strength"])
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    scene.camera.data.lens = 15.0       # a 100 x 84 degree view
    plane = cs.add_plane("square", (0.0, 0.0, 0.0), 30.0, material)
    plane.rotation_euler = (math.radians(-50.0), math.radians(10.0), math.radians(25.0))
    plane.scale = (1.0, 1.5, 0.8)
    bpy.context.view_layer.update()
    plane.data.transform(Matrix(plane.matrix_world).inverted())
    return scene, ies


#: Per pixel, |Glint - Cycles| <= RELATIVE x Cycles + ABSOLUTE.  Cycles samples each pixel
#: within its 0.01-pixel filter, up to 0.005 pixel = 1.8e-4 rad from the centre Glint
#: looks through (2.1 degrees a pixel); the profile's intensity changes by at most 4.4 % per
#: 0.01 rad (100 to 10 cd over 30 degrees), so up to 8e-4 of a pixel's value; measured: 1.1e-3
#: at most.  ABSOLUTE (2e-4 of the brightest pixel) covers pixels where the profile falls
#: to 0 near the horizon.
RELATIVE, ABSOLUTE = 2e-3, 2e-3


@pytest.mark.cycles
def test_an_emission_strength_from_an_ies_texture_matches_cycles_pixel_by_pixel(tmp_path):
    import cycles_support as cs

    path = tmp_path / "half.ies"
    path.write_text(_profile_text(), newline="")
    _ies_plane_scene('EXTERNAL', str(path))
    glint, cycles = (image[..., 0] for image in cs.render_both())
    # The view spans the whole profile: its brightest downward cone, every horizontal
    # angle, and the dark upper side; a turned, mirrored or world-space lookup differs by
    # far more than the tolerance.
    assert cycles.max() > 10 and (cycles == 0).any() and (cycles > 0).mean() > 0.9
    np.testing.assert_array_equal(glint == 0, cycles == 0)
    np.testing.assert_array_less(np.abs(glint - cycles), RELATIVE * cycles + ABSOLUTE)


@pytest.mark.cycles
def test_an_internal_text_renders_as_the_same_file_and_a_missing_file_as_cycles(tmp_path):
    import bpy

    import cycles_support as cs
    from addon_support import depsgraph
    from glint.addon.engine.job import prepare_job

    _ies_plane_scene('INTERNAL', text=_profile_text())
    internal, cycles = (image[..., 0] for image in cs.render_both())
    np.testing.assert_array_less(np.abs(internal - cycles), RELATIVE * cycles + ABSOLUTE)

    # Cycles' lookup of a file it could not load is 100 in every direction, times Strength.
    node = bpy.data.materials["ies"].node_tree.nodes["IES Texture"]
    node.mode, node.filepath = 'EXTERNAL', str(tmp_path / "missing.ies")
    glint, cycles = (image[..., 0] for image in cs.render_both())
    np.testing.assert_allclose(cycles, 150.0)
    np.testing.assert_allclose(glint, 150.0)
    warnings = [w for w in prepare_job(depsgraph()).warnings if "IES" in w]
    assert len(warnings) == 1
    assert "'IES Texture'" in warnings[0] and "material 'ies'" in warnings[0]
    assert "missing.ies" in warnings[0] and "cannot be read" in warnings[0]
