"""What a material costs per hit: a constant material, and a 20-node tree.

    .venv/bin/python -m bench.node_tree [--width 1920 --height 1080 --repeats 3]

Both materials are made in Blender (pip bpy, headless) and exported by the add-on
(``addon.export.materials.export_material``), so that the program timed is the one a render
runs.  The batch is W x H hits (1920 x 1080: 2,073,600 by default) on a plane filling a
frame, in scanline order as a frame's hits come, in float64 (the precision meshes render
in):

* constant: a default Principled BSDF, which folds to constants; each hit gathers its row of
  the material table (``Closures.from_table``), as the path integrator does for every hit
  before any program runs;
* 20 nodes: Texture Coordinate, Mapping, two Noise textures, a Voronoi, two Color Ramps,
  five Math nodes, Map Range, an RGB, two Mix nodes, Hue/Saturation/Value, Separate Color
  and Bump into a Principled BSDF (Base Color, Roughness, Metallic, Normal): the program's
  run over the batch and its closures (``core.path.closures_at``'s work per material).
  The Bump evaluates its height's subtree at each hit and at two neighbours, as Cycles does.

The hits' coordinates (Generated, Object, UV and their derivatives) are given as ready
arrays: what making them costs (``core.surface_points``) is not counted, nor is the light
sampling and shading that follows.  It prints, per row, the median over the timed runs
(after a warm-up) of the CPU time and of the wall time, in microseconds per hit, and the
program's length.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from .measure import load_average
from .textures import time_case

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The plane's half extent (x, y): a 16:9 frame's.
HALF_WIDTH, HALF_HEIGHT = 1.0, 0.5625


def _glint():
    """The add-on, loaded and registered as render.py does (bpy first)."""
    import bpy  # noqa: F401  (first: it makes Blender's own modules importable)

    sys.path.insert(0, REPOSITORY)
    import render as render_script

    glint = render_script.import_glint()
    render_script.register_glint(glint)
    return glint


def _socket(sockets, identifier):
    return next(socket for socket in sockets if socket.identifier == identifier)


def twenty_node_material():
    """A bpy material of 20 nodes (module docstring) into its Material Output."""
    from glint.addon.compat import new_material

    material = new_material("twenty nodes")
    tree = material.node_tree
    nodes, links = tree.nodes, tree.links
    principled = nodes["Principled BSDF"]

    def add(kind, **properties):
        made = nodes.new(kind)
        for name, value in properties.items():
            setattr(made, name, value)
        return made

    def math(operation, a, b):
        made = add("ShaderNodeMath", operation=operation)
        for socket, value in zip(made.inputs, (a, b)):
            if isinstance(value, float):
                socket.default_value = value
            else:
                links.new(value, socket)
        return made.outputs[0]

    coordinates = add("ShaderNodeTexCoord")
    mapping = add("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (3.0, 3.0, 3.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.3)
    links.new(coordinates.outputs["Generated"], mapping.inputs["Vector"])
    noise = add("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value, noise.inputs["Detail"].default_value = 4.0, 4.0
    links.new(mapping.outputs["Vector"], noise.inputs["Vector"])
    fine = add("ShaderNodeTexNoise")
    fine.inputs["Scale"].default_value, fine.inputs["Detail"].default_value = 20.0, 2.0
    links.new(coordinates.outputs["Object"], fine.inputs["Vector"])
    voronoi = add("ShaderNodeTexVoronoi")
    voronoi.inputs["Scale"].default_value = 6.0
    links.new(mapping.outputs["Vector"], voronoi.inputs["Vector"])

    colours = add("ShaderNodeValToRGB")
    colours.color_ramp.elements[0].color = (0.6, 0.25, 0.1, 1.0)
    colours.color_ramp.elements[1].color = (0.9, 0.8, 0.6, 1.0)
    colours.color_ramp.elements.new(0.5).color = (0.3, 0.15, 0.05, 1.0)
    links.new(noise.outputs["Fac"], colours.inputs["Fac"])
    greys = add("ShaderNodeValToRGB")
    greys.color_ramp.elements[1].position = 0.4
    links.new(voronoi.outputs["Distance"], greys.inputs["Fac"])

    grain = math('MULTIPLY', noise.outputs["Fac"], fine.outputs["Fac"])
    cells = math('ADD', grain, voronoi.outputs["Distance"])
    sharpened = math('POWER', cells, 1.5)
    weight = math('MINIMUM', sharpened, 1.0)
    height = add("ShaderNodeMapRange")
    height.inputs["From Max"].default_value = 0.5
    links.new(voronoi.outputs["Distance"], height.inputs["Value"])
    metallic = math('SUBTRACT', 1.0, height.outputs["Result"])

    tint = add("ShaderNodeRGB")
    tint.outputs[0].default_value = (0.8, 0.7, 0.9, 1.0)
    mix = add("ShaderNodeMix", data_type='RGBA', blend_type='MULTIPLY')
    links.new(weight, _socket(mix.inputs, "Factor_Float"))
    links.new(colours.outputs["Color"], _socket(mix.inputs, "A_Color"))
    links.new(tint.outputs[0], _socket(mix.inputs, "B_Color"))
    hsv = add("ShaderNodeHueSaturation")
    links.new(_socket(mix.outputs, "Result_Color"), hsv.inputs["Color"])
    links.new(grain, hsv.inputs["Value"])

    separate = add("ShaderNodeSeparateColor")
    links.new(greys.outputs["Color"], separate.inputs["Color"])
    roughness = add("ShaderNodeMix", data_type='FLOAT')
    links.new(fine.outputs["Fac"], _socket(roughness.inputs, "Factor_Float"))
    links.new(separate.outputs["Red"], _socket(roughness.inputs, "A_Float"))
    _socket(roughness.inputs, "B_Float").default_value = 0.2
    bump = add("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.4
    links.new(height.outputs["Result"], bump.inputs["Height"])

    links.new(hsv.outputs["Color"], principled.inputs["Base Color"])
    links.new(_socket(roughness.outputs, "Result_Float"), principled.inputs["Roughness"])
    links.new(metallic, principled.inputs["Metallic"])
    links.new(bump.outputs["Normal"], principled.inputs["Normal"])
    counted = [n for n in nodes if n.bl_idname != "ShaderNodeOutputMaterial"]
    assert len(counted) == 20, [n.bl_idname for n in counted]
    return material


def plane_points(width: int, height: int, dtype=np.float64):
    """The ShadingPoints of width x height hits on the plane z = 0 filling the frame, seen
    from above: Generated, Object and UV coordinates (with their derivatives by position,
    which a Bump moves them along) and the object's axes, as ready arrays."""
    from glint.core.shader.points import ShadingPoints

    count = width * height
    rows, columns = np.divmod(np.arange(count), width)
    x = ((columns + 0.5) / width * 2 - 1) * HALF_WIDTH
    y = (1 - (rows + 0.5) / height * 2) * HALF_HEIGHT
    position = np.stack([x, y, np.zeros(count)]).astype(dtype)
    up = np.broadcast_to(np.array([[0.0], [0.0], [1.0]], dtype), (3, count))
    size = np.array([[HALF_WIDTH], [HALF_HEIGHT], [1.0]])
    generated = ((position + size) / (2 * size)).astype(dtype)
    uv = generated * np.array([[1.0], [1.0], [0.0]], dtype)
    axes = {f"object_axis_{axis}": np.broadcast_to(column.reshape(3, 1).astype(dtype),
                                                    (3, count))
            for axis, column in zip("xyz", np.eye(3))}
    sources = {"generated": lambda: generated, "object": lambda: position, "uv": lambda: uv,
               **{name: (lambda value=value: value) for name, value in axes.items()}}

    def constant(matrix):
        return lambda: np.broadcast_to(np.asarray(matrix, dtype)[:, :, None], (3, 3, count))

    jacobians = {"object": constant(np.eye(3)),
                 "generated": constant(np.diag(1 / (2 * size.ravel()))),
                 "uv": constant(np.diag([1 / (2 * HALF_WIDTH), 1 / (2 * HALF_HEIGHT), 0.0]))}
    # A pixel's footprint: the frame's width over its pixels.
    footprint = np.full(count, 2 * HALF_WIDTH / width, dtype)

    def make():
        return ShadingPoints(position, up, up, up, None, sources, jacobians, footprint)
    return make


def cases(width: int, height: int, dtype=np.float64):
    """(name, program length, callable) per row."""
    _glint()
    from glint.addon.compat import new_material
    from glint.addon.export.materials import export_material
    from glint.core.bsdf import surface_arrays
    from glint.core.closures import Closures
    from glint.core.shader.program import run

    constant, _ = export_material(new_material("constant"))
    assert constant.program is None
    table = surface_arrays([constant], dtype)
    material_ids = np.zeros(width * height, np.int64)

    textured, note = export_material(twenty_node_material())
    assert textured.program is not None, note
    make_points = plane_points(width, height, dtype)
    normal = np.ascontiguousarray(make_points().normal)

    def run_program():
        points = make_points()
        return run(textured.program, points).closures(len(points), dtype, normal)

    return [("constant material (default Principled BSDF)", 0,
             lambda: Closures.from_table(table, material_ids)),
            ("20-node tree into a Principled BSDF", len(textured.program), run_program)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.node_tree", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per row")
    args = parser.parse_args(argv)
    count = args.width * args.height
    rows = cases(args.width, args.height)
    print(f"{count:,} hits ({args.width} x {args.height}), float64; load average "
          f"{load_average()}")
    print("| material | instructions | CPU µs / hit | wall µs / hit |")
    print("|---|---|---|---|")
    for name, length, work in rows:
        cpu, wall = time_case(work, args.repeats)
        print(f"| {name} | {length} | {cpu / count * 1e6:.3f} | {wall / count * 1e6:.3f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
