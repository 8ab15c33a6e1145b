"""A Blender user's usual scene rendered by Glint: every object in it, each where Blender
draws it, and meshes with several materials shaded per slot.

Coverage is compared with Workbench (no anti-aliasing, transparent film) object by object:
each object is rendered alone (the others hidden for render) by both, and the masks must
agree except within ``EDGE_TOLERANCE_PIXELS`` of a projected triangle edge, or in the band of
an analytic sphere (``blender_scenes``).
"""

from __future__ import annotations

import bpy
import numpy as np

from addon_support import core_image, depsgraph, export_scene, link
from glint.addon.compat import new_material  # noqa: E402
from blender_scenes import blender_mask, configure_renderers, glint_masks, silhouette_check

WIDTH, HEIGHT = 96, 54


def default_scene_with_sphere_and_floor():
    """Blender's startup scene (cube, light, camera), plus a UV sphere and a floor plane added
    as a user would, through the Add menu's operators."""
    bpy.ops.wm.read_factory_settings(use_empty=False)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    configure_renderers(scene)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(0.5, 2.5, 0.0))
    bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 0.0, -1.0))
    return scene


def test_the_default_scene_with_a_sphere_and_a_floor_renders_every_object(tmp_path):
    scene = default_scene_with_sphere_and_floor()
    names = ["Cube", "Sphere", "Plane"]

    exported, warnings = export_scene(depsgraph())
    drawn = [m.name for m in exported.meshes] + [s.name for s in exported.spheres]
    assert sorted(drawn) == sorted(names)
    assert not [w for w in warnings if "skipped" in w]

    for name in names:
        for other in names:
            bpy.data.objects[other].hide_render = other != name
        alone, _ = export_scene(depsgraph())
        glint = glint_masks(alone)
        reference = blender_mask(scene, 'BLENDER_WORKBENCH', tmp_path)
        assert 0 < reference.sum() < reference.size, f"{name}: Workbench drew nothing"
        check = silhouette_check(glint, reference)
        assert check.outside_band == 0, f"{name}: {check.describe()}"


def test_a_multi_material_mesh_shades_each_face_with_its_slot(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 32
    scene.render.resolution_percentage = 100
    mesh = bpy.data.meshes.new("halves")
    mesh.from_pydata([(-2, -1, 0), (0, -1, 0), (2, -1, 0), (2, 1, 0), (0, 1, 0), (-2, 1, 0)],
                     [], [(0, 1, 4, 5), (1, 2, 3, 4)])
    for name, rgb in (("red", (0.8, 0.02, 0.02)), ("blue", (0.02, 0.02, 0.8))):
        material = new_material(name)
        material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = \
            (*rgb, 1.0)
        mesh.materials.append(material)
    mesh.polygons.foreach_set("material_index", [0, 1])
    link(bpy.data.objects.new("halves", mesh))
    light = link(bpy.data.objects.new("light", bpy.data.lights.new("light", 'POINT')))
    light.location = (0.0, 0.0, 3.0)
    camera = link(bpy.data.objects.new("camera", bpy.data.cameras.new("camera")))
    camera.location = (0.0, 0.0, 5.0)  # looking straight down at the two halves
    camera.data.type = 'ORTHO'
    camera.data.ortho_scale = 4.0
    scene.camera = camera

    image = core_image()

    left, right = image[:, :30, :3].mean(axis=(0, 1)), image[:, 34:, :3].mean(axis=(0, 1))
    assert left[0] > 2 * left[2], f"left half {left} is not red"
    assert right[2] > 2 * right[0], f"right half {right} is not blue"
