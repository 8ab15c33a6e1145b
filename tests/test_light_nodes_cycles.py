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


def _two_colour_emission(name: str, strength: float):
    """An Emission shader red on the left half of a plane, blue on the right (Generated x
    through Greater Than into a Mix's factor)."""
    material = new_material(name)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = strength
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    right = tree.nodes.new("ShaderNodeMath")
    right.operation = 'GREATER_THAN'
    right.inputs[1].default_value = 0.5
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = 'RGBA'
    mix.inputs["A"].default_value = (1.0, 0.05, 0.05, 1.0)
    mix.inputs["B"].default_value = (0.05, 0.1, 1.0, 1.0)
    tree.links.new(coordinates.outputs["Generated"], separate.inputs[0])
    tree.links.new(separate.outputs["X"], right.inputs[0])
    tree.links.new(right.outputs[0], mix.inputs["Factor"])
    tree.links.new(mix.outputs["Result"], emission.inputs["Color"])
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def _halves(glint, cycles, rows):
    """Per half (left, right) of the image rows ``rows``: Glint's and Cycles' mean RGB."""
    middle = glint.shape[1] // 2
    result = []
    for columns in (slice(0, middle), slice(middle, None)):
        result.append((glint[rows, columns, :3].reshape(-1, 3).mean(axis=0),
                       cycles[rows, columns, :3].reshape(-1, 3).mean(axis=0)))
    return result


def test_a_floor_lit_by_a_checker_textured_emitting_panel_matches_cycles():
    scene = cs.cycles_scene(bounces=0, samples=512)
    scene.glint.samples = 256
    _floor(cs.diffuse("floor", (0.8, 0.8, 0.8)))
    # A panel facing the camera, its lower edge just over the floor: red on the left,
    # blue on the right.
    cs.add_plane("panel", (0.0, 1.0, 0.1), 2.0, _two_colour_emission("panel", 4.0))
    glint, cycles = cs.render_both()
    # The floor just before the panel (its base is 5.7 degrees under the horizon: row 25).
    floor_rows = slice(25, 31)
    (left_glint, left_cycles), (right_glint, right_cycles) = _halves(glint, cycles, floor_rows)
    # The texture reaches the floor: red light on the left, blue on the right.
    assert left_cycles[0] > 2 * left_cycles[2] and right_cycles[2] > 2 * right_cycles[0]
    for got, want in ((left_glint, left_cycles), (right_glint, right_cycles)):
        np.testing.assert_allclose(got, want, rtol=MEAN_TOLERANCE,
                                   atol=MEAN_TOLERANCE * want.max())
