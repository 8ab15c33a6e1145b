"""The shader node registry against Blender itself: every registered node names sockets that
exist on Blender's node of that type with the same types, and options it has (or its reader
gives), so the registry cannot drift from Blender; and every node function follows the
registry's calling convention for constant and per-point inputs."""

from __future__ import annotations

import inspect

import bpy
import numpy as np
import pytest

from node_support import by_identifier, evaluate

from glint.addon.export.context import ExportContext  # noqa: E402
from glint.addon.compat import (NEWER_NODES, NEWER_SOCKETS, absent_input_value,  # noqa: E402
                                new_material)
from glint.addon.export.node_options import OPTION_READERS  # noqa: E402
from glint.addon.export.shader import node_options  # noqa: E402
from glint.core.shader.points import ShadingPoints  # noqa: E402
from glint.core.shader.registry import CLOSURE, COLOR, FLOAT, NODES, VECTOR  # noqa: E402

BLENDER_TYPES = {FLOAT: "VALUE", VECTOR: "VECTOR", COLOR: "RGBA", CLOSURE: "SHADER"}


@pytest.fixture(scope="module")
def tree():
    material = new_material("registry check")
    yield material.node_tree
    bpy.data.materials.remove(material)


@pytest.mark.parametrize("bl_idname", sorted(name for name in NODES
                                       if not name.startswith("Glint")))
def test_registered_sockets_and_options_exist_on_blenders_node(tree, bl_idname):
    # (Glint's own nodes, the compiler's conversions, are not Blender's.)  A node or socket
    # newer than this Blender (compat.NEWER_NODES, NEWER_SOCKETS) must be missing from it,
    # and an input missing has a value the exporter stands in for it.
    spec = NODES[bl_idname]
    if bpy.app.version < NEWER_NODES.get(bl_idname, (0, 0, 0)):
        assert not hasattr(bpy.types, bl_idname), f"{bl_idname} is older than compat says"
        return
    blender_node = tree.nodes.new(bl_idname)
    for label, declared, sockets in (("input", spec.inputs, blender_node.inputs),
                                     ("output", spec.outputs, blender_node.outputs)):
        actual = {identifier: socket.type for identifier, socket in by_identifier(sockets).items()}
        for identifier, kind in declared:
            if bpy.app.version < NEWER_SOCKETS.get((bl_idname, identifier), (0, 0, 0)):
                assert identifier not in actual, f"{bl_idname}: {identifier!r} is older"
                if label == "input":
                    assert absent_input_value(bl_idname, identifier) is not None
                continue
            assert identifier in actual, f"{bl_idname}: no {label} socket {identifier!r}"
            assert actual[identifier] == BLENDER_TYPES[kind], (
                f"{bl_idname}: {label} {identifier!r} is {actual[identifier]} in Blender, "
                f"{kind} in the registry")
    for identifier in spec.implicit:
        assert identifier in dict(spec.inputs), f"{bl_idname}: implicit {identifier!r}"
    # Every option is the node's property or its reader's, and nothing else is read.
    if bl_idname not in OPTION_READERS:
        for name in spec.options:
            assert hasattr(blender_node, name), f"{bl_idname}: no property {name!r}"
    read = node_options(blender_node, spec, ExportContext.for_camera(None, None))
    assert set(read) == set(spec.options), bl_idname
    parameters = inspect.signature(spec.function).parameters
    keywords = {name for name, p in parameters.items() if p.kind is p.KEYWORD_ONLY}
    assert set(spec.options) <= keywords, f"{bl_idname}: options the function does not take"
    positional = [p for p in parameters.values() if p.kind is p.POSITIONAL_OR_KEYWORD]
    assert len(positional) == 1 + len(spec.inputs), f"{bl_idname}: inputs and arguments differ"


def every_node_of_these_modules():
    return sorted(name for name, spec in NODES.items()
                  if spec.function.__module__.split(".")[-1] in ("colour_nodes",
                                                                  "converter_nodes",
                                                                  "input_nodes"))


@pytest.mark.parametrize("bl_idname", every_node_of_these_modules())
@pytest.mark.parametrize("linked, dtype", [(False, np.float64), (True, np.float64),
                                           (True, np.float32)],
                         ids=["constants", "per point", "per point float32"])
def test_node_functions_return_one_broadcastable_array_per_output(tree, bl_idname, linked,
                                                                  dtype):
    """Constant inputs (0-d floats, (3, 1) vectors) and per-point ones ((n,), (3, n)) both
    give outputs that broadcast to (n,) for floats and (3, n) for vectors and colours, in
    the render precision of the points and inputs (float32 stays float32)."""
    n = 7
    rng = np.random.default_rng(1)
    position = rng.normal(size=(3, n)).astype(dtype)
    normal = position / np.linalg.norm(position, axis=0)
    points = ShadingPoints(position, normal, normal.copy(), normal.copy(),
                           backfacing=rng.random(n) < 0.5)
    spec = NODES[bl_idname]
    blender_node = tree.nodes.new(bl_idname)
    given = {}
    if linked:
        for identifier, kind in spec.inputs:
            given[identifier] = (rng.uniform(0.1, 1, n) if kind == FLOAT
                                 else rng.uniform(0.1, 1, (3, n))).astype(dtype)
    outputs = evaluate(blender_node, points, **given)
    for identifier, kind in spec.outputs:
        shape = (n,) if kind == FLOAT else (3, n)
        value = np.broadcast_to(outputs[identifier], shape)
        assert np.isfinite(value).all(), (bl_idname, identifier)
        if linked:
            assert value.dtype == dtype, (bl_idname, identifier, value.dtype)


@pytest.mark.parametrize("bl_idname, options, words", [
    ("ShaderNodeMath", dict(operation="CUBE"), ["Math", "operation", "'CUBE'"]),
    ("ShaderNodeVectorMath", dict(operation="CURL"), ["Vector Math", "'CURL'"]),
    ("ShaderNodeMapRange", dict(interpolation_type="CUBIC"), ["Map Range", "'CUBIC'"]),
    ("ShaderNodeMapRange", dict(data_type="COLOR"), ["Map Range", "data_type"]),
    ("ShaderNodeClamp", dict(clamp_type="SOFT"), ["Clamp", "clamp_type"]),
    ("ShaderNodeSeparateColor", dict(mode="CMYK"), ["Separate Color", "'CMYK'"]),
    ("ShaderNodeVectorRotate", dict(rotation_type="QUATERNION"), ["Vector Rotate"]),
    ("ShaderNodeMapping", dict(vector_type="UV"), ["Mapping", "vector_type"]),
    ("ShaderNodeVectorTransform", dict(convert_to="SCREEN"), ["Vector Transform", "convert_to"]),
    ("ShaderNodeMix", dict(data_type="RGBA", blend_type="GLOW"), ["Mix", "blend_type"]),
    ("ShaderNodeMix", dict(data_type="ROTATION"), ["Mix", "'ROTATION'"]),
    ("ShaderNodeValToRGB", dict(interpolation="CUBIC"), ["Color Ramp", "interpolation"]),
    ("ShaderNodeValToRGB", dict(elements=()), ["Color Ramp", "elements"]),
    ("ShaderNodeAttribute", dict(attribute_type="SCENE"), ["Attribute", "attribute_type"]),
])
def test_bad_options_give_one_line_naming_the_node_and_option(tree, bl_idname, options, words):
    spec = NODES[bl_idname]
    blender_node = tree.nodes.new(bl_idname)
    points = ShadingPoints(np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)),
                           np.zeros((3, 2)))
    arguments = [np.zeros(()) if kind == FLOAT else np.zeros((3, 1)) for _, kind in spec.inputs]
    with pytest.raises(ValueError) as raised:
        spec.function(points, *arguments, **options)
    message = str(raised.value)
    assert "\n" not in message and all(word in message for word in words), message
