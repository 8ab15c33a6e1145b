"""Checking the core's shader node functions against Cycles, pixel by pixel.

A plane fills the view of an orthographic camera looking straight down at it.  Its material
feeds the node under test inputs that vary over the image: the plane's Object coordinates x
(left to right) and y (bottom to top), spanning ranges the test chooses (the object is
scaled to fill the view whatever the ranges), through nodes the test adds.  Each result goes
to a shader AOV, so one Cycles render (1 sample per pixel at its centre: ``cycles_scene``'s
filter_width 0.01) checks many nodes at once; the multilayer OpenEXR holds the AOVs
scene-linear and unclamped (an Emission shader's pixels would be the same but for negative
channels, which Cycles' emission turns to 0: seen for a colour of (-0.5, 2, 0.3)).  The
test computes the same inputs at each pixel centre and calls the node's function from the
registry with them, its options read from the Blender node as the add-on reads them
(``addon.export.node_options``, else the node's properties).

Tolerance (``compare``): Cycles computes in float32, so a value may differ from the float64
one by a few float32 steps of the quantities involved (``RTOL``, ``ATOL``); and Cycles'
Object coordinates carry an error of their own (the hit point found in world space and moved
into object space: ``INPUT_ERROR``, measured at most 3e-7 of the largest coordinate), so
where the result is steep or jumps (floor, modulo, a colour ramp's constant steps) the
comparison allows for the values the function takes within that error of the pixel's
inputs, and for as much again about its own value (a sawtooth such as Wrap has branches on
both sides that float32 rounding can land between).  So that this cannot hide a wrong
function, at most MAX_LOOSE of a node's pixels may have such an allowance above LOOSE.
"""

from __future__ import annotations

import math
import os
import tempfile

import bpy
import numpy as np
from mathutils import Matrix, Vector

from addon_support import link
from glint.addon.compat import new_material, set_file_format  # noqa: E402
from cycles_support import cycles_scene
from exr import read_exr

from glint.addon.export.node_options import OPTION_READERS  # noqa: E402
from glint.core.shader.points import ShadingPoints  # noqa: E402
from glint.core.shader.registry import COLOR, FLOAT, NODES, VECTOR  # noqa: E402

WIDTH, HEIGHT = 64, 48
#: The view: 4 x 3 world units (WIDTH x HEIGHT pixels) centred on the origin, seen from +Z.
VIEW_WIDTH, VIEW_HEIGHT = 4.0, 3.0
CAMERA_HEIGHT = 10.0
#: float32 arithmetic: a few units in the last place of values near 1.
RTOL, ATOL = 2e-6, 2e-6
#: How far Cycles' Object coordinates may be from the exact pixel centre, relative to the
#: largest coordinate (measured: 2.4e-7 for ranges of 4, 2.9e-7 for 20, 2e-7 for 1).
INPUT_ERROR = 1e-6
#: A pixel whose allowance grew past LOOSE (relative to 1 + |value|) is loosely checked (the
#: function is steep or jumps there); at most MAX_LOOSE of the pixels may be.
LOOSE = 1e-3
MAX_LOOSE = 0.15

SOCKET_KINDS = {"VALUE": FLOAT, "VECTOR": VECTOR, "RGBA": COLOR}


class NodeScene:
    """The plane, its material and the AOVs a test adds (module docstring).

    x_range, y_range: the Object coordinates at the left/right and bottom/top edges.
    turn: the plane turned about Z by this angle (radians), scaled to still fill the view.
    perspective: a perspective camera (placed so the view spans the same part of the
    plane), so that the direction to the camera varies over the image; back: the plane
    faces away from the camera (every hit is backfacing).
    ``x`` and ``y``: sockets giving them; ``X``, ``Y``: (HEIGHT, WIDTH) their exact values
    at the pixel centres (row 0 at the top, as the EXR).
    """

    def __init__(self, x_range=(-2.0, 2.0), y_range=(-1.5, 1.5), turn=0.0, perspective=False,
                 back=False):
        scene = cycles_scene(samples=1)
        scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
        for obj in list(scene.objects):
            bpy.data.objects.remove(obj)
        camera = bpy.data.cameras.new("top")
        camera_object = link(bpy.data.objects.new("top", camera))
        if perspective:
            # At this height the perspective view spans the same 4 x 3 units of the plane.
            camera.sensor_fit, camera.sensor_width, camera.lens = 'HORIZONTAL', 36.0, 50.0
            height = VIEW_WIDTH / 2 * camera.lens / (camera.sensor_width / 2)
        else:
            camera.type, camera.ortho_scale = 'ORTHO', VIEW_WIDTH
            height = CAMERA_HEIGHT
        camera_object.location = (0.0, 0.0, height)
        scene.camera = camera_object
        self.eye = np.array([0.0, 0.0, height]) if perspective else None
        self.back = back
        (x0, x1), (y0, y1) = x_range, y_range
        mesh = bpy.data.meshes.new("plane")
        corners = [(0, 1, 2, 3)] if not back else [(3, 2, 1, 0)]
        mesh.from_pydata([(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0)], [],
                         corners)
        self.plane = link(bpy.data.objects.new("plane", mesh))
        # Turned by ``turn`` about Z, the plane is scaled to cover the view's rotated extent;
        # its centre sits at the view's centre.
        cos, sin = abs(math.cos(turn)), abs(math.sin(turn))
        half_x = VIEW_WIDTH / 2 * cos + VIEW_HEIGHT / 2 * sin
        half_y = VIEW_WIDTH / 2 * sin + VIEW_HEIGHT / 2 * cos
        sx, sy = 2 * half_x / (x1 - x0), 2 * half_y / (y1 - y0)
        self.plane.scale = (sx, sy, 1.0)
        self.plane.rotation_euler = (0.0, 0.0, turn)
        centre = Matrix.Rotation(turn, 3, 'Z') @ Vector((sx * (x0 + x1) / 2, sy * (y0 + y1) / 2,
                                                          0.0))
        self.plane.location = -centre
        self.material = new_material("under test")
        mesh.materials.append(self.material)
        self.tree = self.material.node_tree
        self.tree.nodes.remove(self.tree.nodes["Principled BSDF"])
        coordinates = self.node("ShaderNodeTexCoord")
        split = self.node("ShaderNodeSeparateXYZ")
        self.link(coordinates.outputs["Object"], split.inputs[0])
        self.x, self.y = split.outputs["X"], split.outputs["Y"]
        # The pixel centres in world space, taken into the plane's local space.
        u = ((np.arange(WIDTH) + 0.5) / WIDTH - 0.5) * VIEW_WIDTH
        v = (0.5 - (np.arange(HEIGHT) + 0.5) / HEIGHT) * VIEW_HEIGHT
        world_x, world_y = np.meshgrid(u, v)
        bpy.context.view_layer.update()
        inverse = np.array(self.plane.matrix_world.inverted())
        self.X = inverse[0, 0] * world_x + inverse[0, 1] * world_y + inverse[0, 3]
        self.Y = inverse[1, 0] * world_x + inverse[1, 1] * world_y + inverse[1, 3]
        self.scale = max(abs(x0), abs(x1), abs(y0), abs(y1), 1.0)
        self.scene = scene
        self.aovs = {}

    def node(self, kind, **properties):
        made = self.tree.nodes.new(kind)
        for key, value in properties.items():
            setattr(made, key, value)
        return made

    def link(self, output, into):
        self.tree.links.new(output, into)

    def constant(self, value):
        """A Value node's output holding ``value``."""
        made = self.node("ShaderNodeValue")
        made.outputs[0].default_value = value
        return made.outputs[0]

    def combine(self, first, second, third):
        """A Combine XYZ of three sockets or numbers (a vector or, linked into a colour
        socket, a colour)."""
        made = self.node("ShaderNodeCombineXYZ")
        for socket, source in zip(made.inputs, (first, second, third)):
            if isinstance(source, bpy.types.NodeSocket):
                self.link(source, socket)
            else:
                socket.default_value = source
        return made.outputs[0]

    def aov(self, socket) -> str:
        """Write ``socket`` to a new AOV; its name (a key of ``render``'s result)."""
        name = f"aov{len(self.aovs)}"
        colour = socket.type in ("VECTOR", "RGBA")
        output = self.node("ShaderNodeOutputAOV")
        output.aov_name = name
        self.link(socket, output.inputs["Color" if colour else "Value"])
        entry = self.scene.view_layers[0].aovs.add()
        entry.name, entry.type = name, 'COLOR' if colour else 'VALUE'
        self.aovs[name] = colour
        return name

    def render(self) -> dict:
        """{AOV name: (HEIGHT, WIDTH) or (3, HEIGHT, WIDTH) float32} from Cycles."""
        scene = self.scene
        scene.render.engine = 'CYCLES'
        settings = scene.render.image_settings
        set_file_format(settings, 'OPEN_EXR_MULTILAYER')
        settings.exr_codec, settings.color_depth = 'NONE', '32'
        layer = scene.view_layers[0].name
        with tempfile.TemporaryDirectory() as folder:
            scene.render.filepath = os.path.join(folder, "nodes.exr")
            bpy.ops.render.render(write_still=True)
            planes = read_exr(scene.render.filepath)
        result = {}
        for name, colour in self.aovs.items():
            if colour:
                result[name] = np.stack([planes[f"{layer}.{name}.{c}"] for c in "RGB"])
            else:
                result[name] = planes[f"{layer}.{name}.X"]
        return result

    def points(self, X=None, Y=None, sources=None) -> ShadingPoints:
        """ShadingPoints at the pixel centres (or at Object coordinates X, Y): on the plane,
        normal +Z (facing the camera, on either side), incoming towards the camera, Object
        coordinates given."""
        X = self.X if X is None else X
        Y = self.Y if Y is None else Y
        local = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
        world = (np.array(self.plane.matrix_world)[:3, :3] @ local
                 + np.array(self.plane.matrix_world)[:3, 3:4])
        up = np.zeros_like(world)
        up[2] = 1.0
        if self.eye is None:
            incoming = up.copy()
        else:
            incoming = self.eye[:, None] - world
            incoming /= np.linalg.norm(incoming, axis=0)
        given = {"object": lambda: local}
        given.update(sources or {})
        return ShadingPoints(world, up, up.copy(), incoming,
                             backfacing=np.full(X.size, self.back), sources=given)


def by_identifier(sockets) -> dict:
    """{identifier: socket} of a node's inputs or outputs, the unavailable ones too (Blender
    5 finds only available sockets by name)."""
    return {socket.identifier: socket for socket in sockets}


def node_options(blender_node) -> dict:
    """The node's options as the add-on reads them."""
    reader = OPTION_READERS.get(blender_node.bl_idname)
    if reader is not None:
        return reader(blender_node)
    return {name: getattr(blender_node, name) for name in NODES[blender_node.bl_idname].options}


def unlinked_value(socket):
    """A socket's own value as the evaluator passes it: 0-d for a float, (3, 1) for a vector
    or colour (alpha dropped)."""
    if socket.type == "VALUE":
        return np.asarray(float(socket.default_value))
    return np.asarray(tuple(socket.default_value)[:3], np.float64).reshape(3, 1)


def evaluate(blender_node, points, **linked):
    """The registry function's outputs {identifier: array} for ``blender_node``: inputs
    from ``linked`` (identifier -> array) or the socket's own value, options as the add-on
    reads them."""
    spec = NODES[blender_node.bl_idname]
    sockets = by_identifier(blender_node.inputs)
    arguments = []
    for identifier, kind in spec.inputs:
        if identifier in linked:
            arguments.append(np.asarray(linked[identifier]))
        elif identifier in spec.implicit:
            arguments.append(points.coordinate(spec.implicit[identifier]))
        else:
            arguments.append(unlinked_value(sockets[identifier]))
    results = spec.function(points, *arguments, **node_options(blender_node))
    assert len(results) == len(spec.outputs), blender_node.bl_idname
    return {identifier: np.asarray(result)
            for (identifier, _), result in zip(spec.outputs, results)}


def as_image(values, colour: bool):
    """A node output (n,) / (3, n) (or broadcastable) as (HEIGHT, WIDTH) / (3, HEIGHT, WIDTH)."""
    shape = (3, HEIGHT * WIDTH) if colour else (HEIGHT * WIDTH,)
    return np.broadcast_to(np.asarray(values, np.float64), shape).reshape(
        ((3,) if colour else ()) + (HEIGHT, WIDTH))


def compare(cycles, compute, scene: NodeScene, label: str, rtol=RTOL, atol=ATOL,
            max_loose=MAX_LOOSE):
    """Assert Cycles' image matches ``compute(X, Y)`` (the function's output at Object
    coordinates X, Y, as an image) within the module docstring's tolerance: float32
    arithmetic (rtol, atol) beyond the range of values the function takes within
    INPUT_ERROR of each pixel's inputs, or that range's width about its own value; at most
    ``max_loose`` of the pixels may have a range wider than LOOSE."""
    expected = compute(scene.X, scene.Y)
    step = INPUT_ERROR * scene.scale
    low, high = expected.copy(), expected.copy()
    for dx, dy in ((step, 0), (-step, 0), (0, step), (0, -step)):
        nearby = compute(scene.X + dx, scene.Y + dy)
        low, high = np.fmin(low, nearby), np.fmax(high, nearby)
    allowed = atol + rtol * np.maximum(np.abs(low), np.abs(high))
    error = np.abs(cycles - expected)
    # Within the values the function takes near the inputs, or as far from the pixel's value
    # as they spread (a sawtooth's branches: Cycles' float32 rounding may land between).
    bad = ~(((cycles >= low - allowed) & (cycles <= high + allowed))
            | (error <= allowed + (high - low)))
    loose = ~(high - low <= LOOSE * (1 + np.abs(expected)))
    if expected.ndim == 3:
        bad, loose = bad.any(axis=0), loose.any(axis=0)
    if bad.any():
        where = np.argwhere(bad)[:5]
        details = [(tuple(p), float(scene.X[tuple(p[-2:])]), float(scene.Y[tuple(p[-2:])]),
                    cycles[(...,) + tuple(p[-2:])], expected[(...,) + tuple(p[-2:])])
                   for p in where]
        raise AssertionError(f"{label}: {bad.sum()} of {bad.size} pixels differ from Cycles "
                             f"(max error {np.nanmax(error):.3g}); first (pixel, x, y, "
                             f"Cycles, Glint): {details}")
    assert loose.mean() <= max_loose, (
        f"{label}: {loose.mean():.1%} of the pixels are steep or jump within the inputs' "
        "error: the comparison would say little there")


def check_outputs(scene: NodeScene, cases):
    """Render ``scene`` once and ``compare`` each case with Cycles: (label, Blender node,
    output identifier, compute(X, Y) -> the node function's outputs at Object coordinates
    X, Y, as ``evaluate`` gives them)."""
    names = [scene.aov(by_identifier(blender_node.outputs)[output])
             for _, blender_node, output, _ in cases]
    rendered = scene.render()
    for name, (label, blender_node, output, compute) in zip(names, cases):
        colour = by_identifier(blender_node.outputs)[output].type in ("VECTOR", "RGBA")
        compare(rendered[name], lambda X, Y: as_image(compute(X, Y)[output], colour), scene,
                label)
