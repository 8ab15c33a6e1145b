"""The README's picture: one small scene rendered by Glint and by Cycles, side by side.

    .venv/bin/python -m bench.readme_picture [--out docs/images/glint-and-cycles.png]
        [--width 320] [--height 240] [--cycles-samples 256]

The scene is built here in ``bpy`` (no file is read): three spheres (a red plastic, a gold
metal, a white plastic) and a blue cube on a grey floor, a sun and a blue world, each
surface a Principled BSDF.  Both engines render it through F12 (``bpy.ops.render.render``)
with their own settings: Glint at the add-on's defaults (path tracing, 4 samples,
denoised, the scene's light paths), Cycles on the CPU at ``--cycles-samples`` samples with
its default light paths, not denoised.
Both go through the scene's colour management (AgX, Blender's default).  The PNG has Glint
on the left and Cycles on the right; one JSON line gives each engine's F12 time and the
two images' similarity (``bench.scale.similarity``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

from . import scale
from .blender_scenes import principled_material

OUTPUT = os.path.join(scale.REPOSITORY, "docs", "images", "glint-and-cycles.png")
#: Each image's size: two of them side by side make a picture about 640 pixels wide.
SIZE = (320, 240)
#: Cycles' samples: enough that its noise is small beside the two engines' differences.
CYCLES_SAMPLES = 256


def _ball(name: str, location, radius: float, material):
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    shape = bmesh.new()
    bmesh.ops.create_uvsphere(shape, u_segments=64, v_segments=32, radius=radius)
    shape.to_mesh(mesh)
    shape.free()
    mesh.shade_smooth()
    mesh.materials.append(material)
    ball = scale._link(bpy.data.objects.new(name, mesh))
    ball.location = location
    return ball


def build(width: int, height: int, cycles_samples: int) -> None:
    """A fresh file holding the picture's scene, camera, sun and world."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=30.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.data.materials.append(principled_material("floor", (0.55, 0.55, 0.55), 0.5))
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(0.15, -1.4, 0.6),
                                    rotation=(0.0, 0.0, math.radians(30.0)))
    bpy.context.object.data.materials.append(principled_material("cube", (0.08, 0.2, 0.65), 0.4))
    _ball("red", (-1.55, 0.7, 1.0), 1.0, principled_material("red", (0.8, 0.08, 0.04), 0.35))
    _ball("gold", (1.2, 1.4, 0.8), 0.8, principled_material("gold", (1.0, 0.72, 0.3), 0.25, 1.0))
    _ball("white", (1.9, -0.7, 0.5), 0.5, principled_material("white", (0.8, 0.8, 0.8), 0.2))

    camera = scale._link(bpy.data.objects.new("camera", bpy.data.cameras.new("camera")))
    camera.location = (0.0, -7.6, 3.0)
    camera.rotation_euler = (math.radians(72.0), 0.0, 0.0)
    camera.data.lens = 42.0
    scene.camera = camera
    sun = bpy.data.lights.new("sun", 'SUN')
    sun.energy = 3.0
    sun.angle = math.radians(4.0)
    scale._link(bpy.data.objects.new("sun", sun)).rotation_euler = (
        math.radians(40.0), 0.0, math.radians(-35.0))
    world = bpy.data.worlds.new("sky")
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.35, 0.5, 0.8, 1.0)
    background.inputs["Strength"].default_value = 0.6
    scene.world = world

    render = scene.render
    render.resolution_x, render.resolution_y = width, height
    render.resolution_percentage = 100
    render.film_transparent = False
    render.use_compositing = render.use_sequencer = False
    scene.view_settings.view_transform = 'AgX'
    settings = render.image_settings
    settings.file_format = 'PNG'
    settings.color_mode = 'RGBA'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = cycles_samples
    scene.cycles.use_denoising = False


def render_both() -> dict:
    """F12 with each engine: {engine: (H, W, 4) display image}, and each F12's seconds."""
    import bpy

    scene = bpy.context.scene
    images, seconds = {}, {}
    with tempfile.TemporaryDirectory() as folder:
        for engine in ("GLINT", "CYCLES"):
            scene.render.engine = engine
            start = time.perf_counter()
            scale.f12(scene, engine, "the README's picture")()
            seconds[engine.lower()] = time.perf_counter() - start
            images[engine] = scale._render_image(engine, folder)
    return {"images": images, "seconds": seconds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.readme_picture",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=OUTPUT, help="the side-by-side PNG to write")
    parser.add_argument("--width", type=int, default=SIZE[0], help="each image's width")
    parser.add_argument("--height", type=int, default=SIZE[1], help="each image's height")
    parser.add_argument("--cycles-samples", type=int, default=CYCLES_SAMPLES)
    args = parser.parse_args(argv)
    from .blender import quiet_output

    out = os.path.abspath(args.out)
    scale.start_blender(os.path.dirname(out))
    with quiet_output():
        build(args.width, args.height, args.cycles_samples)
        rendered = render_both()
        images = rendered["images"]
        scale._save_side_by_side(out, images["GLINT"], images["CYCLES"])
    print(json.dumps({"picture": out, "seconds": rendered["seconds"],
                      "cycles_samples": args.cycles_samples,
                      "similarity": scale.similarity(images["GLINT"], images["CYCLES"])}),
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
