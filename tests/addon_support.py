"""Shared set-up for the add-on tests (headless pip bpy, one process).

The add-on is this checkout loaded as the package ``glint`` by render.py's ``import_glint`` (the
same way render.py runs it) and registered once per session.  Everything the add-on computes
uses ``glint.core``; the tests therefore use ``glint.core`` too, not the top-level ``core``
(a second copy of the same modules, whose classes would not be the add-on's).

Each test builds its own small scene with the helpers below (64 x 48 by default, so every
render takes milliseconds) in a freshly emptied file.
"""

from __future__ import annotations

import math
import os
import sys

import bpy
import bmesh  # after bpy: the pip module makes bmesh importable
import numpy as np

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RENDER_SCRIPT = os.path.join(REPOSITORY, "render.py")
if REPOSITORY not in sys.path:
    sys.path.insert(0, REPOSITORY)

import render as render_script  # noqa: E402  (render.py, the command-line entry point)

glint = render_script.import_glint()
render_script.register_glint(glint)

from glint import core  # noqa: E402
from glint.addon.compat import new_compositor, new_material, new_world  # noqa: E402
from glint.addon.engine.job import prepare_job  # noqa: E402
from glint.addon.export import ExportError, export_scene  # noqa: E402
from glint.addon.utils.image import read_image  # noqa: E402
from glint.core.png import to_rgba8  # noqa: E402

WIDTH, HEIGHT = 64, 48


def empty_file():
    """Start from an empty file (no objects, one scene), with the add-on still registered."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.render.dither_intensity = 0.0  # Blender dithers 8-bit output by default
    scene.glint.anti_aliasing = 'OFF'
    # The renderer's own image: OIDN's output is not what a test of the renderer compares
    # (it moves a flat grey frame's border pixels by up to a quarter).  The tests of
    # denoising turn it back on.
    scene.glint.use_denoising = False
    return scene


def link(obj, scene=None):
    (scene or bpy.context.scene).collection.objects.link(obj)
    return obj


def uv_sphere_mesh(name="sphere", radius=1.0, segments=32, rings=16, smooth=True):
    """A UV sphere mesh, smooth-shaded by default (flat facets show as soon as they cover a
    pixel, which makes the exporter draw the triangles)."""
    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    bmesh.ops.create_uvsphere(builder, u_segments=segments, v_segments=rings, radius=radius)
    builder.to_mesh(mesh)
    builder.free()
    if smooth:
        mesh.shade_smooth()
    return mesh


def ico_sphere_mesh(name="ico", radius=1.0, subdivisions=2, smooth=True):
    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    bmesh.ops.create_icosphere(builder, subdivisions=subdivisions, radius=radius)
    builder.to_mesh(mesh)
    builder.free()
    if smooth:
        mesh.shade_smooth()
    return mesh


def cube_mesh(name="cube", size=2.0):
    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    bmesh.ops.create_cube(builder, size=size)
    builder.to_mesh(mesh)
    builder.free()
    return mesh


def add_sphere(name="sphere", location=(0.0, 0.0, 0.0), radius=1.0, material=None, **mesh_args):
    obj = link(bpy.data.objects.new(name, uv_sphere_mesh(name, radius, **mesh_args)))
    obj.location = location
    if material is not None:
        obj.data.materials.append(material)
    return obj


def add_point_light(name="light", location=(5.0, 5.0, 5.0), energy=1000.0, radius=0.0,
                    colour=(1.0, 1.0, 1.0)):
    data = bpy.data.lights.new(name, type='POINT')
    data.energy = energy
    data.shadow_soft_size = radius
    data.color = colour
    obj = link(bpy.data.objects.new(name, data))
    obj.location = location
    return obj


def add_camera(name="camera", location=(0.0, -6.0, 0.0), rotation=(math.pi / 2, 0.0, 0.0),
               lens=50.0):
    """A camera (default: on -Y looking at the origin along +Y, Z up) made the scene camera."""
    data = bpy.data.cameras.new(name)
    data.lens = lens
    obj = link(bpy.data.objects.new(name, data))
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.camera = obj
    return obj


def add_world(name, colour, strength=None):
    """A world whose Background node has ``colour`` (RGB) and, if given, ``strength``, made
    the scene's world."""
    world = new_world(name)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*colour, 1.0)
    if strength is not None:
        background.inputs["Strength"].default_value = strength
    bpy.context.scene.world = world
    return world


def animate_small_sphere(last_frame):
    """Keys ``simple_scene``'s small sphere from x = -1 at frame 1 to x = 1 at last_frame."""
    small = bpy.data.objects["small"]
    small.location.x = -1.0
    small.keyframe_insert("location", frame=1)
    small.location.x = 1.0
    small.keyframe_insert("location", frame=last_frame)
    return small


def invert_compositor(scene, layer="ViewLayer"):
    """Compositing that shows ``layer`` inverted."""
    tree, image = new_compositor(scene, "Invert")
    render_layers = tree.nodes.new("CompositorNodeRLayers")
    render_layers.layer = layer
    invert = tree.nodes.new("CompositorNodeInvert")
    tree.links.new(render_layers.outputs["Image"], invert.inputs["Color"])
    tree.links.new(invert.outputs["Color"], image)
    scene.render.use_compositing = True
    # On the CPU, as Blender before 5.3 composites by default: 5.3 chooses the GPU, and where
    # there is none (CI) Blender prints EGL errors on stderr, which render.py cannot silence.
    scene.render.compositor_device = 'CPU'
    return tree


def camera_and_light_file():
    """An empty file holding only the default ``add_camera`` and ``add_point_light``."""
    scene = empty_file()
    add_camera()
    add_point_light()
    return scene


def simple_scene():
    """Two spheres, a point light and a camera looking at them: a small but full scene.  The
    spheres are fine enough (64 x 32) to be drawn as analytic spheres in any view of it."""
    scene = empty_file()
    add_sphere("big", (0.0, 0.0, 0.0), 1.0, segments=64, rings=32)
    add_sphere("small", (1.2, -0.8, 0.6), 0.3, segments=64, rings=32)
    add_point_light()
    add_camera()
    return scene


def depsgraph():
    # (Setting a property of scene.glint from Python does not tag the scene: without the
    # tag its evaluated copy keeps the settings of the last evaluation.)
    bpy.context.scene.update_tag()
    graph = bpy.context.evaluated_depsgraph_get()
    graph.update()
    return graph


def core_image(graph=None) -> np.ndarray:
    """The core's own render of the exported scene, as the add-on would finish it."""
    job = prepare_job(graph or depsgraph())
    return job.run().image


def read_png(path: str) -> np.ndarray:
    """(H, W, 4) uint8, row 0 = top, of any PNG Blender can read (loaded as data, so no
    colour conversion happens)."""
    image = bpy.data.images.load(path, check_existing=False)
    try:
        image.colorspace_settings.name = 'Non-Color'
        return np.round(read_image(image) * 255).astype(np.uint8)
    finally:
        bpy.data.images.remove(image)
