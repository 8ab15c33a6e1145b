"""Textured emitters against Cycles: light whose colour or strength comes from a texture,
on an emitting mesh and on Blender's lights, seen directly and through the light it casts.

Direct light only (bounces 0).  What a light sample finds on an emitter must be the
texture's value where it lands, as Cycles evaluates an emitter's shader at its light
sample's point: a floor lit by a two-coloured panel is red on one side and blue on the
other.  Tolerance: both renderers sample an area light here (Glint 256 samples, Cycles 512
at 48x36), so single pixels keep a few percent of noise; means over each half of the lit
floor are held to 4 %, well inside the 20-70 % by which a constant emission is off.
"""

from __future__ import annotations

import bpy
import numpy as np
import pytest

import cycles_support as cs
from addon_support import link
from glint.addon.compat import new_material

pytestmark = pytest.mark.cycles  # every test here renders with Cycles

MEAN_TOLERANCE = 0.04


def _floor(material, z: float = -1.0, size: float = 8.0):
    mesh = bpy.data.meshes.new("floor")
    h = size / 2
    mesh.from_pydata([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    return link(bpy.data.objects.new("floor", mesh))


def _emptied(tree):
    """``tree`` with only its output node left (a material's or a light's), which it gives."""
    for node in list(tree.nodes):
        if not node.bl_idname.startswith("ShaderNodeOutput"):
            tree.nodes.remove(node)
    return tree.nodes[0]   # (found anew: removing nodes may move the others)


def _two_colours(tree, coordinate: str, threshold: float, strength: float):
    """In ``tree``, an Emission of ``strength`` into its output's Surface, red where the
    Texture Coordinate ``coordinate``'s x is under ``threshold``, blue above (through
    Greater Than into a Mix's factor)."""
    output = _emptied(tree)
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = strength
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    right = tree.nodes.new("ShaderNodeMath")
    right.operation = 'GREATER_THAN'
    right.inputs[1].default_value = threshold
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = 'RGBA'
    mix.inputs["A"].default_value = (1.0, 0.05, 0.05, 1.0)
    mix.inputs["B"].default_value = (0.05, 0.1, 1.0, 1.0)
    tree.links.new(coordinates.outputs[coordinate], separate.inputs[0])
    tree.links.new(separate.outputs["X"], right.inputs[0])
    tree.links.new(right.outputs[0], mix.inputs["Factor"])
    tree.links.new(mix.outputs["Result"], emission.inputs["Color"])
    tree.links.new(emission.outputs[0], output.inputs["Surface"])


def _two_colour_emission(name: str, strength: float):
    """A material emitting red on the left half of a plane, blue on the right (its
    Generated x)."""
    material = new_material(name)
    _two_colours(material.node_tree, "Generated", 0.5, strength)
    return material


def _halves(glint, cycles, rows):
    """Per half (left, right) of the image rows ``rows``: Glint's and Cycles' mean RGB."""
    middle = glint.shape[1] // 2
    result = []
    for columns in (slice(0, middle), slice(middle, None)):
        result.append((glint[rows, columns, :3].reshape(-1, 3).mean(axis=0),
                       cycles[rows, columns, :3].reshape(-1, 3).mean(axis=0)))
    return result


def _assert_red_left_blue_right(glint, cycles, rows):
    """Cycles' rows ``rows`` red on the left half and blue on the right (the texture reaches
    them), and Glint's mean of each half within MEAN_TOLERANCE of Cycles'."""
    (left_glint, left_cycles), (right_glint, right_cycles) = _halves(glint, cycles, rows)
    assert left_cycles[0] > 2 * left_cycles[2] and right_cycles[2] > 2 * right_cycles[0]
    for got, want in ((left_glint, left_cycles), (right_glint, right_cycles)):
        np.testing.assert_allclose(got, want, rtol=MEAN_TOLERANCE,
                                   atol=MEAN_TOLERANCE * want.max())


def test_a_floor_lit_by_a_two_coloured_emitting_panel_matches_cycles():
    scene = cs.cycles_scene(bounces=0, samples=512)
    scene.glint.samples = 256
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    # A panel facing the camera, its lower edge just over the floor: red on the left,
    # blue on the right.
    cs.add_plane("panel", (0.0, 1.0, 0.1), 2.0, _two_colour_emission("panel", 4.0))
    glint, cycles = cs.render_both()
    # The floor just before the panel (its base is 5.7 degrees under the horizon: row 25).
    floor_rows = slice(25, 31)
    _assert_red_left_blue_right(glint, cycles, floor_rows)


def _two_colour_light(kind: str, coordinate: str, location, **settings):
    """A light of ``kind`` at ``location`` pointing down whose node tree makes it red where
    its ``coordinate``'s x is negative and blue where positive."""
    light = cs.add_light(kind, location, **settings)
    light.data.use_nodes = True
    _two_colours(light.data.node_tree, coordinate, 0.0, 1.0)
    return light


@pytest.mark.parametrize("kind, coordinate, settings", [
    ('SPOT', "Normal", dict(energy=300.0, spot_size=2.0, shadow_soft_size=0.0)),
    ('POINT', "Normal", dict(energy=300.0, shadow_soft_size=0.2)),
    ('AREA', "Object", dict(energy=150.0, size=3.0)),
])
def test_a_light_textured_by_its_node_tree_matches_cycles(kind, coordinate, settings):
    """The light's Texture Coordinate in its own space: a point or spot light's Normal is
    the direction its light leaves in, an area light's Object the point on it."""
    scene = cs.cycles_scene(bounces=0, samples=256)
    scene.glint.samples = 128
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    _two_colour_light(kind, coordinate, (0.0, 1.0, 0.5), **settings)
    glint, cycles = cs.render_both()
    _assert_red_left_blue_right(glint, cycles, slice(20, 36))


@pytest.mark.parametrize("linked", [True, False])
def test_a_light_tree_of_constants_scales_the_light_as_in_cycles(linked):
    """An Emission of constant colour x strength multiplies the light's colour; a Light
    Output that nothing reaches leaves the light dark."""
    scene = cs.cycles_scene(bounces=0, samples=64)
    scene.glint.samples = 16
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    light = cs.add_light('POINT', (0.0, 1.0, 0.5), energy=100.0, shadow_soft_size=0.0)
    light.data.use_nodes = True
    tree = light.data.node_tree
    emission = tree.nodes["Emission"]
    emission.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    emission.inputs["Strength"].default_value = 2.5
    if not linked:
        tree.links.remove(tree.nodes["Light Output"].inputs["Surface"].links[0])
    glint, cycles = cs.render_both()
    floor = cycles[20:36, :, :3].reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(glint[20:36, :, :3].reshape(-1, 3).mean(axis=0), floor,
                               rtol=MEAN_TOLERANCE, atol=1e-6)
    if linked:
        # Brighter than the light's 100 W alone would make it (the factor is read).
        assert floor[0] > 2 * floor[2] > 0


def _falloff_emission(tree, output: str, strength: float, smooth: float):
    """In ``tree``, an Emission whose Strength is Light Falloff's ``output`` into the output
    node's Surface."""
    surface = _emptied(tree).inputs["Surface"]
    emission = tree.nodes.new("ShaderNodeEmission")
    falloff = tree.nodes.new("ShaderNodeLightFalloff")
    falloff.inputs["Strength"].default_value = strength
    falloff.inputs["Smooth"].default_value = smooth
    tree.links.new(falloff.outputs[output], emission.inputs["Strength"])
    tree.links.new(emission.outputs[0], surface)


def test_light_falloff_on_an_emitter_and_a_light_matches_cycles():
    """Light Falloff reads the ray's length in the scene's units: a panel whose strength
    grows linearly with the distance it is seen from (by the camera, and from the floor it
    lights), and a point light of constant falloff with a smooth term."""
    scene = cs.cycles_scene(bounces=0, samples=256)
    scene.glint.samples = 128
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    panel = new_material("panel")
    _falloff_emission(panel.node_tree, "Linear", 1.0, 0.0)
    # (A panel 0.6 across makes the render's frame twice the scene's units: lengths must be
    # converted back.)
    cs.add_plane("panel", (-1.5, 1.0, 0.1), 0.6, panel)
    light = cs.add_light('POINT', (1.5, 1.0, 0.0), energy=1.0, shadow_soft_size=0.0)
    light.data.use_nodes = True
    _falloff_emission(light.data.node_tree, "Constant", 10.0, 1.0)
    glint, cycles = cs.render_both()
    (left_glint, left_cycles), (right_glint, right_cycles) = _halves(glint, cycles,
                                                                     slice(0, cs.HEIGHT))
    assert left_cycles.min() > 0 and right_cycles.min() > 0
    for got, want in ((left_glint, left_cycles), (right_glint, right_cycles)):
        np.testing.assert_allclose(got, want, rtol=MEAN_TOLERANCE)


def test_a_point_light_shaped_by_an_ies_profile_matches_cycles():
    """IES Texture in a light's tree with its Vector unlinked (Cycles: the direction the
    light leaves in, in the light's space): a profile uneven in horizontal angle lights the
    floor unevenly, the same way in both."""
    import bpy

    from test_shader_ies import HALF_CIRCLE, _profile_text

    scene = cs.cycles_scene(bounces=0, samples=64)
    scene.glint.samples = 16
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    light = cs.add_light('POINT', (0.0, 1.0, 0.5), rotation=(0.0, 0.0, 0.6), energy=20.0,
                         shadow_soft_size=0.0)
    light.data.use_nodes = True
    tree = light.data.node_tree
    ies = tree.nodes.new("ShaderNodeTexIES")
    ies.mode = 'INTERNAL'
    ies.ies = bpy.data.texts.new("profile.ies")
    ies.ies.from_string(_profile_text(HALF_CIRCLE))
    tree.links.new(ies.outputs["Fac"], tree.nodes["Emission"].inputs["Strength"])
    glint, cycles = cs.render_both()
    (left_glint, left_cycles), (right_glint, right_cycles) = _halves(glint, cycles,
                                                                     slice(18, cs.HEIGHT))
    # The profile reaches the floor: its two halves differ.
    assert abs(left_cycles[0] / right_cycles[0] - 1) > 0.1
    for got, want in ((left_glint, left_cycles), (right_glint, right_cycles)):
        np.testing.assert_allclose(got, want, rtol=MEAN_TOLERANCE)
