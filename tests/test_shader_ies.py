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


#: Type B (the polar axis horizontal): Cycles transposes it and mirrors both 0..90 halves,
#: so that its table spans horizontal angles 0..180 only (dark beyond) and vertical 0..180.
#: As in any measured file, the pole (here the file's horizontal 90) has one value: near a
#: pole the horizontal angle turns fast from pixel to pixel, and a profile that differs
#: there would make the comparison one of Cycles' sampling jitter.
TYPE_B = """IESNA:LM-63-2002
TILT=NONE
1 1000 1.0 3 3 2 2 0.1 0.1 0.0
1.0 1.0 60
0 45 90
0 40 90
120 80 20
90 60 20
50 30 20
"""
#: Type A: vertical angles shift by 90 (-90..90 becomes 0..180); horizontal 0..90 is
#: mirrored to 90..270.
TYPE_A = """IESNA:LM-63-2002
TILT=NONE
1 1000 1.0 4 3 3 2 0.1 0.1 0.0
1.0 1.0 60
-90 -30 30 90
0 45 90
10 100 70 5
10 90 40 0
10 80 20 10
"""


def _profile_text(body: str = HALF_CIRCLE) -> str:
    """The file as Windows tools write it (CRLF line ends), which Cycles reads alike."""
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


@pytest.mark.parametrize("body, h_degrees, v_degrees", [
    (TYPE_B, [0, 45, 90, 135, 180], [0, 50, 90, 130, 180]),   # transposed, both mirrored
    (TYPE_A, [90, 135, 180, 225, 270], [0, 60, 120, 180]),   # v + 90, h 180 - h mirrored
], ids=["B", "A"])
def test_types_b_and_a_become_cycles_tables(body, h_degrees, v_degrees):
    profile = parse_ies(body)
    np.testing.assert_allclose(np.degrees(profile.h_angles), h_degrees, atol=1e-5)
    np.testing.assert_allclose(np.degrees(profile.v_angles), v_degrees, atol=1e-5)
    if body is TYPE_B:
        # Row h 90 is the file's vertical 0: its values at the file's horizontal 90, 40, 0,
        # 40, 90.
        np.testing.assert_allclose(profile.intensity[2] / CANDELA_TO_WATT,
                                   [50, 90, 120, 90, 50], rtol=1e-6)


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


#: Per pixel, |Glint - Cycles| <= RELATIVE x Cycles + ABSOLUTE.  At the same directions the
#: lookup equals Cycles' to 2e-5 (float32); what the renders add is where Cycles samples a
#: pixel: within its 0.01-pixel filter, up to 0.005 pixel = 1.8e-4 rad from the centre Glint
#: looks through (2.1 degrees a pixel).  That moves a value by up to 0.2 % (measured 0.16 %)
#: away from the pole, and next to it, where the horizontal angle turns 1 / sin(v) times
#: faster, by up to 0.45 % (measured on the type B file, 2 degrees from its pole).
#: ABSOLUTE (2e-4 of the brightest pixel) covers values falling to 0 at a profile's edge.
RELATIVE, ABSOLUTE = 6e-3, 2e-3


@pytest.mark.cycles
@pytest.mark.parametrize("body", [HALF_CIRCLE, TYPE_B, TYPE_A], ids=["C", "B", "A"])
def test_an_emission_strength_from_an_ies_texture_matches_cycles_pixel_by_pixel(tmp_path,
                                                                                 body):
    import cycles_support as cs

    path = tmp_path / "profile.ies"
    path.write_text(_profile_text(body), newline="")
    _ies_plane_scene('EXTERNAL', str(path))
    glint, cycles = (image[..., 0] for image in cs.render_both())
    # The view spans the whole profile: its brightest downward cone, every horizontal
    # angle, and a dark side; a turned, mirrored or world-space lookup differs by far more
    # than the tolerance.
    assert cycles.max() > 5 and (cycles == 0).any() and (cycles > 0).mean() > 0.1
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
