"""Glint in Blender's engine list: F12, animation renders and ``blender -b file -f/-a``.

A thin layer over ``RenderJob``: progress through update_progress, cancel through test_break,
warnings through report.  Whatever goes wrong (an export error, an invalid value, a
MemoryError in a tile, a bug) ends in one ERROR report naming it (``job.failure_message``) and
no render result: an ERROR report is what makes Blender treat the frame as failed, so
``render(write_still=True)``, F12 + save and ``blender -b -f/-a`` keep the previous file
instead of saving a blank frame, and an animation stops.  (Measured with bpy 5.0.1:
``error_set`` alone lets Blender save the empty frame, and with an ERROR report Blender repeats
its message as a second report; so ``error_set`` is used only with a window, where it shows
the message on the render view.)

Blender calls ``render`` once per view layer with that layer's depsgraph, so each layer is
exported with its own visibility and written to its own layer of the result
(``begin_result(layer=...)``); a multilayer EXR holds them all.

Blender expects scene-linear render results; the core's values are display values, so they
are handed over through the inverse sRGB transfer function, and with view transform Standard
Blender shows and saves the core's own numbers.  Render results have row 0 at the bottom.
The hand-over is done in place, a block of rows at a time, so a frame costs one float32 image
besides Blender's own buffer.

Scripts that want the core's numbers rather than Blender's colour-managed result (render.py)
ask for them explicitly with ``FrameRequest`` (below).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Optional

import bpy
import numpy as np

from ...core import RenderCancelled
from ..utils.colour import premultiplied_to_scene_linear
from ..export import ExportError
from .job import ROW_BLOCK, JobResult, failure_message, prepare_job


@dataclass
class FrameRequest:
    """A script's request for the frames the engine renders during one
    ``bpy.ops.render.render`` call (the only way to pass it anything: the operator takes no
    Python objects).  Made active with ``requesting_frames``; main thread only.

    frames: (RenderJob, JobResult) appended for each frame rendered (JobResult.image: the
        display values, row 0 = top).
    should_cancel: polled with Blender's own test_break; True cancels the render (render.py
        sets it from SIGINT/SIGTERM).
    fill_render_result: False when the script writes the frame itself: the engine then
        leaves Blender's render result empty, which spares a frame-sized copy.
    """

    should_cancel: Callable[[], bool] = lambda: False
    fill_render_result: bool = True
    frames: list = field(default_factory=list)


_active_request: Optional[FrameRequest] = None


@contextmanager
def requesting_frames(request: FrameRequest):
    """``with requesting_frames(request): bpy.ops.render.render(...)``; not re-entrant."""
    global _active_request
    if _active_request is not None:
        raise RuntimeError("a Glint frame request is already active")
    _active_request = request
    try:
        yield request
    finally:
        _active_request = None


class GlintRenderEngine(bpy.types.RenderEngine):
    bl_idname = "GLINT"
    bl_label = "Glint"
    bl_use_preview = False
    # The viewport's Material Preview and Rendered modes fall back to EEVEE: Glint has no
    # interactive renderer.
    bl_use_eevee_viewport = True

    def render(self, depsgraph):
        request = _active_request
        try:
            self._render(depsgraph, request)
        except RenderCancelled:
            return  # no result: Blender writes nothing for a cancelled frame
        except BaseException as error:  # noqa: B036 - every failure must reach the user
            self._fail(failure_message(error))

    def _render(self, depsgraph, request: Optional[FrameRequest]) -> None:
        job = prepare_job(depsgraph, camera_override=self.camera_override)
        for warning in job.warnings:
            self.report({'WARNING'}, warning)
        width, height = job.size
        if (width, height) != (self.resolution_x, self.resolution_y):
            raise RenderSetupError(f"Glint exported a {width}x{height} frame but Blender "
                                   f"renders {self.resolution_x}x{self.resolution_y}")
        region = render_region(depsgraph.scene_eval.render, width, height)
        if region is None:
            raise RenderSetupError("the render region (border) covers no whole pixel")
        summary = f"{len(job.scene.spheres)} spheres, {len(job.scene.lights)} lights, " \
                  f"{width}x{height}"
        self.update_stats("Glint", summary)

        def should_cancel():
            return self.test_break() or (request is not None and request.should_cancel())

        # Blender's render result is a float32 frame of its own, and a script that wants
        # both that and its own copy needs a third.
        copies = 1 if request is None else int(request.fill_render_result) * 2
        result = job.run(progress=self.update_progress, should_cancel=should_cancel,
                         reserve_bytes=copies * job.frame_bytes)
        self.update_stats("Glint", f"{summary}, {result.precision}")
        if request is not None:
            request.frames.append((job, result))
            if not request.fill_render_result:
                return
            result = JobResult(result.image.copy(), result.precision, result.stats)
        self._hand_over(result.image, region, depsgraph.view_layer.name)

    def _hand_over(self, image: np.ndarray, region, layer: str) -> None:
        """Write the job's image (consumed: converted in place) into Blender's result for
        ``layer``."""
        pixels = blender_pixels(image, region)
        # begin_result counts from the region's corner, not the frame's.
        x0, y0, x1, y1 = region
        result = self.begin_result(0, 0, x1 - x0, y1 - y0, layer=layer)
        try:
            result.layers[0].passes["Combined"].rect.foreach_set(pixels.reshape(-1))
        except BaseException:
            self.end_result(result, cancel=True)
            raise
        self.end_result(result)

    def _fail(self, message: str) -> None:
        self.report({'ERROR'}, message)
        if not bpy.app.background:
            self.error_set(message)


class RenderSetupError(ExportError):
    """Blender and the exported scene disagree about the frame; the message says how."""


def blender_pixels(image: np.ndarray, region) -> np.ndarray:
    """The job's (H, W, 4) float32 image (row 0 = top, display values) -> the render region's
    pixels as Blender wants them: C-contiguous (h, w, 4) float32, row 0 = bottom, premultiplied
    scene-linear.  The image is converted in place, ROW_BLOCK rows at a time, and returned
    itself for the whole frame (a region is copied out)."""
    x0, y0, x1, y1 = region
    flip_rows(image)
    for first in range(y0, y1, ROW_BLOCK):
        rows = image[first:min(first + ROW_BLOCK, y1), x0:x1]
        rows[...] = premultiplied_to_scene_linear(rows)
    if (x0, y0, x1, y1) == (0, 0, image.shape[1], image.shape[0]):
        return image
    return np.ascontiguousarray(image[y0:y1, x0:x1])


def flip_rows(image: np.ndarray) -> None:
    """Reverse the row order of ``image`` in place, ROW_BLOCK rows at a time."""
    height = image.shape[0]
    for top in range(0, height // 2, ROW_BLOCK):
        count = min(ROW_BLOCK, height // 2 - top)
        upper = image[top:top + count].copy()
        bottom = height - top - count
        image[top:top + count] = image[bottom:bottom + count][::-1]
        image[bottom:bottom + count] = upper[::-1]


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
