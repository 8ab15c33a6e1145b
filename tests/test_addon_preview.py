"""Material, light and world previews.

Headless Blender renders no previews (``ID.preview_ensure()`` returns an empty 0 x 0 preview
and the preview job never runs without a window), so the engine's preview path is tested on
a scene built like Blender's preview scene (``release/datafiles/preview.blend``: a sphere
mesh named ``preview_*`` carrying the user's material, a checker ``Floor`` plane, two area
lights, a camera): ``prepare_preview_job``, which ``GlintRenderEngine.render`` uses when
``is_preview`` is set.
"""

from __future__ import annotations

import bpy
import numpy as np

from addon_support import (add_camera, add_point_light, add_sphere, cube_mesh, depsgraph,
                           empty_file, link, prepare_job)
from glint.addon.engine.base import GlintRenderEngine
from glint.addon.engine.preview import prepare_preview_job


def preview_like_scene(material=None):
    """material: a callable making the preview sphere's material (after the file is reset)."""
    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = 96, 96
    scene.glint.anti_aliasing = 'ADAPTIVE'
    # A finely tessellated sphere, like preview.blend's: the exporter draws it as a sphere
    # (a 32 x 16 one would be drawn as its triangles at this size: see export/geometry.py).
    add_sphere("preview_sphere", (0.0, 0.0, 0.0), 1.0,
               material=material() if material else None, segments=64, rings=32)
    floor = link(bpy.data.objects.new("Floor", cube_mesh("Floor", 20.0)))
    floor.scale.z = 0.01
    floor.location.z = -1.0
    for name, location in (("Light", (-10.0, -15.0, 10.0)), ("Light.001", (20, -30, 12))):
        data = bpy.data.lights.new(name, type='AREA')
        link(bpy.data.objects.new(name, data)).location = location
    add_camera(location=(0.0, -5.0, 0.0))
    return scene


def red_material():
    material = bpy.data.materials.new("red")
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
        0.8, 0.05, 0.05, 1.0)
    return material


def test_a_material_preview_is_lit_and_says_nothing():
    preview_like_scene(red_material)
    graph = depsgraph()
    # A normal render has the preview scene's two area lights (and the floor, a mesh).
    assert len(prepare_job(graph).scene.lights) == 2

    job = prepare_preview_job(graph)

    assert job.warnings == []
    assert [light.name for light in job.scene.lights] == ["Glint preview light"]
    assert [sphere.name for sphere in job.scene.spheres] == ["preview_sphere"]
    result = job.run(passes=True)
    image = result.image
    sphere = result.passes.primitive == 0   # the preview sphere, the scene's first primitive
    # The sphere shows the user's red, lit from the upper left: its upper-left quarter is
    # brighter than its lower-right one (shadow side, ambient and the floor's reflection).
    rows, cols = np.nonzero(sphere)
    cy, cx = rows.mean(), cols.mean()
    y, x = np.mgrid[:sphere.shape[0], :sphere.shape[1]]
    red = image[..., 0]
    upper_left = red[sphere & (y < cy) & (x < cx)].mean()
    lower_right = red[sphere & (y > cy) & (x > cx)].mean()
    assert sphere[48, 48]
    assert image[sphere, 0].mean() > 2 * image[sphere, 1].mean()
    assert upper_left > lower_right + 0.15


def test_a_point_light_being_previewed_is_the_light():
    preview_like_scene()
    add_point_light("previewed", (2.0, -3.0, 2.0), energy=500.0)

    job = prepare_preview_job(depsgraph())

    assert [light.name for light in job.scene.lights] == ["previewed"]


def test_the_engine_uses_the_preview_path_for_previews(monkeypatch):
    from types import SimpleNamespace

    from glint.addon.engine import base

    assert GlintRenderEngine.bl_use_preview is True
    calls = []
    monkeypatch.setattr(base, "render_preview", lambda engine, graph: calls.append("preview"))
    monkeypatch.setattr(base, "render_final", lambda engine, graph: calls.append("final"))
    for is_preview in (True, False):
        GlintRenderEngine.render(SimpleNamespace(is_preview=is_preview), None)
    assert calls == ["preview", "final"]
