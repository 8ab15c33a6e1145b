"""Value, RGB, Fresnel, Layer Weight, Geometry, Texture Coordinate, Object Info, Attribute
and Light Path against Cycles, per pixel (``node_support``).  A perspective camera makes the
direction to the camera vary over the plane, so the Fresnel and Layer Weight curves, the
Incoming and Reflection vectors and the Camera coordinates are checked over a range of
angles; the plane is seen from its front and from its back.

Per-hit data that the integrator gives (Generated, UV, Camera and Window coordinates,
attributes, object data, the ray's length) is given here from the plane itself and Blender's
own numbers, as the integrator is to give it: these tests check the nodes' reading and
arithmetic, and say what each name must hold."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from node_support import VIEW_HEIGHT, VIEW_WIDTH, NodeScene, check_outputs, evaluate

from glint.addon.export.node_options import world_to_camera  # noqa: E402
from glint.core.shader.points import ShadingPoints  # noqa: E402
from glint.core.shader.registry import NODES  # noqa: E402


def cases_of(scene, entries, sources=None):
    """``check_outputs`` cases for (Blender node, output identifier, linked inputs(X, Y)),
    the node function run at ShadingPoints carrying ``sources(X, Y)``."""
    def case(blender_node, output, inputs):
        def compute(X, Y):
            points = scene.points(X, Y, sources(X, Y) if sources else None)
            return evaluate(blender_node, points, **inputs(X, Y))
        return (f"{blender_node.bl_idname} {output}", blender_node, output, compute)
    return [case(*entry) for entry in entries]


def no_inputs(X, Y):
    return {}


@pytest.mark.cycles
def test_value_and_rgb_match_cycles():
    scene = NodeScene()
    value = scene.node("ShaderNodeValue")
    value.outputs[0].default_value = -2.75
    colour = scene.node("ShaderNodeRGB")
    colour.outputs[0].default_value = (0.2, 1.7, 0.05, 1.0)
    check_outputs(scene, cases_of(scene, [(value, "Value", no_inputs),
                                          (colour, "Color", no_inputs)]))


@pytest.mark.cycles
@pytest.mark.parametrize("back", [False, True], ids=["front", "back"])
def test_fresnel_and_layer_weight_match_cycles(back):
    """IOR from 0.5 to 3 and Blend from -0.2 to 1.2 across the image, with the surface's
    normal and with a Normal input (not of unit length, as Cycles takes it) whose cosine to
    the camera runs from about -0.9 to 0.9.  (Past a cosine of 1 Facing's power overflows
    float32 in Cycles: not a case to compare.)"""
    scene = NodeScene((0.0, 1.0), (-0.94, 0.94), perspective=True, back=back)
    spread = scene.node("ShaderNodeMath", operation='MULTIPLY_ADD')
    scene.link(scene.x, spread.inputs[0])
    spread.inputs[1].default_value, spread.inputs[2].default_value = 2.5, 0.5
    blend = scene.node("ShaderNodeMath", operation='MULTIPLY_ADD')
    scene.link(scene.x, blend.inputs[0])
    blend.inputs[1].default_value, blend.inputs[2].default_value = 1.4, -0.2
    bent = scene.combine(0.3, -0.2, scene.y)
    cases = []
    for linked_normal in (False, True):
        def normal(X, Y, linked=linked_normal):
            x = X.ravel()
            return dict(Normal=np.stack([np.full_like(x, 0.3), np.full_like(x, -0.2),
                                         Y.ravel()])) if linked else {}
        fresnel = scene.node("ShaderNodeFresnel")
        scene.link(spread.outputs[0], fresnel.inputs["IOR"])
        weight = scene.node("ShaderNodeLayerWeight")
        scene.link(blend.outputs[0], weight.inputs["Blend"])
        if linked_normal:
            scene.link(bent, fresnel.inputs["Normal"])
            scene.link(bent, weight.inputs["Normal"])
        cases.append((fresnel, "Fac",
                      lambda X, Y, n=normal: dict(IOR=X.ravel() * 2.5 + 0.5, **n(X, Y))))
        for output in ("Fresnel", "Facing"):
            cases.append((weight, output,
                          lambda X, Y, n=normal: dict(Blend=X.ravel() * 1.4 - 0.2, **n(X, Y))))
    check_outputs(scene, cases_of(scene, cases))


@pytest.mark.cycles
@pytest.mark.parametrize("back", [False, True], ids=["front", "back"])
def test_geometry_matches_cycles(back):
    """Position, Normal, True Normal, Incoming, Backfacing, and Pointiness (0.5: Cycles
    computes it for the mesh, and a flat one is 0.5 everywhere, the node's value when the
    integrator gives none).  Tangent, Parametric and Random Per Island are the integrator's
    data and read as given (``test_per_hit_data_defaults``)."""
    scene = NodeScene(perspective=True, back=back)
    geometry = scene.node("ShaderNodeNewGeometry")
    outputs = ("Position", "Normal", "True Normal", "Incoming", "Backfacing", "Pointiness")
    check_outputs(scene, cases_of(scene, [(geometry, output, no_inputs) for output in outputs]))


def window_and_camera_sources(scene):
    """'window' and 'camera' as the integrator gives them: the pixel's place in the frame
    (0 to 1 across, 0 to 1 up, z 0) and the hit in Cycles' camera space."""
    to_camera = np.array(world_to_camera(scene.scene))

    def sources(X, Y):
        points = scene.points(X, Y)
        position = points.position
        window = np.stack([(position[0] + VIEW_WIDTH / 2) / VIEW_WIDTH,
                           (position[1] + VIEW_HEIGHT / 2) / VIEW_HEIGHT,
                           np.zeros(X.size)])
        camera = to_camera[:, :3] @ position + to_camera[:, 3:]
        return {"window": lambda: window, "camera": lambda: camera}
    return sources


@pytest.mark.cycles
def test_texture_coordinate_matches_cycles():
    """Generated (the mesh's texture space), UV (a UV map), Object, Camera and Window from
    the integrator; Object relative to another object, Normal and Reflection computed by the
    node.  The plane is turned and scaled unevenly and its mesh is offset from its origin."""
    scene = NodeScene((0.5, 3.5), (-1.0, 1.5), turn=0.3, perspective=True)
    mesh = scene.plane.data
    uv = mesh.uv_layers.new(name="map")
    for loop in mesh.loops:
        x, y, _ = mesh.vertices[loop.vertex_index].co
        uv.data[loop.index].uv = (0.25 * x - 0.1, 0.5 * y + 0.3)   # linear: exact in Cycles
    other = bpy.data.objects.new("reference", None)
    scene.scene.collection.objects.link(other)
    other.location, other.rotation_euler, other.scale = (0.4, -0.3, 0.2), (0.3, 0.2, 1.0), (
        1.5, 0.5, 2.0)
    bpy.context.view_layer.update()
    # Blender's texture space of the mesh: Generated = (local - (location - size)) / 2 size.
    location, size = np.array(mesh.texspace_location), np.array(mesh.texspace_size)
    window_camera = window_and_camera_sources(scene)

    def sources(X, Y):
        local = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
        generated = (local - (location - size)[:, None]) / (2 * size)[:, None]
        uv_map = np.stack([0.25 * X.ravel() - 0.1, 0.5 * Y.ravel() + 0.3, np.zeros(X.size)])
        given = {"generated": lambda: generated, "uv": lambda: uv_map}
        given.update(window_camera(X, Y))
        return given

    plain = scene.node("ShaderNodeTexCoord")
    relative = scene.node("ShaderNodeTexCoord", object=other)
    cases = [(plain, output, no_inputs) for output in
             ("Generated", "Normal", "UV", "Object", "Camera", "Window", "Reflection")]
    cases.append((relative, "Object", no_inputs))
    check_outputs(scene, cases_of(scene, cases, sources))


def object_sources(scene, obj, material):
    count = scene.X.size

    def repeat(values):
        column = np.array(values, np.float64).reshape(3, 1)
        return lambda: np.repeat(column, count, axis=1)
    return lambda X, Y: {"object_location": repeat(obj.matrix_world.translation),
                         "object_color": repeat(obj.color[:3]),
                         "object_alpha": repeat((obj.color[3],) * 3),
                         "object_index": repeat((obj.pass_index,) * 3),
                         "material_index": repeat((material.pass_index,) * 3)}


@pytest.mark.cycles
def test_object_info_matches_cycles():
    """Location, Color, Alpha, Object Index and Material Index as the integrator gives them
    from the object and material; Random is Cycles' hash of the object, not compared."""
    scene = NodeScene()
    scene.plane.color = (0.2, 0.5, 0.9, 0.7)
    scene.plane.pass_index = 5
    scene.material.pass_index = 3
    info = scene.node("ShaderNodeObjectInfo")
    outputs = ("Location", "Color", "Alpha", "Object Index", "Material Index")
    check_outputs(scene, cases_of(scene, [(info, output, no_inputs) for output in outputs],
                                  object_sources(scene, scene.plane, scene.material)))


@pytest.mark.cycles
def test_attribute_matches_cycles():
    """A colour attribute (positive: Blender clamps colour attributes at 0) and a float
    attribute on the plane's corners (linear in x and y, so Cycles' interpolation over
    either triangle of the quad gives the same value), a missing one, and the object's
    Color through an Object attribute and a missing Object attribute (Alpha 0, where a
    missing geometry attribute's is 1)."""
    scene = NodeScene((-2.0, 2.0), (-1.5, 1.5))
    mesh = scene.plane.data
    mesh.color_attributes.new("tint", 'FLOAT_COLOR', 'POINT')
    mesh.attributes.new("weight", 'FLOAT', 'POINT')
    # Looked up again: adding an attribute moves the others' data (an older reference would
    # write to freed memory).
    tint, weight = mesh.attributes["tint"], mesh.attributes["weight"]

    def tint_of(x, y):
        return (0.5 + 0.2 * x, 0.3 - 0.1 * y, 0.6 + 0.1 * x + 0.2 * y, 0.6 + 0.1 * x)

    for index, vertex in enumerate(mesh.vertices):
        x, y, _ = vertex.co
        tint.data[index].color = tint_of(x, y)
        weight.data[index].value = 1.5 * x - y
    scene.plane.color = (0.7, 0.2, 0.4, 1.0)

    def sources(X, Y):
        x, y = X.ravel(), Y.ravel()
        r, g, b, a = tint_of(x, y)
        colour, alpha = np.stack([r, g, b]), np.stack([a, a, a])
        w = np.stack([1.5 * x - y] * 3)
        obj = np.repeat(np.array(scene.plane.color[:3]).reshape(3, 1), x.size, axis=1)
        return {"attribute:tint": lambda: colour, "attribute_alpha:tint": lambda: alpha,
                "attribute:weight": lambda: w, "object_attribute:color": lambda: obj}

    cases = []
    for attribute_type, name in (("GEOMETRY", "tint"), ("GEOMETRY", "weight"),
                                 ("GEOMETRY", "nothing"), ("OBJECT", "color"),
                                 ("OBJECT", "nothing")):
        node = scene.node("ShaderNodeAttribute", attribute_type=attribute_type,
                          attribute_name=name)
        outputs = ("Color", "Vector", "Fac", "Alpha") if name == "tint" else ("Color", "Fac",
                                                                              "Alpha")
        cases.extend((node, output, no_inputs) for output in outputs)
    check_outputs(scene, cases_of(scene, cases, sources))


@pytest.mark.cycles
def test_light_path_matches_cycles_for_camera_rays():
    """What the Light Path node says of camera rays: a camera ray, at depth 0, of length the
    hit's distance from the camera's near clipping plane along the ray (Cycles starts camera
    rays there: the distance from the camera less clip_start / cos(angle to the view axis));
    without a 'ray_type' the node takes every hit for a camera ray's.  (Other rays need the
    integrator: ``test_light_path_reads_the_ray_type_bits``.)"""
    scene = NodeScene(perspective=True)
    clip_start = scene.scene.camera.data.clip_start

    def sources(X, Y):
        points = scene.points(X, Y)
        distance = np.linalg.norm(points.position - scene.eye[:, None], axis=0)
        length = distance - clip_start * distance / scene.eye[2]
        return {"ray_length": lambda: np.stack([length] * 3)}
    path = scene.node("ShaderNodeLightPath")
    check_outputs(scene, cases_of(scene, [(path, socket.identifier, no_inputs)
                                          for socket in path.outputs], sources))


# --- Per-hit data without Cycles -----------------------------------------------------------

def bare_points(n=4, sources=None, backfacing=None):
    position = np.arange(3 * n, dtype=np.float64).reshape(3, n)
    up = np.zeros((3, n))
    up[2] = 1
    return ShadingPoints(position, up, up.copy(), up.copy(), backfacing=backfacing,
                         sources=sources)


def call(bl_idname, points, *inputs, **options):
    return NODES[bl_idname].function(points, *inputs, **options)


def test_per_hit_data_defaults():
    """Without the integrator's data the nodes take Cycles' values for such a hit: a flat
    surface's Pointiness 0.5, a white opaque object at the origin, a camera ray, zero for
    attributes, tangents and depths; with it they read it."""
    points = bare_points()
    geometry = call("ShaderNodeNewGeometry", points)
    assert np.all(geometry[2] == 0) and np.all(geometry[5] == 0)     # Tangent, Parametric
    assert np.all(geometry[7] == 0.5) and np.all(geometry[8] == 0)   # Pointiness, island
    location, colour, alpha, index, material, random = call("ShaderNodeObjectInfo", points)
    assert np.all(location == 0) and np.all(colour == 1) and np.all(alpha == 1)
    assert np.all(index == 0) and np.all(material == 0) and np.all(random == 0)
    colour, vector, fac, alpha = call("ShaderNodeAttribute", points, attribute_name="none")
    assert np.all(colour == 0) and np.all(fac == 0) and np.all(alpha == 1)
    flags = call("ShaderNodeLightPath", points)
    assert [float(np.max(f)) for f in flags[:8]] == [1, 0, 0, 0, 0, 0, 0, 0]
    assert all(np.all(depth == 0) for depth in flags[8:])

    values = np.array([[0.1, 0.2, 0.3, 0.4]] * 3)
    given = bare_points(sources={name: (lambda: values) for name in (
        "tangent", "parametric", "pointiness", "random_per_island", "object_color",
        "object_random")})
    geometry = call("ShaderNodeNewGeometry", given)
    for output in (geometry[2], geometry[5]):
        np.testing.assert_array_equal(output, values)
    np.testing.assert_array_equal(geometry[7], values[0])
    np.testing.assert_array_equal(geometry[8], values[0])
    info = call("ShaderNodeObjectInfo", given)
    np.testing.assert_array_equal(info[1], values)
    np.testing.assert_array_equal(info[5], values[0])

    instanced = bare_points(sources={"instancer_generated": lambda: values,
                                     "instancer_uv": lambda: 2 * values})
    generated, _, uv = call("ShaderNodeTexCoord", instanced, from_instancer=True)[:3]
    np.testing.assert_array_equal(generated, values)
    np.testing.assert_array_equal(uv, 2 * values)
    assert np.all(call("ShaderNodeTexCoord", instanced)[0] == 0)    # its own Generated


def test_light_path_reads_the_ray_type_bits():
    from glint.core.shader import input_nodes as inputs

    codes = [inputs.RAY_CAMERA, inputs.RAY_SHADOW, inputs.RAY_DIFFUSE | inputs.RAY_REFLECT,
             inputs.RAY_GLOSSY | inputs.RAY_TRANSMIT | inputs.RAY_SINGULAR,
             inputs.RAY_VOLUME_SCATTER]
    code = np.array([codes] * 3, np.float64)
    depth = np.array([[0, 1, 2, 3, 4]] * 3, np.float64)
    points = bare_points(5, {"ray_type": lambda: code, "ray_depth": lambda: depth,
                             "glossy_depth": lambda: depth * 2})
    flags = np.array([np.broadcast_to(f, 5) for f in call("ShaderNodeLightPath", points)])
    # Rows: camera, shadow, diffuse, glossy, singular, reflection, transmission, volume.
    np.testing.assert_array_equal(flags[:8], [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0],
                                              [0, 0, 1, 0, 0], [0, 0, 0, 1, 0],
                                              [0, 0, 0, 1, 0], [0, 0, 1, 0, 0],
                                              [0, 0, 0, 1, 0], [0, 0, 0, 0, 1]])
    np.testing.assert_array_equal(flags[9], [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(flags[11], [0, 2, 4, 6, 8])
    np.testing.assert_array_equal(flags[10], 0)
