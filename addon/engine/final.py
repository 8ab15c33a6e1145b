"""Glint in Blender's engine list: F12, animation renders and ``blender -b file -f/-a``.

A thin layer over ``RenderJob``: progress through update_progress, cancel through test_break,
warnings through report, errors through report + error_set (so F12 shows the message and a
command-line render fails instead of writing an empty image).  Blender expects scene-linear
render results: the default semantics' radiance is handed over unchanged (so the user's view
transform, look, exposure and gamma apply to it), the article semantics' display values
through the inverse sRGB transfer function (``RenderJob.scene_linear``).  Render results have
row 0 at the bottom.
"""

from __future__ import annotations

from contextlib import contextmanager

import bpy
import numpy as np

from ...core import RenderCancelled, SceneError
from ..export import ExportError
from .job import prepare_job


#: Callables given (job, finished image) for every frame rendered (the job's image, row 0 =
#: top, see ``RenderJob.run``), for scripts that want the frame's numbers.
_image_listeners = []


@contextmanager
def captured_images():
    """``with captured_images() as images: bpy.ops.render.render(...)`` collects a
    (RenderJob, image) pair for each frame the Glint engine renders meanwhile (render.py
    writes its PNG from it)."""
    images = []

    def listener(job, image):
        images.append((job, image))

    _image_listeners.append(listener)
    try:
        yield images
    finally:
        _image_listeners.remove(listener)


class GlintRenderEngine(bpy.types.RenderEngine):
    bl_idname = "GLINT"
    bl_label = "Glint"
    bl_use_preview = False
    # The viewport's Material Preview and Rendered modes fall back to EEVEE: Glint has no
    # interactive renderer.
    bl_use_eevee_viewport = True
    # Glint reads the materials' shader nodes (``addon.export.materials``): the Shader Editor
    # must be available to edit them.
    bl_use_shading_nodes_custom = False

    def render(self, depsgraph):
        try:
            job = prepare_job(depsgraph, camera_override=self.camera_override)
        except (ExportError, SceneError) as error:
            self._fail(str(error))
            return
        for warning in job.warnings:
            self.report({'WARNING'}, warning)
        width, height = job.size
        if (width, height) != (self.resolution_x, self.resolution_y):
            self._fail(f"Glint exported a {width}x{height} frame but Blender renders "
                       f"{self.resolution_x}x{self.resolution_y}")
            return
        region = render_region(depsgraph.scene_eval.render, width, height)
        if region is None:
            self._fail("the render region (border) covers no whole pixel")
            return
        spheres, lights = len(job.scene.spheres), len(job.scene.lights)
        self.update_stats("Glint", f"{spheres} spheres, {lights} lights, {width}x{height}")
        try:
            image = job.run(progress=self.update_progress, should_cancel=self.test_break)
        except RenderCancelled:
            return
        except SceneError as error:
            self._fail(str(error))
            return
        self.update_stats("Glint", f"{spheres} spheres, {lights} lights, {width}x{height}, "
                                   f"{job.precision}")
        for listener in _image_listeners:
            listener(job, image)
        x0, y0, x1, y1 = region
        pixels = job.scene_linear(image)[::-1][y0:y1, x0:x1]
        # begin_result counts from the region's corner, not the frame's.
        result = self.begin_result(0, 0, x1 - x0, y1 - y0)
        result.layers[0].passes["Combined"].rect.foreach_set(np.ascontiguousarray(pixels).ravel())
        self.end_result(result)

    def _fail(self, message: str) -> None:
        self.report({'ERROR'}, message)
        self.error_set(message)


def render_region(render, width: int, height: int):
    """(x0, y0, x1, y1) of the pixels Blender's render result holds, rows counted from the
    bottom: the whole frame, or the render region ("border") as Blender's render pipeline
    computes it (float32 border fraction times size, truncated); None if that is empty.
    Glint traces the whole frame and hands Blender that part of it."""
    if not render.use_border:
        return 0, 0, width, height
    border = np.array([render.border_min_x, render.border_min_y, render.border_max_x,
                       render.border_max_y], np.float32)
    size = np.array([width, height, width, height], np.float32)
    x0, y0, x1, y1 = (int(value) for value in border * size)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def compatible_panels():
    """Blender's panels Glint's users need, as other engines choose them: every panel marked
    for all engines ('BLENDER_RENDER': output, format, colour management, camera, ...), minus
    what Glint does not use, plus the EEVEE panels that edit what Glint exports (material
    slots and surface, world surface, light colour/power/radius)."""
    excluded = {'DATA_PT_light'}  # a type-only light panel, superseded by DATA_PT_EEVEE_light
    included = {'EEVEE_MATERIAL_PT_context_material', 'EEVEE_MATERIAL_PT_surface',
                'EEVEE_WORLD_PT_surface', 'DATA_PT_EEVEE_light'}
    panels = []
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None:
            continue
        name = panel.__name__
        if name in included or ('BLENDER_RENDER' in engines and name not in excluded
                                and 'FREESTYLE' not in name.upper()):
            panels.append(panel)
    return panels


def register_panels():
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.add(GlintRenderEngine.bl_idname)


def unregister_panels():
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.discard(GlintRenderEngine.bl_idname)
