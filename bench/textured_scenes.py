"""Three textured scenes as .blend files, made the way a Blender user makes them, for the
speed-vs-error comparison with Cycles.

    .venv/bin/python -m bench.textured_scenes --out DIR

writes DIR/textured_product.blend, DIR/textured_procedural.blend and
DIR/textured_normal_map.blend (nothing is downloaded; every image is made here or taken from
the bpy wheel, and packed into the file):

- product: a bevelled cube and a UV sphere, each UV-mapped with an Image Texture (a checker
  with a label band, made with NumPy and packed as a PNG), on a grey floor, lit only by
  Blender's own studio-light HDRI ``studio.exr`` (CC0, shipped in the wheel's datafiles,
  packed) through an Environment Texture turned by a Mapping node;
- procedural: a ball whose Base Color is a Noise texture through a Color Ramp, whose Normal is
  a Voronoi distance through a Bump node and whose Roughness is a Math (Multiply Add) of the
  noise, on a floor under a sun and an area light;
- normal_map: a floor whose Normal is a tangent-space normal image (made with NumPy, packed,
  Non-Color) through a Normal Map node on its UV map, with a metallic ball, under a point
  light and a constant world colour.

Each file has a camera, 480 x 270 pixels, Cycles' settings at their defaults and Glint (at
its defaults) as the render engine; ``../shared/tools/speed_vs_error.py FILE`` renders each
against Cycles.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

from . import scale
from .blender_scenes import principled_material

SIZE = (480, 270)
#: Blender's studio light used by the product shot (a soft studio with a bright softbox).
STUDIO_HDRI = "studio.exr"


def _new_file():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.engine = 'GLINT'
    return scene


def _look_at(obj, target) -> None:
    """Point ``obj``'s -Z axis (a camera's or a light's) at ``target``, Y up."""
    from mathutils import Vector

    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()


def _camera(location, target, lens: float = 50.0):
    import bpy

    camera = scale._link(bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera")))
    camera.location = location
    camera.data.lens = lens
    _look_at(camera, target)
    bpy.context.scene.camera = camera
    return camera


def _floor(material, size: float = 20.0):
    import bpy

    bpy.ops.mesh.primitive_plane_add(size=size, location=(0.0, 0.0, 0.0))
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(material)
    return floor


def _uv_sphere(name: str, location, radius: float, material):
    import bpy

    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=radius,
                                         location=location)
    ball = bpy.context.object
    ball.name = name
    bpy.ops.object.shade_smooth()
    ball.data.materials.append(material)
    return ball


def _packed_image(name: str, rgb: np.ndarray, non_colour: bool = False):
    """A Blender image holding ``rgb`` ((H, W, 3) in 0..1, row 0 = top), packed into the file
    as a PNG."""
    import bpy

    height, width = rgb.shape[:2]
    image = bpy.data.images.new(name, width, height, alpha=False)
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = rgb[::-1]   # Blender's rows run from the bottom up
    image.pixels.foreach_set(rgba.ravel())
    image.file_format = 'PNG'
    image.pack()
    if non_colour:
        image.colorspace_settings.name = 'Non-Color'
    return image


def label_checker(size: int = 512) -> np.ndarray:
    """(size, size, 3): an 8 x 8 checker of orange and cream with a dark band across the
    middle holding a row of light dots, like a product's label."""
    rows, columns = np.mgrid[0:size, 0:size] / size
    checker = ((np.floor(rows * 8) + np.floor(columns * 8)) % 2)[..., None]
    rgb = checker * np.array([0.95, 0.45, 0.1]) + (1 - checker) * np.array([0.95, 0.9, 0.8])
    band = np.abs(rows - 0.5) < 0.12
    rgb[band] = (0.08, 0.12, 0.3)
    dots = band & (np.hypot((columns * 8) % 1 - 0.5, (rows - 0.5) * 8) < 0.3)
    rgb[dots] = (0.9, 0.9, 0.95)
    return rgb


def tile_normal_map(size: int = 256, tiles: int = 4, bevel: float = 0.12,
                    relief: float = 0.1) -> np.ndarray:
    """(size, size, 3): a tangent-space normal image (0.5 + n / 2) of ``tiles`` x ``tiles``
    raised tiles whose edges rise by ``relief`` over ``bevel`` (both in tiles) from the
    grout."""
    u = (np.arange(size) + 0.5) / size * tiles % 1.0
    edge = np.minimum(u, 1 - u)   # distance to the nearest grout line, in tiles
    height_1d = relief * np.clip(edge / bevel, 0.0, 1.0)
    slope_1d = np.gradient(height_1d) * size / tiles   # height per tile along the axis
    # Columns run along u; rows along v from the top (v = 1) down.
    height_u, height_v = np.meshgrid(height_1d, height_1d[::-1])
    slope_u, slope_v = np.meshgrid(slope_1d, slope_1d[::-1])
    # A tile is raised where both directions are, so its height is the smaller of the two.
    du = np.where(height_u <= height_v, slope_u, 0.0)
    dv = np.where(height_v < height_u, slope_v, 0.0)
    normal = np.stack([-du, -dv, np.ones_like(du)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return 0.5 + 0.5 * normal


def _link_nodes(tree, pairs) -> None:
    for output, input_ in pairs:
        tree.links.new(output, input_)


def product_shot():
    """A bevelled cube and a UV sphere with an Image Texture, on a floor, lit by an HDRI."""
    import bpy

    scene = _new_file()
    label = _packed_image("label", label_checker())
    material = bpy.data.materials.new("Label")
    nodes, tree = material.node_tree.nodes, material.node_tree
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = label
    principled = nodes["Principled BSDF"]
    principled.inputs["Roughness"].default_value = 0.35
    tree.links.new(texture.outputs["Color"], principled.inputs["Base Color"])

    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-0.75, 0.0, 0.6),
                                    rotation=(0.0, 0.0, math.radians(25.0)))
    cube = bpy.context.object
    cube.name = "Box"
    bevel = cube.modifiers.new("Bevel", 'BEVEL')
    bevel.width, bevel.segments, bevel.harden_normals = 0.08, 4, True
    bpy.ops.object.shade_smooth()
    cube.data.materials.append(material)
    _uv_sphere("Ball", (0.85, 0.2, 0.5), 0.5, material)
    _floor(principled_material("Floor", (0.6, 0.6, 0.6), 0.5))

    world = bpy.data.worlds.new("Studio")
    scene.world = world
    wnodes = world.node_tree.nodes
    environment = wnodes.new("ShaderNodeTexEnvironment")
    path = os.path.join(bpy.utils.system_resource('DATAFILES', path="studiolights/world"),
                        STUDIO_HDRI)
    environment.image = bpy.data.images.load(path)
    environment.image.pack()
    mapping = wnodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(120.0))
    coordinates = wnodes.new("ShaderNodeTexCoord")
    _link_nodes(world.node_tree, [
        (coordinates.outputs["Generated"], mapping.inputs["Vector"]),
        (mapping.outputs["Vector"], environment.inputs["Vector"]),
        (environment.outputs["Color"], wnodes["Background"].inputs["Color"])])
    _camera((0.0, -4.6, 2.2), (0.0, 0.0, 0.45), lens=45.0)
    return scene


def procedural_ball():
    """A ball with a Noise / Color Ramp colour, Voronoi bump and Math roughness, on a floor
    under a sun and an area light."""
    import bpy

    scene = _new_file()
    material = bpy.data.materials.new("Procedural")
    tree = material.node_tree
    nodes = tree.nodes
    principled = nodes["Principled BSDF"]
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    noise.inputs["Detail"].default_value = 6.0
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[1].position = 0.4, 0.6
    ramp.color_ramp.elements[0].color = (0.05, 0.2, 0.5, 1.0)
    ramp.color_ramp.elements[1].color = (0.9, 0.6, 0.15, 1.0)
    roughness = nodes.new("ShaderNodeMath")
    roughness.operation = 'MULTIPLY_ADD'
    roughness.inputs[1].default_value = 0.75   # noise 0.3..0.7 -> roughness 0.1..0.4
    roughness.inputs[2].default_value = -0.12
    voronoi = nodes.new("ShaderNodeTexVoronoi")
    voronoi.inputs["Scale"].default_value = 8.0
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 1.0
    bump.inputs["Distance"].default_value = 0.05   # the node's default (0.001) hardly shows
    _link_nodes(tree, [
        (noise.outputs["Fac"], ramp.inputs["Fac"]),
        (ramp.outputs["Color"], principled.inputs["Base Color"]),
        (noise.outputs["Fac"], roughness.inputs[0]),
        (roughness.outputs["Value"], principled.inputs["Roughness"]),
        (voronoi.outputs["Distance"], bump.inputs["Height"]),
        (bump.outputs["Normal"], principled.inputs["Normal"])])
    _uv_sphere("Ball", (0.0, 0.0, 1.0), 1.0, material)
    _floor(principled_material("Floor", (0.5, 0.5, 0.5), 0.6))

    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = 3.0
    sun.angle = math.radians(3.0)
    scale._link(bpy.data.objects.new("Sun", sun)).rotation_euler = (
        math.radians(45.0), 0.0, math.radians(30.0))
    area = bpy.data.lights.new("Area", 'AREA')
    area.energy = 400.0
    area.size = 2.0
    area.color = (0.7, 0.8, 1.0)
    area_object = scale._link(bpy.data.objects.new("Area", area))
    area_object.location = (-3.0, -2.0, 3.0)
    _look_at(area_object, (0.0, 0.0, 0.8))
    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.06, 1.0)
    scene.world = world
    _camera((0.0, -5.5, 2.4), (0.0, 0.0, 0.9), lens=50.0)
    return scene


def normal_mapped_floor():
    """A tiled floor by a normal image through a Normal Map node, a metallic ball, a point
    light and a world colour."""
    import bpy

    scene = _new_file()
    tiles = _packed_image("tiles_normal", tile_normal_map(), non_colour=True)
    material = bpy.data.materials.new("Tiles")
    tree = material.node_tree
    nodes = tree.nodes
    principled = nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.55, 0.5, 0.45, 1.0)
    principled.inputs["Roughness"].default_value = 0.3
    coordinates = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (3.0, 3.0, 1.0)   # 12 x 12 tiles on the floor
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = tiles
    normal_map = nodes.new("ShaderNodeNormalMap")   # tangent space, the active UV map
    _link_nodes(tree, [
        (coordinates.outputs["UV"], mapping.inputs["Vector"]),
        (mapping.outputs["Vector"], texture.inputs["Vector"]),
        (texture.outputs["Color"], normal_map.inputs["Color"]),
        (normal_map.outputs["Normal"], principled.inputs["Normal"])])
    _floor(material, size=8.0)
    _uv_sphere("Ball", (0.0, 0.4, 0.8), 0.8, principled_material("Chrome", (0.9, 0.9, 0.9), 0.15, 1.0))

    point = bpy.data.lights.new("Point", 'POINT')
    point.energy = 600.0
    point.shadow_soft_size = 0.3
    scale._link(bpy.data.objects.new("Point", point)).location = (2.0, -1.5, 3.0)
    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.25, 0.35, 1.0)
    scene.world = world
    _camera((0.0, -5.0, 2.0), (0.0, 0.3, 0.3), lens=40.0)
    return scene


SCENES = {"textured_product": product_shot,
          "textured_procedural": procedural_ball,
          "textured_normal_map": normal_mapped_floor}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.textured_scenes",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True, help="the folder to write the .blend files to")
    args = parser.parse_args(argv)
    import bpy

    from .blender import quiet_output

    out = os.path.abspath(args.out)
    scale.start_blender(out)
    for name, build in SCENES.items():
        path = os.path.join(out, name + ".blend")
        with quiet_output():
            build()
            bpy.ops.wm.save_as_mainfile(filepath=path)
        print(path, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
