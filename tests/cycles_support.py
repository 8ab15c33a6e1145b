"""Rendering one small scene with Glint and with Cycles, and comparing them on the surface.

Both renderers see the same Blender scene: Glint through its exporter and core (the job's
scene-linear radiance, what Blender's render result holds), Cycles on the CPU with a
near-zero pixel filter (so that each pixel is sampled near its centre, as Glint's
anti-aliasing-off render is), no denoising, and direct light only unless a test asks for
bounces.  The result is read from an OpenEXR file, so it is scene-linear and unclipped too.

``surface_ratios`` compares the two on the pixels both see as one object's surface, away from
its silhouette (where Cycles' faceted UV sphere and Glint's analytic one disagree by up to
one pixel) and from its shading terminator (where interpolated mesh normals differ most):
per colour channel, the ratio of the mean radiance Glint gives to the mean Cycles gives.
"""

from __future__ import annotations

import math
import os
import tempfile

import bpy
import numpy as np

from addon_support import add_camera, core_image, empty_file, link, uv_sphere_mesh
from glint.addon.compat import new_material, new_world  # noqa: E402

WIDTH, HEIGHT = 48, 36


def cycles_scene(bounces: int = 0, samples: int = 32):
    """An empty file set up for both renderers (Standard view, no world light)."""
    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    cycles = scene.cycles
    cycles.device = 'CPU'
    cycles.samples = samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = bounces
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "transparent_max_bounces", "volume_bounces"):
        setattr(cycles, name, bounces)
    cycles.filter_width = 0.01
    cycles.seed = 1
    scene.glint.max_depth = max(1, bounces + 1)
    # Glint's path tracer with enough samples and neither denoising nor adaptive stopping,
    # so that what remains between the two is the models' difference, not noise.
    scene.glint.samples = 64
    scene.glint.use_adaptive_sampling = False
    scene.glint.use_denoising = False
    world = new_world("black")
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    add_camera(location=(0.0, -8.0, 0.0), lens=50.0)
    return scene


def set_world(colour, strength: float):
    background = bpy.context.scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*colour, 1.0)
    background.inputs["Strength"].default_value = strength


def node_material(name: str, kind: str, **inputs):
    """A material whose output's Surface is one shader node of ``kind`` with ``inputs``."""
    material = new_material(name)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = (*value, 1.0) if isinstance(value, tuple) else value
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def diffuse(name: str, colour):
    return node_material(name, "ShaderNodeBsdfDiffuse", Color=colour)


def add_ball(name: str, location, radius: float, material):
    mesh = uv_sphere_mesh(name, radius, segments=96, rings=48)
    mesh.shade_smooth()
    mesh.materials.append(material)
    obj = link(bpy.data.objects.new(name, mesh))
    obj.location = location
    return obj


def add_plane(name: str, centre, size: float, material, angle: float = 0.0):
    """A vertical square of ``material`` facing -Y (the camera), turned ``angle`` radians
    about Z: at pi / 4 it faces (1, -1, 0)."""
    mesh = bpy.data.meshes.new(name)
    h = size / 2
    mesh.from_pydata([(-h, 0, -h), (h, 0, -h), (h, 0, h), (-h, 0, h)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = link(bpy.data.objects.new(name, mesh))
    obj.location, obj.rotation_euler = centre, (0.0, 0.0, angle)
    return obj


def add_light(kind: str, location, rotation=(0.0, 0.0, 0.0), **settings):
    data = bpy.data.lights.new(kind.lower(), kind)
    for key, value in settings.items():
        setattr(data, key, value)
    obj = link(bpy.data.objects.new(kind.lower(), data))
    obj.location = location
    obj.rotation_euler = rotation
    return obj


def aim(obj, target):
    """Point an object's -Z (a light's direction) at ``target``."""
    from mathutils import Vector

    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()


#: Where Cycles' references are kept between runs, per Blender version (a fresh clone, as CI
#: has, renders them all).  GLINT_CYCLES_CACHE overrides it; "off" renders every time.
CACHE_VARIABLE = "GLINT_CYCLES_CACHE"
_calls: dict = {}


def _cache_path():
    """The file a reference of the running test's next render is cached in, or None: keyed
    by the test's id, its render's number within the test, the sources of the test file and
    of this module (an edit to either renders anew) and the render's size and samples."""
    import hashlib

    root = os.environ.get(CACHE_VARIABLE, os.path.join(os.path.expanduser("~"), ".cache",
                                                       "glint", "cycles-references"))
    current = os.environ.get("PYTEST_CURRENT_TEST")
    if root == "off" or not current:
        return None
    test_id = current.rsplit(" ", 1)[0]
    count = _calls[test_id] = _calls.get(test_id, 0) + 1
    digest = hashlib.sha1(f"{test_id} {count}".encode())
    test_file = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                             test_id.split("::")[0])
    for path in (__file__, test_file):
        if path and os.path.exists(path):
            with open(path, "rb") as source:
                digest.update(source.read())
    scene = bpy.context.scene
    digest.update(f"{scene.render.resolution_x} {scene.render.resolution_y} "
                  f"{scene.cycles.samples}".encode())
    folder = os.path.join(root, bpy.app.version_string.replace(" ", "_"))
    return os.path.join(folder, digest.hexdigest() + ".npy")


def render_cycles() -> np.ndarray:
    """(H, W, 4) float32 scene-linear Cycles render, row 0 = top (cached: ``_cache_path``)."""
    cached = _cache_path()
    if cached is not None and os.path.exists(cached):
        image = np.load(cached)
        if image.shape == (HEIGHT, WIDTH, 4):
            return image
    image = _render_cycles()
    if cached is not None:
        os.makedirs(os.path.dirname(cached), exist_ok=True)
        np.save(cached + ".tmp.npy", image)
        os.replace(cached + ".tmp.npy", cached)
    return image


def _render_cycles() -> np.ndarray:
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    settings = scene.render.image_settings
    settings.file_format = 'OPEN_EXR'
    settings.color_depth = '32'
    with tempfile.TemporaryDirectory() as folder:
        scene.render.filepath = os.path.join(folder, "cycles.exr")
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(scene.render.filepath)
        try:
            pixels = np.empty(WIDTH * HEIGHT * 4, np.float32)
            image.pixels.foreach_get(pixels)
        finally:
            bpy.data.images.remove(image)
    scene.render.engine = 'GLINT'
    return pixels.reshape(HEIGHT, WIDTH, 4)[::-1].copy()


def render_both():
    """(glint, cycles) (H, W, 4) scene-linear renders of the current scene."""
    bpy.context.scene.render.engine = 'GLINT'
    glint = core_image()
    return glint, render_cycles()


def sphere_mask(obj, erode: int = 2) -> np.ndarray:
    """(H, W) bool: pixels whose centre sees ``obj``'s analytic sphere, ``erode`` pixels in
    from its silhouette (projected with Blender's own camera matrices)."""
    from bpy_extras.object_utils import world_to_camera_view

    scene = bpy.context.scene
    camera = scene.camera
    centre = obj.matrix_world.translation
    radius = max(obj.dimensions) / 2
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH]
    view = world_to_camera_view(scene, camera, centre)
    # Pixel radius of the sphere's silhouette, from a point at its edge seen sideways.
    to_camera = (camera.matrix_world.translation - centre).normalized()
    side = to_camera.cross((0.0, 0.0, 1.0)).normalized()
    distance = (camera.matrix_world.translation - centre).length
    edge = centre + side * radius * distance / math.sqrt(distance ** 2 - radius ** 2)
    edge_view = world_to_camera_view(scene, camera, edge)
    px, py = view.x * WIDTH, (1 - view.y) * HEIGHT
    pr = math.hypot((edge_view.x - view.x) * WIDTH, (edge_view.y - view.y) * HEIGHT)
    return np.hypot(xs + 0.5 - px, ys + 0.5 - py) < pr - erode


def lit_pixels(cycles, mask, floor: float = 0.05):
    """``mask``'s pixels whose Cycles radiance exceeds ``floor`` x the brightest of them (the
    lit surface, away from the terminator); floor 0 keeps them all."""
    brightness = cycles[..., :3].max(axis=2)
    chosen = mask & (brightness > floor * brightness[mask].max())
    assert chosen.sum() >= 20, f"only {chosen.sum()} pixels to compare"
    return chosen


def surface_ratios(glint, cycles, mask, floor: float = 0.05):
    """(3,) mean Glint radiance / mean Cycles radiance per channel over ``lit_pixels``."""
    chosen = lit_pixels(cycles, mask, floor)
    return glint[chosen, :3].mean(axis=0) / cycles[chosen, :3].mean(axis=0)


def pixel_errors(glint, cycles, mask, floor: float = 0.05):
    """(k,) |Glint / Cycles - 1| of each of ``lit_pixels``' summed RGB."""
    chosen = lit_pixels(cycles, mask, floor)
    return np.abs(glint[chosen, :3].sum(axis=1) / cycles[chosen, :3].sum(axis=1) - 1)
