"""Texture nodes rendered by Cycles and evaluated by Glint's node functions at the same
points, pixel by pixel.

Each ``Case`` is one texture node with its options and input values.  Cases are laid out as
square tiles in one orthographic render looking straight down (-Z) at a grid of planes, one
plane and one material per tile; Cycles renders one sample per pixel with a 0.01-pixel
filter, which hits each pixel's centre (the test checks the Object and Generated coordinates
Cycles reports against the centres: within 2.3e-6, the rounding of its hit points).  Each material feeds the texture its Vector (the plane's Object
coordinate through a Mapping node, which turns and shifts it so that all three components
vary over the tile; or the socket left unlinked, which Cycles reads as the Generated
coordinate, or for White Noise as the socket's value) and a W that varies across the tile,
and writes them into shader AOVs beside the texture's outputs.  The EXR's AOVs thus
hold, per pixel, the exact float32 coordinates Cycles evaluated the texture at and what it
found there, and the test calls the node function on those same coordinates: the comparison
sees only the texture's arithmetic, not how either renderer computes a hit point.

Planes tilt (z = 0.3 x - 0.2 y in object space) so that the Generated coordinate's z varies
too.  A tile's pixels are all inside its plane (tile edges fall on pixel edges).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field

import bpy
import numpy as np

from addon_support import link
from glint.addon.compat import new_material  # noqa: E402
from cycles_support import cycles_scene
from exr import read_exr

from glint.addon.export.node_options import OPTION_READERS
from glint.core.shader import textures  # noqa: F401  (registers the texture nodes)
from glint.core.shader.registry import FLOAT, NODES, VECTOR

TILE = 24
COLUMNS = 8
LAYER = "ViewLayer"
#: AOVs written by every material: the texture's Vector and W, and up to three float and
#: three colour (or vector) outputs.
FLOAT_AOVS = ("w", "f0", "f1", "f2")
COLOUR_AOVS = ("vector", "c0", "c1", "c2")


@dataclass
class Case:
    """One texture node: its type, options (node properties), input values by socket
    identifier (the rest keep Blender's defaults), and how its Vector is fed: 'object' (the
    Object coordinate mapped by ``location``, ``rotation``, ``scale``), or left unlinked.
    exact: whether Cycles' AVX2 kernel was measured to give these values bit for bit."""

    kind: str
    options: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    #: 'object', 'generated' (unlinked, Cycles links the Generated coordinate) or 'socket'
    #: (unlinked, the socket's own value: White Noise's).
    vector: str = "object"
    location: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = (0.6, 0.4, 0.2)
    scale: tuple = (1.0, 1.0, 1.0)
    #: W = x * w_scale + w_offset of the mapped vector.
    w_scale: float = 1.5
    w_offset: float = 0.25
    name: str = ""
    exact: bool = True
    #: The node's Texture Mapping: {property of TexMapping: value}, set in Blender.
    texture_mapping: dict = field(default_factory=dict)
    #: The outputs to compare (all when empty).
    compared: tuple = ()

    def label(self) -> str:
        if self.name:
            return self.name
        text = ",".join(f"{key}={value}" for key, value in self.options.items())
        values = ",".join(f"{key}={value}" for key, value in self.inputs.items())
        return f"{self.kind[13:]}[{text}]({values})"


@dataclass
class Result:
    """What Cycles gave for one case: the points (vector (3, n), w (n,)), the outputs
    {identifier: (n,) or (3, n)}, the input values the node had, the tile's shape, and the
    options the add-on's readers (``addon.export.node_options``) found on the node."""

    case: Case
    vector: np.ndarray
    w: np.ndarray
    outputs: dict
    inputs: dict
    shape: tuple
    read_options: dict = field(default_factory=dict)

    def glint(self) -> dict:
        """The node function's outputs at the same points, by identifier."""
        spec = NODES[self.case.kind]
        arguments = []
        for identifier, kind in spec.inputs:
            if identifier == "Vector":
                arguments.append(self.vector)
            elif identifier == "W":
                arguments.append(self.w)
            elif kind == FLOAT:
                arguments.append(np.asarray(self.inputs[identifier], np.float32))
            else:
                arguments.append(np.asarray(self.inputs[identifier], np.float32).reshape(3, 1))
        values = spec.function(None, *arguments, **self.case.options, **self.read_options)
        return {identifier: np.broadcast_to(value, self.outputs[identifier].shape)
                for (identifier, _), value in zip(spec.outputs, values)
                if identifier in self.outputs}


def _socket_value(socket):
    value = socket.default_value
    try:
        return tuple(value)[:3]
    except TypeError:
        return value


def _input(node, identifier):
    """A node's input by identifier (looking one up by name skips unavailable sockets, such
    as Noise's Offset in fBM mode, whose value Cycles still reads)."""
    return next(socket for socket in node.inputs if socket.identifier == identifier)


def _output(node, identifier):
    return next(socket for socket in node.outputs if socket.identifier == identifier)


def _material(case: Case, index: int):
    material = new_material(f"case{index}")
    tree = material.node_tree
    nodes, links = tree.nodes, tree.links
    nodes.remove(nodes["Principled BSDF"])
    texture = nodes.new(case.kind)
    for key, value in case.options.items():
        setattr(texture, key, value)
    for key, value in case.texture_mapping.items():
        setattr(texture.texture_mapping, key, value)
    reader = OPTION_READERS.get(case.kind)
    read_options = reader(texture) if reader else {}
    for key, value in case.inputs.items():
        socket = _input(texture, key)
        socket.default_value = (*value, 1.0) if isinstance(value, tuple) and len(value) == 3 \
            and socket.type == 'RGBA' else value
    coordinates = nodes.new("ShaderNodeTexCoord")
    if case.vector == "object":
        mapping = nodes.new("ShaderNodeMapping")
        links.new(coordinates.outputs["Object"], mapping.inputs["Vector"])
        mapping.inputs["Location"].default_value = case.location
        mapping.inputs["Rotation"].default_value = case.rotation
        mapping.inputs["Scale"].default_value = case.scale
        vector = mapping.outputs["Vector"]
        links.new(vector, _input(texture, "Vector"))
    else:
        vector = coordinates.outputs["Generated"]  # what an unlinked texture Vector reads
    separate = nodes.new("ShaderNodeSeparateXYZ")
    links.new(vector, separate.inputs[0])
    w = nodes.new("ShaderNodeMath")
    w.operation = 'MULTIPLY_ADD'
    links.new(separate.outputs["X"], w.inputs[0])
    w.inputs[1].default_value, w.inputs[2].default_value = case.w_scale, case.w_offset
    if any(socket.identifier == "W" for socket in texture.inputs):
        links.new(w.outputs[0], _input(texture, "W"))

    def aov(name, socket, kind):
        output = nodes.new("ShaderNodeOutputAOV")
        output.aov_name = name
        links.new(socket, output.inputs["Color" if kind == 'COLOR' else "Value"])

    aov("vector", vector, 'COLOR')
    aov("w", w.outputs[0], 'VALUE')
    captured, floats, colours = {}, iter(FLOAT_AOVS[1:]), iter(COLOUR_AOVS[1:])
    for identifier, kind in NODES[case.kind].outputs:
        socket = _output(texture, identifier)
        if not socket.enabled:  # a socket the node's options hide: nothing can read it
            continue
        name = next(floats) if kind == FLOAT else next(colours)
        aov(name, socket, 'VALUE' if kind == FLOAT else 'COLOR')
        captured[identifier] = (name, kind)
    emission = nodes.new("ShaderNodeEmission")
    links.new(next(socket for socket in texture.outputs if socket.enabled),
              emission.inputs["Color"])
    links.new(emission.outputs[0], nodes["Material Output"].inputs["Surface"])
    inputs = {socket.identifier: _socket_value(socket) for socket in texture.inputs
              if socket.identifier != "W"}
    return material, captured, inputs, read_options


def _tile_mesh():
    mesh = bpy.data.meshes.new("tile")
    mesh.from_pydata([(-1.0, -1.0, -0.1), (1.0, -1.0, 0.5), (1.0, 1.0, 0.1), (-1.0, 1.0, -0.5)],
                     [], [(0, 1, 2, 3)])
    return mesh


def render_cases(cases: list[Case], tile: int = TILE) -> list[Result]:
    """Renders the cases with Cycles in one image and returns what each tile holds."""
    rows = -(-len(cases) // COLUMNS)
    columns = min(COLUMNS, len(cases))
    scene = cycles_scene(samples=1)
    scene.render.resolution_x, scene.render.resolution_y = columns * tile, rows * tile
    bpy.data.objects.remove(scene.camera)
    camera = bpy.data.cameras.new("above")
    camera.type = 'ORTHO'
    camera.ortho_scale = max(columns, rows)
    camera_object = link(bpy.data.objects.new("above", camera))
    camera_object.location = (columns / 2, -rows / 2, 10.0)
    scene.camera = camera_object
    layer = scene.view_layers[LAYER]
    for name in FLOAT_AOVS + COLOUR_AOVS:
        aov = layer.aovs.add()
        aov.name, aov.type = name, 'VALUE' if name in FLOAT_AOVS else 'COLOR'
    captured = []
    for index, case in enumerate(cases):
        material, outputs, inputs, read_options = _material(case, index)
        mesh = _tile_mesh()
        mesh.materials.append(material)
        plane = link(bpy.data.objects.new(f"tile{index}", mesh))
        row, column = divmod(index, COLUMNS)
        plane.location = (column + 0.5, -row - 0.5, 0.0)
        plane.scale = (0.5, 0.5, 0.5)
        captured.append((outputs, inputs, read_options))
    settings = scene.render.image_settings
    settings.media_type = 'MULTI_LAYER_IMAGE'
    settings.exr_codec, settings.color_depth = 'NONE', '32'
    scene.render.engine = 'CYCLES'
    with tempfile.TemporaryDirectory() as folder:
        scene.render.filepath = os.path.join(folder, "cases.exr")
        bpy.ops.render.render(write_still=True)
        planes = read_exr(scene.render.filepath)
    scene.render.engine = 'GLINT'

    def plane(name, kind, rows_, columns_):
        if kind == FLOAT:
            return planes[f"{LAYER}.{name}.X"][rows_, columns_].reshape(-1)
        return np.stack([planes[f"{LAYER}.{name}.{c}"][rows_, columns_].reshape(-1)
                         for c in "RGB"])

    results = []
    for index, (case, (outputs, inputs, read_options)) in enumerate(zip(cases, captured)):
        row, column = divmod(index, COLUMNS)
        rows_ = slice(row * tile, (row + 1) * tile)
        columns_ = slice(column * tile, (column + 1) * tile)
        vector = plane("vector", VECTOR, rows_, columns_)
        if case.vector == "socket":
            vector = np.broadcast_to(np.asarray(inputs["Vector"], np.float32).reshape(3, 1),
                                     vector.shape)
        results.append(Result(
            case, vector, plane("w", FLOAT, rows_, columns_),
            {identifier: plane(name, kind, rows_, columns_)
             for identifier, (name, kind) in outputs.items()},
            inputs, (tile, tile), read_options))
    return results
