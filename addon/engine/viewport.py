"""The viewport's Rendered shading: what the 3D View shows, traced progressively.

The engine's ``view_update`` / ``view_draw`` hand over to a ``ViewportEngine`` (one per
engine instance, i.e. per 3D View in Rendered mode), which exports the scene, reports, draws
(``addon.draw.viewport``) and keeps a ``ViewportSession``.  Everything below it works on plain
data (Blender's matrices, core scenes), so the tests drive it headless:

* ``ViewportView`` (``addon.export.view``): what the region shows, and the core camera of
  its pixels' rays;
* ``refinement_schedule``: the passes a view goes through: a coarse pass at a fraction of the
  resolution, then full resolution at pixel centres, then the scene's anti-aliasing (a
  4-sample pass first when that is fixed with more samples).
* ``ProgressiveRender``: those passes on a worker thread (NumPy only, no Blender data),
  cancelled between tiles as soon as the user edits again.
* ``ViewportSession``: re-renders only when the exported scene or the view changed.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..utils.denoise import available as denoise_available, denoise as denoise_image
from ...core import BlenderCamera, RenderSettings, Scene, SceneError, render
from ...core.context import path_traced
from ..export.view import ViewportView
from .ignored import ignored_settings_warning
from .job import ThreadedRender, failure_message

#: The coarse pass traces at most this many pixels (a power-of-two fraction of the view's
#: resolution), so the first picture of a small scene comes back in a few hundredths of a
#: second whatever the size of the viewport.
COARSE_PIXELS = 25_000
#: Fixed anti-aliasing with more samples than this gets a pass with this many first.
PREVIEW_SAMPLES = 4
#: Tiles of the viewport's passes: small, so that a cancel is honoured within a few
#: milliseconds of tracing.
VIEWPORT_TILE = 64


# --------------------------------------------------------------------------------------------
# Progressive refinement

@dataclass(frozen=True)
class RefinementPass:
    """One picture of the refinement: the view traced at 1 / divisor of its resolution with
    these settings."""

    divisor: int
    settings: RenderSettings


def coarse_divisor(width: int, height: int, pixel_size: int = 1) -> int:
    """The smallest power of two d >= 2 pixel_size for which the view at 1 / d of its
    resolution has at most COARSE_PIXELS pixels."""
    divisor = 2 * pixel_size
    while (width // divisor) * (height // divisor) > COARSE_PIXELS:
        divisor *= 2
    return divisor


def refinement_schedule(width: int, height: int, settings: RenderSettings,
                        pixel_size: int = 1, path: bool = False) -> list[RefinementPass]:
    """The passes a view goes through, each a better picture than the last:

    1. coarse: 1 / ``coarse_divisor`` of the resolution, one ray per (big) pixel; left out
       when the view is already small enough;
    2. the resolution (divided by ``pixel_size``, Blender's viewport Pixel Size), one ray
       through each pixel centre;
    3. with fixed anti-aliasing of more than PREVIEW_SAMPLES samples, first PREVIEW_SAMPLES
       of them (a smooth picture for a fraction of the final pass's time);
    4. the scene's own anti-aliasing (its settings unchanged, so the last picture is what F12
       renders of the same view); left out when anti-aliasing is off.
    """
    if path:
        # Path tracing refines itself, pass by pass (``core.progressive``): a coarse
        # sample first, then the view at its resolution, its frames published as its
        # passes complete (``ProgressiveRender``).
        traced = dataclasses.replace(settings, tile_size=VIEWPORT_TILE)
        passes = []
        if (width // pixel_size) * (height // pixel_size) > COARSE_PIXELS:
            passes.append(RefinementPass(coarse_divisor(width, height, pixel_size),
                                         dataclasses.replace(traced, samples=1)))
        passes.append(RefinementPass(pixel_size, traced))
        return passes
    base = dataclasses.replace(settings, anti_aliasing="off", tile_size=VIEWPORT_TILE)
    passes = []
    if (width // pixel_size) * (height // pixel_size) > COARSE_PIXELS:
        passes.append(RefinementPass(coarse_divisor(width, height, pixel_size), base))
    passes.append(RefinementPass(pixel_size, base))
    if settings.anti_aliasing == "fixed" and settings.samples > PREVIEW_SAMPLES:
        passes.append(RefinementPass(pixel_size, dataclasses.replace(
            settings, samples=PREVIEW_SAMPLES, tile_size=VIEWPORT_TILE)))
    if settings.anti_aliasing != "off":
        passes.append(RefinementPass(pixel_size, dataclasses.replace(
            settings, tile_size=VIEWPORT_TILE)))
    return passes


@dataclass(frozen=True, eq=False)
class ViewportFrame:
    """A finished pass: image (h, w, 4) float32 (row 0 = top, the job's values of
    ``semantics``: see ``RenderJob``), the pass's index in the schedule and how many passes
    there are, and the rectangle of the region (rows from the bottom) it covers."""

    image: np.ndarray
    index: int
    passes: int
    rect: tuple
    semantics: str = "article"
    complete: bool = True     # False: a progressive pass of a path-traced step

    @property
    def final(self) -> bool:
        return self.complete and self.index == self.passes - 1


class ProgressiveRender(ThreadedRender):
    """The refinement of one (scene, view) on a worker thread (``job.ThreadedRender``, one
    pass per step of ``schedule``): ``frame`` is the latest picture (None before the first),
    each step's and, for a path-traced step, each of its progressive passes as it completes
    (``ViewportFrame.complete`` False); ``frame_times`` when each landed; ``cancel`` stops the
    worker between tiles and no later picture replaces the frame; ``on_frame`` (called on the
    worker thread, so it must not touch Blender data) is told of each new frame; ``denoise``:
    the last step is denoised (where Open Image Denoise is available).
    """

    def __init__(self, scene: Scene, view: ViewportView, settings: RenderSettings,
                 pixel_size: int = 1,
                 on_frame: Optional[Callable[[ViewportFrame], None]] = None,
                 denoise: bool = False):
        self.scene, self.view = scene, view
        x0, y0, x1, y1 = view.rect
        self.schedule = refinement_schedule(x1 - x0, y1 - y0, settings, pixel_size,
                                            path_traced(scene, settings))
        self._denoise = denoise
        super().__init__([functools.partial(self._render_step, index)
                          for index in range(len(self.schedule))],
                         on_result=on_frame, name="glint-viewport")

    def _render_step(self, index: int, progress, should_cancel) -> ViewportFrame:
        step = self.schedule[index]
        scene = dataclasses.replace(self.scene, camera=self.view.camera(step.divisor))
        final = index == len(self.schedule) - 1
        denoise = final and self._denoise and denoise_available()
        settings = (dataclasses.replace(step.settings, guides=True) if denoise
                    else step.settings)
        result = render(scene, settings, progress=progress, should_cancel=should_cancel,
                        image_dtype=np.float32,
                        on_pass=self._pass_watcher(index, scene, settings))
        image = result.image
        if denoise and result.albedo is not None:
            image = np.array(image, np.float32, copy=True)
            image[..., :3] = denoise_image(image[..., :3], result.albedo, result.normal)
        return ViewportFrame(image, index, len(self.schedule), self.view.rect, result.semantics)

    def _pass_watcher(self, index: int, scene, settings):
        """For a path-traced step: an on_pass that shows the frame as each progressive pass
        completes, so the view sharpens sample by sample; None for other steps."""
        if not path_traced(scene, settings):
            return None

        def on_pass(samples, image):
            if samples < settings.samples:
                self._publish(ViewportFrame(np.array(image[..., :4], np.float32), index,
                                            len(self.schedule), self.view.rect,
                                            settings.semantics, complete=False))
        return on_pass

    @property
    def frame(self) -> Optional[ViewportFrame]:
        return self.result

    @property
    def frame_times(self) -> list[float]:
        return self.result_times


class ViewportSession:
    """A 3D View in Rendered mode: the scene last exported and the view last drawn, and the
    refinement running for them.  ``update_scene`` (from view_update) and ``update_view``
    (from view_draw) restart the refinement only when what they are given differs from what
    is being rendered, cancelling the previous one at once."""

    def __init__(self, on_frame: Optional[Callable[[ViewportFrame], None]] = None):
        self.scene: Optional[Scene] = None
        self.settings: Optional[RenderSettings] = None
        self.pixel_size = 1
        self.view: Optional[ViewportView] = None
        self.render: Optional[ProgressiveRender] = None
        self.restarts = 0
        self._on_frame = on_frame
        self._previous: Optional[ViewportFrame] = None

    def update_scene(self, scene: Scene, settings: RenderSettings,
                     pixel_size: int = 1) -> bool:
        """Take a newly exported scene (its camera is ignored: the view decides); True if the
        refinement restarted.  A depsgraph update that changes nothing Glint renders
        (selection, a UI property) restarts nothing."""
        # Film > Transparent is in the settings (their film).
        state = (scene.spheres, scene.lights, scene.background, scene.ambient, settings,
                 pixel_size)
        if self.scene is not None and state == (
                self.scene.spheres, self.scene.lights, self.scene.background,
                self.scene.ambient, self.settings, self.pixel_size):
            return False
        self.scene, self.settings, self.pixel_size = scene, settings, pixel_size
        return self._restart()

    #: Denoise the last pass (Glint's Denoise option), set by the engine from the scene.
    denoise = False

    def update_view(self, view: Optional[ViewportView]) -> bool:
        """Take the view being drawn; True if the refinement restarted."""
        if view == self.view:
            return False
        self.view = view
        return self._restart()

    def _restart(self) -> bool:
        self.stop()
        if self.render is not None and self.render.frame is not None:
            self._previous = self.render.frame
        if self.scene is None or self.view is None:
            return False
        self.render = ProgressiveRender(self.scene, self.view, self.settings,
                                        self.pixel_size, self._on_frame, self.denoise)
        self.restarts += 1
        return True

    @property
    def frame(self) -> Optional[ViewportFrame]:
        """The picture to draw: the refinement's latest pass, or until its first pass
        arrives the last picture of the previous one (so an edit never flashes an empty
        viewport)."""
        if self.render is not None and self.render.frame is not None:
            return self.render.frame
        return self._previous

    @property
    def busy(self) -> bool:
        """Whether a better picture is still coming (the drawer polls until it is not)."""
        return self.render is not None and not self.render.done

    def stop(self) -> None:
        if self.render is not None:
            self.render.cancel()


# --------------------------------------------------------------------------------------------
# The Blender side (main thread): what view_update and view_draw do

#: The camera the viewport's scene is exported with; ``ViewportView.camera`` replaces it for
#: every pass, so a scene without a camera (or with a panoramic one) still shows in a free view.
_PLACEHOLDER_CAMERA = BlenderCamera(matrix_world=tuple(tuple(float(r == c) for c in range(4))
                                                       for r in range(4)))


def pixel_size(render, preferences=None) -> int:
    """Blender's viewport Pixel Size (Render properties > Performance > Viewport): 1, 2, 4
    or 8 screen pixels per traced pixel; Automatic follows the interface's pixel size."""
    value = render.preview_pixel_size
    if value == 'AUTO':
        return max(1, int(round(preferences.system.pixel_size))) if preferences else 1
    return int(value)


def export_viewport_scene(depsgraph, preferences=None, view: Optional[ViewportView] = None):
    """(scene, settings, pixel size, warnings) for the viewport's evaluated
    depsgraph.  Raises ExportError / SceneError like any export.

    The scene is exported with the view's camera (a placeholder before the first draw); the
    exporter judges which sphere-like meshes stay analytic spheres from the scene's render
    camera, so the viewport shows the shapes F12 renders.  The passes then trace through the
    view whatever it becomes."""
    from ..export import export_scene
    from .job import render_settings

    camera = view.camera() if view is not None else _PLACEHOLDER_CAMERA
    scene, warnings = export_scene(depsgraph, view_camera=camera)
    warnings += ignored_settings_warning(depsgraph)
    blender_scene = depsgraph.scene_eval
    # The viewport renders here: a cluster's round trips would slow its every redraw.
    settings = dataclasses.replace(
        render_settings(blender_scene.glint, blender_scene.render, blender_scene), cluster="")
    if path_traced(scene, settings):
        settings = dataclasses.replace(settings, samples=blender_scene.glint.viewport_samples)
    return (scene, settings, pixel_size(blender_scene.render, preferences), warnings)


class ViewportEngine:
    """What ``GlintRenderEngine.view_update`` / ``view_draw`` delegate to: one per engine
    instance.  Errors and warnings go to the engine's report once per change, and the
    viewport's status text (``update_stats``) says which pass is shown."""

    def __init__(self):
        self.session = ViewportSession()
        self._reported = None
        self._drawer = None
        self._drawn = None

    def _report(self, engine, kind, messages) -> None:
        if (kind, messages) == self._reported:
            return
        self._reported = (kind, messages)
        for message in messages:
            engine.report({kind}, message)

    def view_update(self, engine, context, depsgraph) -> None:
        from ..export import ExportError

        try:
            view = ViewportView.from_context(context, depsgraph.scene_eval) \
                if getattr(context, "region_data", None) is not None else None
            scene, settings, size, warnings = export_viewport_scene(
                depsgraph, context.preferences, view)
        except (ExportError, SceneError) as error:
            self.session.stop()
            self._report(engine, 'ERROR', (str(error),))
            return
        self._report(engine, 'WARNING', tuple(warnings))
        self.session.denoise = bool(depsgraph.scene_eval.glint.use_denoising)
        self.session.update_scene(scene, settings, size)

    def view_draw(self, engine, context, depsgraph) -> None:
        scene = depsgraph.scene_eval
        view = ViewportView.from_context(context, scene)
        self.session.update_view(view)
        frame = self.session.frame
        if frame is not None and view is not None:  # None: the render border is empty
            if self._drawer is None:
                from ..draw.viewport import FrameDrawer

                self._drawer = FrameDrawer()
            self._drawer.draw(engine, scene, frame)
            self._drawn = frame
        engine.update_stats("", status_text(self.session))
        if self.session.busy:
            watch_for_frames(self)

    def free(self) -> None:
        self.session.stop()

    def __del__(self):
        # The engine holds the only reference: when Blender frees it (Rendered shading ends,
        # the 3D View closes), this goes too and the worker stops, even where the engine's
        # own __del__ can no longer reach its attributes.
        self.session.stop()

    def has_undrawn_frame(self) -> bool:
        frame = self.session.frame
        return frame is not None and frame is not self._drawn


def status_text(session: ViewportSession) -> str:
    """The viewport's status line: the pass shown and the time it took."""
    progressive = session.render
    if progressive is None:
        return "Glint"
    if progressive.error is not None:
        return f"Glint: {failure_message(progressive.error)}"
    frame = progressive.frame
    if frame is None:
        return "Glint: rendering..."
    step = progressive.schedule[frame.index]
    if step.settings.anti_aliasing != "off":
        what = f"{step.settings.anti_aliasing} anti-aliasing, {step.settings.samples} samples"
    elif step.divisor > session.pixel_size:
        what = f"preview at 1/{step.divisor} resolution"
    else:
        what = "pixel centres"
    state = "done" if frame.final else "refining"
    return f"Glint: {what} ({frame.index + 1}/{frame.passes}, {state}) " \
           f"{progressive.frame_times[frame.index]:.2f} s"


#: Viewports whose refinement is running; a timer on the main thread redraws their 3D Views
#: when a new pass lands (the worker thread never calls Blender).
_watched = None
POLL_SECONDS = 0.05


def watch_for_frames(viewport: ViewportEngine) -> None:
    import weakref

    import bpy

    global _watched
    if _watched is None:
        _watched = weakref.WeakSet()
    _watched.add(viewport)
    if not bpy.app.timers.is_registered(_redraw_new_frames):
        bpy.app.timers.register(_redraw_new_frames, first_interval=POLL_SECONDS)


def _redraw_new_frames():
    import bpy

    if not _watched:
        return None
    if any(viewport.has_undrawn_frame() for viewport in list(_watched)):
        for window in bpy.context.window_manager.windows:
            for area in window.screen.areas:
                if area.type == 'VIEW_3D':
                    area.tag_redraw()
    for viewport in list(_watched):
        if not viewport.session.busy and not viewport.has_undrawn_frame():
            _watched.discard(viewport)
    return POLL_SECONDS if _watched else None
