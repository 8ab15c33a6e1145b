"""Final renders: F12, animation renders, ``blender -b file -f/-a`` and render.py, handed over
by the engine (``base.GlintRenderEngine``) to ``render_final``.

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

Blender expects scene-linear render results: the default semantics' radiance is handed over
unchanged (so the user's view transform, look, exposure and gamma apply to it), the article
semantics' display values through the inverse sRGB transfer function
(``RenderJob.scene_linear``), so that view transform Standard shows the article's numbers.
Render results have row 0 at the bottom.  Tiles are handed over as they land
(``TileHandOver``), so a frame costs the job's float32 image and Blender's own buffer, plus a
tile.

Scripts that render through the engine (render.py) make a ``FrameRequest`` (below): it gives
them the core's numbers as well as (or instead of) Blender's render result, their own
cancel, and the failure to report themselves.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Optional

import bpy
import numpy as np

from ...core import RenderCancelled
from ..utils.colour import render_result_pixels
from ..export import ExportError
from .job import failure_message, prepare_job
from ...core.passes import PrimaryPasses, primitive_sources
from .passes import (denoising_passes, enabled_passes, pass_pixels, pass_warning,
                     scene_pass_indices)


@dataclass
class FrameRequest:
    """A script's request for the frames the engine renders during one
    ``bpy.ops.render.render`` call (the only way to pass it anything: the operator takes no
    Python objects).  Made active with ``requesting_frames``; main thread only.

    frames: (RenderJob, JobResult) appended for each frame rendered (JobResult.image: the
        job's values, row 0 = top; ``RenderJob.scene_linear`` gives the render result's).
    should_cancel: polled with Blender's own test_break; True cancels the render (render.py
        sets it from SIGINT/SIGTERM).
    fill_render_result: False when the script writes the frame itself: the engine then
        leaves Blender's render result empty, which spares a frame-sized copy.
    progress: called as (RenderJob, fraction done) as tiles land (render.py's progress line).
    failure: the one line about the failure that ended the render, for the script to report
        once: with a request the engine makes no ERROR report (which Blender prints besides
        raising it), and renders no view layer after a failed one (the frame is lost;
        Blender would go on rendering the others).
    """

    should_cancel: Callable[[], bool] = lambda: False
    fill_render_result: bool = True
    frames: list = field(default_factory=list)
    progress: Optional[Callable] = None
    failure: Optional[str] = None


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


def render_final(engine, depsgraph) -> None:
    """F12's render of one view layer (``GlintRenderEngine.render``): export, trace, and hand
    the tiles and passes to Blender's render result; any failure ends in one line
    (``failures_reported``)."""
    request = _active_request
    if request is not None and request.failure is not None:
        return  # an earlier view layer failed: the frame is lost already
    with failures_reported(engine, request):
        job = prepare_job(depsgraph, camera_override=engine.camera_override)
        view_layer = depsgraph.view_layer
        missing_passes = pass_warning(view_layer)
        if missing_passes:
            job.warnings.append(missing_passes)
        render_job(engine, depsgraph, job, enabled_passes(view_layer), request,
                   guides=bool(denoising_passes(view_layer)))


def render_job(engine, depsgraph, job, passes=(),
               request: Optional[FrameRequest] = None, guides: bool = False) -> None:
    """Trace a prepared job for ``engine`` (a final render's or a preview's): its warnings
    reported, progress, cancel and stats through the engine, and each tile handed to
    Blender's render result as it lands, with the enabled ``passes`` (``passes.PassSpec``)
    and, with ``guides``, the denoising guides once the frame is done."""
    for warning in job.warnings:
        engine.report({'WARNING'}, warning)
    width, height = job.size
    if (width, height) != (engine.resolution_x, engine.resolution_y):
        raise RenderSetupError(f"Glint exported a {width}x{height} frame but Blender "
                               f"renders {engine.resolution_x}x{engine.resolution_y}")
    region = render_region(depsgraph.scene_eval.render, width, height)
    if region is None:
        raise RenderSetupError("the render region (border) covers no whole pixel")
    summary = f"{len(job.scene.spheres)} spheres, {len(job.scene.lights)} lights, " \
              f"{width}x{height}"
    engine.update_stats("Glint", summary)

    def should_cancel():
        return engine.test_break() or (request is not None and request.should_cancel())

    def progress(fraction):
        engine.update_progress(fraction)
        if request is not None and request.progress is not None:
            request.progress(job, fraction)

    view_layer = depsgraph.view_layer
    # Tiles go to Blender as they land (F12 fills in tile by tile, and a cancel keeps
    # them), unless the script asking for the frames writes it itself.
    fill = request is None or request.fill_render_result
    # The passes, when enabled, are filled tile by tile and handed over with each tile.
    primary = PrimaryPasses.empty(
        width, height, emission=any(spec.name == "Emission" for spec in passes)
    ) if passes and fill else None
    tiles = TileHandOver(engine, region, height, view_layer.name, job.settings.semantics,
                         TilePasses.of(job.scene, passes, primary)) if fill else None
    guides = guides and fill
    result = job.run(progress=progress, should_cancel=should_cancel,
                     on_tile=tiles.hand_over if tiles is not None else None,
                     passes=primary if primary is not None else False, guides=guides,
                     # Beside the job's frame, Blender holds a float32 frame (the
                     # render result, or render.py's colour-managed Image) and, while it
                     # saves, its display buffers: measured, render.py peaks at 3.35
                     # frames at 16K (14.36 GB for 4.29 GB), so 2.5 frames more.
                     reserve_bytes=5 * job.frame_bytes // 2)
    whole = {}
    if guides and result.albedo is not None:
        whole = {"Denoising Albedo": result.albedo, "Denoising Normal": result.normal}
    if (result.denoised or whole) and tiles is not None:
        # The tiles Blender holds are the noisy ones: the denoised frame replaces them
        # (with the denoising guides, known once the frame is done).
        tiles.hand_over((0, height, 0, width), result.image, whole)
    engine.update_stats("Glint", f"{summary}, {result.precision}")
    if result.fallback is not None:
        engine.report({'WARNING'}, f"Glint: {result.fallback}")
    if request is not None:
        request.frames.append((job, result))


@contextmanager
def failures_reported(engine, request: Optional[FrameRequest] = None):
    """Whatever goes wrong inside ends in one ERROR report naming it (``failure_message``,
    module docstring), or with a ``request`` in its ``failure``; a cancel ends quietly: the
    tiles that finished stay in the render result, as with Blender's own engines, and Blender
    writes no file for a cancelled frame."""
    try:
        yield
    except RenderCancelled:
        return
    except BaseException as error:  # noqa: B036 - every failure must reach the user
        message = failure_message(error)
        if request is not None:
            request.failure = message
            return
        engine.report({'ERROR'}, message)
        if not bpy.app.background:
            engine.error_set(message)


@dataclass
class TilePasses:
    """The enabled passes (``passes.PassSpec``) and what their pixels are read from: the
    PrimaryPasses the render fills tile by tile, and the scene's pass indices (read once)."""

    specs: list
    primary: PrimaryPasses
    indices: tuple        # (object index per entry, material index per table entry)
    sources: np.ndarray   # the scene entry of each primitive

    @classmethod
    def of(cls, scene, specs, primary) -> Optional["TilePasses"]:
        if not specs or primary is None:
            return None
        return cls(specs, primary, scene_pass_indices(scene), primitive_sources(scene))

    def pixels(self, region) -> dict:
        return pass_pixels(self.primary, self.specs, *self.indices, self.sources, region)


class TileHandOver:
    """Each tile, as it lands, into Blender's render result (``begin_result`` for the tile's
    part of the render region, ``end_result`` merges it and F12 shows it), the way Cycles hands
    over tiles: Combined and, when enabled, the passes (``TilePasses``), so each is written
    once.  Tiles arrive from ``RenderJob.run(on_tile=...)``: rows from the top of the frame,
    finished job values of ``semantics``; Blender wants premultiplied scene-linear rows from
    the bottom, counted from the render region's corner."""

    def __init__(self, engine, region, frame_height: int, layer: str, semantics: str,
                 passes: Optional[TilePasses] = None):
        self.engine, self.region, self.frame_height, self.layer = engine, region, frame_height, layer
        self.semantics = semantics
        self.passes = passes

    def hand_over(self, tile, rgba: np.ndarray, whole: Optional[dict] = None) -> None:
        """Hand a tile over; whole: {pass name: (H, W, C) frame-sized array, rows from the
        top} of passes to write beside it (the denoising guides, known once the frame is
        done)."""
        y0, y1, x0, x1 = tile
        # Rows from the bottom of the frame, intersected with the region.
        bottom, top = self.frame_height - y1, self.frame_height - y0
        rx0, ry0, rx1, ry1 = self.region
        left, right = max(x0, rx0), min(x1, rx1)
        low, high = max(bottom, ry0), min(top, ry1)
        if left >= right or low >= high:
            return
        pixels = blender_pixels(rgba[top - high:top - low, left - x0:right - x0],
                                self.semantics)
        extra = self.passes.pixels((left, low, right, high)) if self.passes else {}
        for name, frame in (whole or {}).items():
            rows = frame[self.frame_height - high:self.frame_height - low, left:right][::-1]
            extra[name] = np.ascontiguousarray(rows, np.float32).reshape(-1)
        result = self.engine.begin_result(left - rx0, low - ry0, right - left, high - low,
                                          layer=self.layer)
        try:
            passes = result.layers[0].passes
            passes["Combined"].rect.foreach_set(pixels.reshape(-1))
            for name, values in extra.items():
                passes[name].rect.foreach_set(values)
        except BaseException:
            self.engine.end_result(result, cancel=True)
            raise
        self.engine.end_result(result)


class RenderSetupError(ExportError):
    """Blender and the exported scene disagree about the frame; the message says how."""


def blender_pixels(rows: np.ndarray, semantics: str) -> np.ndarray:
    """(h, w, 4) finished job values of ``semantics``, row 0 = top -> what Blender's render
    result holds: a C-contiguous float32 (h, w, 4) copy, row 0 = bottom, premultiplied
    scene-linear (``render_result_pixels``)."""
    return np.ascontiguousarray(render_result_pixels(rows[::-1], semantics), np.float32)


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
