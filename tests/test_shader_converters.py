"""Math, Vector Math, Map Range, Clamp, Separate/Combine XYZ and Color, Vector Rotate,
Mapping and Vector Transform against Cycles, per pixel (``node_support``: each render feeds
every operation of a node inputs from the plane's Object coordinates and reads them back
from AOVs; tolerances there: float32 arithmetic plus the inputs' own error)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from node_support import NodeScene, by_identifier, check_outputs, evaluate

from glint.core.shader import converter_nodes  # noqa: E402

MATH_OPERATIONS = [item.identifier for item in
                   bpy.types.ShaderNodeMath.bl_rna.properties["operation"].enum_items]
VECTOR_OPERATIONS = [item.identifier for item in
                     bpy.types.ShaderNodeVectorMath.bl_rna.properties["operation"].enum_items]
#: Math's third input where an operation reads it (Multiply Add, Compare's epsilon, Smooth
#: Min/Max's distance, Wrap's minimum).
THIRD = 0.35


#: Operations a later Blender added, which an older one does not offer (Vector Math's Power
#: and Sign: 4.5 has them, 4.2 does not; Round: Blender 5.3).
LATER_VECTOR_OPERATIONS = {"POWER", "SIGN", "ROUND"}


def test_every_math_and_vector_math_operation_of_blender_is_implemented():
    assert set(MATH_OPERATIONS) == set(converter_nodes.MATH_OPERATIONS)
    implemented = (set(converter_nodes.VECTOR_OPERATIONS)
                   | set(converter_nodes.VECTOR_VALUE_OPERATIONS))
    assert set(VECTOR_OPERATIONS) <= implemented
    assert implemented - set(VECTOR_OPERATIONS) <= LATER_VECTOR_OPERATIONS


@pytest.mark.cycles
@pytest.mark.parametrize("x_range, y_range, use_clamp", [
    ((-2.0, 2.0), (-1.5, 1.5), False),
    ((-7.0, 7.0), (-4.0, 6.0), False),
    ((-2.0, 2.0), (-1.5, 1.5), True),
])
def test_math_matches_cycles(x_range, y_range, use_clamp):
    scene = NodeScene(x_range, y_range)
    cases = []
    for operation in MATH_OPERATIONS:
        blender_node = scene.node("ShaderNodeMath", operation=operation, use_clamp=use_clamp)
        scene.link(scene.x, blender_node.inputs[0])
        scene.link(scene.y, blender_node.inputs[1])
        blender_node.inputs[2].default_value = THIRD
        cases.append((operation, blender_node, "Value",
                      lambda X, Y, n=blender_node: evaluate(n, scene.points(X, Y),
                                                            Value=X.ravel(),
                                                            Value_001=Y.ravel())))
    check_outputs(scene, cases)


def vector_inputs(scene):
    """Three vectors varying over the image (sockets) and their values at X, Y."""
    sockets = (scene.combine(scene.x, scene.y, 0.6), scene.combine(scene.y, -0.8, scene.x),
               scene.combine(0.3, scene.x, scene.y))

    def values(X, Y):
        x, y = X.ravel(), Y.ravel()
        one = np.ones_like(x)
        return (np.stack([x, y, 0.6 * one]), np.stack([y, -0.8 * one, x]),
                np.stack([0.3 * one, x, y]))
    return sockets, values


@pytest.mark.cycles
@pytest.mark.parametrize("x_range, y_range", [((-2.0, 2.0), (-1.5, 1.5)),
                                              ((-7.0, 7.0), (-4.0, 6.0))])
def test_vector_math_matches_cycles(x_range, y_range):
    scene = NodeScene(x_range, y_range)
    sockets, values = vector_inputs(scene)
    cases = []
    for operation in VECTOR_OPERATIONS:
        blender_node = scene.node("ShaderNodeVectorMath", operation=operation)
        for socket, source in zip(blender_node.inputs[:3], sockets):
            scene.link(source, socket)
        scene.link(scene.y, by_identifier(blender_node.inputs)["Scale"])
        output = "Value" if operation in ("DOT_PRODUCT", "DISTANCE", "LENGTH") else "Vector"

        def compute(X, Y, n=blender_node):
            a, b, c = values(X, Y)
            return evaluate(n, scene.points(X, Y), Vector=a, Vector_001=b, Vector_002=c,
                            Scale=Y.ravel())
        cases.append((operation, blender_node, output, compute))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_map_range_matches_cycles_for_floats_and_vectors():
    scene = NodeScene((-2.0, 2.0), (-1.5, 1.5))
    vector = scene.combine(scene.x, scene.y, scene.x)
    low3, high3 = scene.combine(-1.0, scene.y, 0.5), scene.combine(scene.y, 1.0, -0.5)
    cases = []
    for interpolation in ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"):
        for clamp in (False, True):
            label = f"{interpolation}, clamp {clamp}"
            floats = scene.node("ShaderNodeMapRange", data_type='FLOAT', clamp=clamp,
                                interpolation_type=interpolation)
            scene.link(scene.x, floats.inputs["Value"])
            scene.link(scene.y, floats.inputs["From Max"])
            for name, number in (("From Min", -1.0), ("To Min", 0.2), ("To Max", 2.0),
                                 ("Steps", 3.5)):
                by_identifier(floats.inputs)[name].default_value = number
            cases.append((label, floats, "Result",
                          lambda X, Y, n=floats: evaluate(n, scene.points(X, Y),
                                                          Value=X.ravel(),
                                                          **{"From Max": Y.ravel()})))
            vectors = scene.node("ShaderNodeMapRange", data_type='FLOAT_VECTOR', clamp=clamp,
                                 interpolation_type=interpolation)
            sockets = by_identifier(vectors.inputs)
            scene.link(vector, sockets["Vector"])
            scene.link(low3, sockets["From_Min_FLOAT3"])
            scene.link(high3, sockets["From_Max_FLOAT3"])
            sockets["To_Min_FLOAT3"].default_value = (0.2, -1.0, 3.0)
            sockets["To_Max_FLOAT3"].default_value = (2.0, 1.0, -1.0)
            sockets["Steps_FLOAT3"].default_value = (3.0, 2.0, 4.5)

            def compute(X, Y, n=vectors):
                x, y = X.ravel(), Y.ravel()
                one = np.ones_like(x)
                return evaluate(n, scene.points(X, Y), Vector=np.stack([x, y, x]),
                                From_Min_FLOAT3=np.stack([-one, y, 0.5 * one]),
                                From_Max_FLOAT3=np.stack([y, one, -0.5 * one]))
            cases.append((label + ", vector", vectors, "Vector", compute))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_clamp_matches_cycles():
    scene = NodeScene((-2.0, 2.0), (-1.5, 1.5))
    cases = []
    for clamp_type in ("MINMAX", "RANGE"):
        blender_node = scene.node("ShaderNodeClamp", clamp_type=clamp_type)
        scene.link(scene.x, blender_node.inputs["Value"])
        scene.link(scene.y, blender_node.inputs["Min"])
        blender_node.inputs["Max"].default_value = 0.5
        cases.append((clamp_type, blender_node, "Result",
                      lambda X, Y, n=blender_node: evaluate(n, scene.points(X, Y),
                                                            Value=X.ravel(), Min=Y.ravel())))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_separate_and_combine_xyz_and_color_match_cycles():
    # Hue, saturation and value or lightness from -0.2 to 1.2: inside and past their range.
    scene = NodeScene((-0.2, 1.2), (-0.2, 1.2))
    colour = scene.combine(scene.x, scene.y, 0.4)
    cases = []

    def colour_of(X, Y):
        x = X.ravel()
        return np.stack([x, Y.ravel(), np.full_like(x, 0.4)])

    split = scene.node("ShaderNodeSeparateXYZ")
    scene.link(colour, split.inputs[0])
    for output in ("X", "Y", "Z"):
        cases.append((f"Separate XYZ {output}", split, output,
                      lambda X, Y: evaluate(split, scene.points(X, Y), Vector=colour_of(X, Y))))
    for mode in ("RGB", "HSV", "HSL"):
        combined = scene.node("ShaderNodeCombineColor", mode=mode)
        scene.link(scene.x, combined.inputs["Red"])
        scene.link(scene.y, combined.inputs["Green"])
        combined.inputs["Blue"].default_value = 0.7
        cases.append((f"Combine {mode}", combined, "Color",
                      lambda X, Y, n=combined: evaluate(n, scene.points(X, Y), Red=X.ravel(),
                                                        Green=Y.ravel())))
        separated = scene.node("ShaderNodeSeparateColor", mode=mode)
        scene.link(colour, separated.inputs["Color"])
        for output in ("Red", "Green", "Blue"):
            cases.append((f"Separate {mode} {output}", separated, output,
                          lambda X, Y, n=separated: evaluate(n, scene.points(X, Y),
                                                             Color=colour_of(X, Y))))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_vector_rotate_matches_cycles():
    scene = NodeScene((-3.0, 3.0), (-2.0, 2.5))
    vector = scene.combine(scene.x, scene.y, 0.5)
    axis = scene.combine(0.3, scene.y, 1.0)
    euler = scene.combine(scene.x, 0.4, scene.y)
    cases = []
    for rotation_type in ("AXIS_ANGLE", "X_AXIS", "Y_AXIS", "Z_AXIS", "EULER_XYZ"):
        for invert in (False, True):
            blender_node = scene.node("ShaderNodeVectorRotate", rotation_type=rotation_type,
                                      invert=invert)
            sockets = by_identifier(blender_node.inputs)
            scene.link(vector, sockets["Vector"])
            scene.link(axis, sockets["Axis"])
            scene.link(scene.x, sockets["Angle"])
            scene.link(euler, sockets["Rotation"])
            sockets["Center"].default_value = (0.2, -0.1, 0.3)

            def compute(X, Y, n=blender_node):
                x, y = X.ravel(), Y.ravel()
                one = np.ones_like(x)
                return evaluate(n, scene.points(X, Y), Vector=np.stack([x, y, 0.5 * one]),
                                Axis=np.stack([0.3 * one, y, one]), Angle=x,
                                Rotation=np.stack([x, 0.4 * one, y]))
            cases.append((f"{rotation_type}, invert {invert}", blender_node, "Vector",
                          compute))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_mapping_matches_cycles():
    scene = NodeScene((-3.0, 3.0), (-2.0, 2.5))
    vector = scene.combine(scene.x, scene.y, 0.5)
    rotation = scene.combine(0.3, scene.x, scene.y)
    scale = scene.combine(1.5, scene.y, 0.7)
    cases = []
    for vector_type in ("POINT", "TEXTURE", "VECTOR", "NORMAL"):
        blender_node = scene.node("ShaderNodeMapping", vector_type=vector_type)
        sockets = by_identifier(blender_node.inputs)
        scene.link(vector, sockets["Vector"])
        scene.link(rotation, sockets["Rotation"])
        scene.link(scale, sockets["Scale"])
        sockets["Location"].default_value = (0.3, -0.2, 0.1)

        def compute(X, Y, n=blender_node):
            x, y = X.ravel(), Y.ravel()
            one = np.ones_like(x)
            return evaluate(n, scene.points(X, Y), Vector=np.stack([x, y, 0.5 * one]),
                            Rotation=np.stack([0.3 * one, x, y]),
                            Scale=np.stack([1.5 * one, y, 0.7 * one]))
        cases.append((vector_type, blender_node, "Vector", compute))
    check_outputs(scene, cases)


def object_sources(obj, count):
    """The integrator's object coordinates for hits on ``obj``: its world matrix's columns."""
    matrix = np.array(obj.matrix_world)
    return {name: (lambda column=column: np.repeat(matrix[:3, column:column + 1], count, 1))
            for column, name in enumerate(("object_axis_x", "object_axis_y", "object_axis_z",
                                           "object_location"))}


@pytest.mark.cycles
def test_vector_transform_matches_cycles_between_world_object_and_camera():
    # The plane turned and scaled unevenly, so that object space differs from world space
    # by a rotation, a translation and a scale that changes normals' directions.
    scene = NodeScene((-3.0, 3.0), (-1.0, 2.0), turn=0.4)
    vector = scene.combine(scene.x, scene.y, 0.5)
    sources = object_sources(scene.plane, scene.X.size)
    cases = []
    for vector_type in ("POINT", "VECTOR", "NORMAL"):
        for convert_from in ("WORLD", "OBJECT", "CAMERA"):
            for convert_to in ("WORLD", "OBJECT", "CAMERA"):
                blender_node = scene.node("ShaderNodeVectorTransform", vector_type=vector_type,
                                          convert_from=convert_from, convert_to=convert_to)
                scene.link(vector, blender_node.inputs["Vector"])

                def compute(X, Y, n=blender_node):
                    x = X.ravel()
                    return evaluate(n, scene.points(X, Y, sources),
                                    Vector=np.stack([x, Y.ravel(), np.full_like(x, 0.5)]))
                cases.append((f"{vector_type} {convert_from} -> {convert_to}", blender_node,
                              "Vector", compute))
    check_outputs(scene, cases)
