"""The article's scene built in Blender, in the article's own coordinates.

The article is Y-up with its eye at (0, 0, 1) looking down -Z.  A Blender camera at (0, 0, 1)
with no rotation also looks down -Z with +Y up, so nothing is rotated: every number is the
article's.  The article's screen spans [-1, 1] horizontally at distance 1 from the eye, so the
camera fits horizontally with sensor_width / lens = 2 (36 mm sensor, 18 mm lens); its pixel
centres are Blender's ((i + 0.5) / W), not the article's linspace, a sub-pixel difference.

Spheres are UV spheres (64 x 32 segments by default) whose vertices lie on the article's
radii, marked ``glint_analytic_sphere`` so that the exporter turns them back into the
article's analytic spheres at any resolution; materials carry the
article's five values in their Glint section, and a matching Principled base colour and
viewport colour so Workbench and Cycles show the same objects.  Requires the add-on to be
registered (for ``Scene.glint`` and ``Material.glint``).
"""

from __future__ import annotations

import bpy
import bmesh  # after bpy: the pip module makes bmesh importable

from ...core.article import ARTICLE_EYE, ARTICLE_HEIGHT, ARTICLE_LIGHT, ARTICLE_WIDTH
from ...core.article import ARTICLE_MAX_DEPTH, article_spheres
from ..compat import new_material, new_world
from ..export.geometry import ANALYTIC_SPHERE_PROPERTY
from .colour import srgb_to_linear

SEGMENTS, RINGS = 64, 32
#: Lens and sensor giving sensor_width / lens = 2: the article's screen [-1, 1] at distance 1.
LENS_MM, SENSOR_WIDTH_MM = 18.0, 36.0


def _uv_sphere_mesh(name: str, radius: float, segments: int, rings: int):
    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    try:
        bmesh.ops.create_uvsphere(builder, u_segments=segments, v_segments=rings, radius=radius)
        builder.to_mesh(mesh)
    finally:
        builder.free()
    mesh.shade_smooth()
    return mesh


def _article_material(name: str, material):
    blender_material = new_material(name)
    linear = tuple(float(c) for c in srgb_to_linear(material.diffuse))
    blender_material.diffuse_color = (*linear, 1.0)
    principled = blender_material.node_tree.nodes.get("Principled BSDF")
    if principled is not None:
        principled.inputs["Base Color"].default_value = (*linear, 1.0)
    custom = blender_material.glint
    custom.use_custom = True
    custom.ambient = material.ambient
    custom.diffuse = material.diffuse
    custom.specular = material.specular
    custom.shininess = material.shininess
    custom.reflection = material.reflection
    return blender_material


def build_article_scene(name: str = "Glint article", *, width: int = ARTICLE_WIDTH,
                        height: int = ARTICLE_HEIGHT, segments: int = SEGMENTS,
                        rings: int = RINGS, engine: str = "GLINT"):
    """A new Scene holding the article's spheres, light, camera and black world; returns it.

    Existing data is left alone.  Render settings: width x height at 100 %, view transform
    Standard and no dither (so Blender shows and saves the core's colours), the article's semantics, depth 3 and no
    anti-aliasing, and ``engine`` as the render engine.
    """
    scene = bpy.data.scenes.new(name)
    scene.render.engine = engine
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.film_transparent = False
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    # Blender dithers 8-bit output by default; the article's image has no noise.
    scene.render.dither_intensity = 0.0
    scene.glint.semantics = 'ARTICLE'
    scene.glint.max_depth = ARTICLE_MAX_DEPTH
    scene.glint.anti_aliasing = 'OFF'
    scene.glint.precision = 'AUTO'

    world = new_world(f"{name} world")
    world.color = (0.0, 0.0, 0.0)
    background = world.node_tree.nodes.get("Background")
    if background is not None:
        background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world

    camera_data = bpy.data.cameras.new(f"{name} camera")
    camera_data.type = 'PERSP'
    camera_data.lens = LENS_MM
    camera_data.sensor_width = SENSOR_WIDTH_MM
    camera_data.sensor_fit = 'HORIZONTAL'
    # The article clips nothing: every sphere hit at t > 0 counts.
    camera_data.clip_start = 1e-3
    camera_data.clip_end = 1e5
    camera = bpy.data.objects.new(f"{name} camera", camera_data)
    camera.location = ARTICLE_EYE
    scene.collection.objects.link(camera)
    scene.camera = camera

    light_data = bpy.data.lights.new(f"{name} light", type='POINT')
    light_data.energy = 1000.0  # PointLight.from_power: 1000 W white is the article's light
    light_data.color = (1.0, 1.0, 1.0)
    light_data.shadow_soft_size = 0.0
    light = bpy.data.objects.new(f"{name} light", light_data)
    light.location = ARTICLE_LIGHT
    scene.collection.objects.link(light)

    for sphere in article_spheres():
        mesh = _uv_sphere_mesh(sphere.name, sphere.radius, segments, rings)
        mesh.materials.append(_article_material(sphere.name, sphere.material))
        obj = bpy.data.objects.new(sphere.name, mesh)
        obj.location = sphere.center
        # The article's spheres are spheres at any resolution (its floor, radius 9000 seen
        # from 0.7 away, is beyond any tessellation): see addon.export.geometry.
        obj[ANALYTIC_SPHERE_PROPERTY] = True
        scene.collection.objects.link(obj)
    return scene
