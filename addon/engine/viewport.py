"""The viewport's Rendered shading: what the 3D View shows, traced progressively.

The engine's ``view_update`` / ``view_draw`` hand over to a ``ViewportEngine`` (one per
engine instance, i.e. per 3D View in Rendered mode), which exports the scene, reports, draws
(``addon.draw.viewport``) and keeps a ``ViewportSession``.  Everything below it works on plain
data (Blender's matrices, core scenes), so the tests drive it headless:

* ``view_camera``: a region's view and projection matrices (``RegionView3D.view_matrix`` /
  ``window_matrix``) -> a ``core.BlenderCamera`` whose rays are the rays through the region's
  pixels.  This covers perspective and orthographic views, the camera view (whose window
  matrix already holds the camera's lens, shift, sensor fit and the view's zoom and pan) and
  any sub-rectangle (``crop_projection``: the camera view's render border, coarse passes).
* ``camera_frame_rect``: where the scene camera's frame lies in the region (camera view),
  and so where its render border lies.
* ``refinement_schedule``: the passes a view goes through: a coarse pass at a fraction of the
  resolution, then full resolution at pixel centres, then the scene's anti-aliasing (a
  4-sample pass first when that is fixed with more samples).
* ``ProgressiveRender``: those passes on a worker thread (NumPy only, no Blender data),
  cancelled between tiles as soon as the user edits again.
* ``ViewportSession``: re-renders only when the exported scene or the view changed.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..utils.denoise import available as denoise_available, denoise as denoise_image
from ...core import BlenderCamera, RenderCancelled, RenderSettings, Scene, SceneError, render
from ...core.context import path_traced
from .ignored import ignored_settings_warning
from .job import failure_message

#: The coarse pass traces at most this many pixels (a power-of-two fraction of the view's
#: resolution), so the first picture of a small scene comes back in a few hundredths of a
#: second whatever the size of the viewport.
COARSE_PIXELS = 25_000
#: Fixed anti-aliasing with more samples than this gets a pass with this many first.
PREVIEW_SAMPLES = 4
#: Tiles of the viewport's passes: small, so that a cancel is honoured within a few
#: milliseconds of tracing.
VIEWPORT_TILE = 64
#: A clip end beyond this (or an infinite far plane) is clamped to it: BlenderCamera needs a
#: finite value, and no scene reaches that far.
FAR_LIMIT = 1e30


# --------------------------------------------------------------------------------------------
# The view -> core camera

def _matrix(matrix) -> np.ndarray:
    return np.array([list(row) for row in matrix], np.float64)


def view_camera(view_matrix, window_matrix, width: int, height: int) -> BlenderCamera:
    """A BlenderCamera of width x height pixels whose rays are the region's.

    view_matrix: world -> view (4x4, a rigid transform); window_matrix: view -> clip, an
    OpenGL perspective (row 3 = (0, 0, -1, 0)) or orthographic (row 3 = (0, 0, 0, 1))
    projection, as ``RegionView3D`` holds them.  A region pixel (i, j), j from the bottom,
    has its centre at NDC (2 (i + .5) / W - 1, 2 (j + .5) / H - 1), exactly as the core's
    camera places pixel centres; the camera is given a horizontal sensor fit whose view-plane
    width is the projection's, a pixel aspect that makes its height the projection's, and a
    shift for an off-centre projection (camera shift, the camera view's pan, a crop).

    Perspective, at view depth 1: x_view = (ndc_x + P02) / P00, so half width 1 / P00 and
    centre P02 / P00; clip planes n = P23 / (P22 - 1), f = P23 / (P22 + 1).
    Orthographic: x_view = (ndc_x - P03) / P00; n = (P23 + 1) / P22, f = (P23 - 1) / P22.
    An orthographic viewport's near plane is behind its view point (n < 0); the camera is
    moved back along the view axis so that its clip start is positive.
    """
    view = _matrix(view_matrix)
    projection = _matrix(window_matrix)
    camera_to_world = np.linalg.inv(view)
    p = projection
    perspective = p[3, 3] == 0.0
    if perspective:
        half_w, half_h = 1.0 / p[0, 0], 1.0 / p[1, 1]
        centre_x, centre_y = p[0, 2] / p[0, 0], p[1, 2] / p[1, 1]
        near = p[2, 3] / (p[2, 2] - 1.0)
        far = p[2, 3] / (p[2, 2] + 1.0) if p[2, 2] != -1.0 else math.inf
    else:
        half_w, half_h = 1.0 / p[0, 0], 1.0 / p[1, 1]
        centre_x, centre_y = -p[0, 3] / p[0, 0], -p[1, 3] / p[1, 1]
        near = (p[2, 3] + 1.0) / p[2, 2]
        far = (p[2, 3] - 1.0) / p[2, 2]
    if not math.isfinite(far) or far <= near or far > FAR_LIMIT:
        far = FAR_LIMIT
    size = 2.0 * half_w                 # the view plane's width (sensor_width / lens, or ortho)
    # half_h = half_w * (H * aspect_y) / (W * aspect_x) with aspect_x = 1:
    aspect_y = half_h * width / (half_w * height)
    if not perspective and near <= 0.0:
        # Move the eye back so the near plane is ahead of it.
        back = (far - near) * 1e-6 - near
        camera_to_world = camera_to_world.copy()
        camera_to_world[:3, 3] += back * camera_to_world[:3, 2]
        near, far = near + back, far + back
    lens = 50.0
    return BlenderCamera(
        matrix_world=tuple(tuple(row) for row in camera_to_world),
        resolution_x=int(width), resolution_y=int(height), resolution_percentage=100,
        projection="PERSP" if perspective else "ORTHO",
        lens=lens, sensor_width=lens * size, sensor_height=lens * size, ortho_scale=size,
        sensor_fit="HORIZONTAL",
        shift_x=centre_x / size, shift_y=centre_y / size,
        clip_start=near, clip_end=far,
        pixel_aspect_x=1.0, pixel_aspect_y=aspect_y,
    )


def crop_projection(window_matrix, width: int, height: int, rect) -> np.ndarray:
    """The projection (4x4) of the sub-rectangle rect = (x0, y0, x1, y1) of a width x height
    region (pixels, rows from the bottom): the same rays, re-normalised so that the rectangle
    spans NDC [-1, 1]^2.  clip' = S clip with S scaling and translating x and y."""
    x0, y0, x1, y1 = rect
    ndc = lambda a, size: 2.0 * a / size - 1.0  # noqa: E731
    left, right = ndc(x0, width), ndc(x1, width)
    bottom, top = ndc(y0, height), ndc(y1, height)
    scale = np.eye(4)
    scale[0, 0] = 2.0 / (right - left)
    scale[0, 3] = -(right + left) / (right - left)
    scale[1, 1] = 2.0 / (top - bottom)
    scale[1, 3] = -(top + bottom) / (top - bottom)
    return scale @ _matrix(window_matrix)


def camera_frame_rect(perspective_matrix, frame_corners, width: int, height: int):
    """(x0, y0, x1, y1) in region pixels (float, rows from the bottom) of the scene camera's
    frame in a camera view: its four world-space corners (``Camera.view_frame`` placed by the
    camera's world matrix) projected by the region's perspective matrix (window @ view), as
    ``bpy_extras.view3d_utils.location_3d_to_region_2d`` does."""
    pers = _matrix(perspective_matrix)
    corners = np.array([list(c)[:3] + [1.0] for c in frame_corners], np.float64)
    clip = corners @ pers.T
    xs = width / 2.0 * (1.0 + clip[:, 0] / clip[:, 3])
    ys = height / 2.0 * (1.0 + clip[:, 1] / clip[:, 3])
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())


def border_rect(frame, border, width: int, height: int):
    """The render border (min_x, min_y, max_x, max_y fractions of the camera frame) in whole
    region pixels (edges rounded to the nearest pixel edge), clamped to the region; None if
    it covers no pixel."""
    fx0, fy0, fx1, fy1 = frame
    min_x, min_y, max_x, max_y = border
    x0 = max(0, round(fx0 + min_x * (fx1 - fx0)))
    x1 = min(width, round(fx0 + max_x * (fx1 - fx0)))
    y0 = max(0, round(fy0 + min_y * (fy1 - fy0)))
    y1 = min(height, round(fy0 + max_y * (fy1 - fy0)))
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


@dataclass(frozen=True)
class ViewportView:
    """What the region shows: its matrices, size in pixels and the rectangle to render
    (rows from the bottom; the whole region, or the render border in a camera view)."""

    view_matrix: tuple
    window_matrix: tuple
    width: int
    height: int
    rect: tuple

    @classmethod
    def from_matrices(cls, view_matrix, window_matrix, width, height, rect=None):
        as_tuple = lambda m: tuple(tuple(float(v) for v in row) for row in m)  # noqa: E731
        return cls(as_tuple(view_matrix), as_tuple(window_matrix), int(width), int(height),
                   tuple(rect) if rect is not None else (0, 0, int(width), int(height)))

    @classmethod
    def from_context(cls, context, scene):
        """The view of ``context.region`` / ``context.region_data`` (main thread); ``scene``
        is the evaluated scene, for the camera and its render border in a camera view.
        Returns None when the render border covers no pixel."""
        region, rv3d = context.region, context.region_data
        width, height = region.width, region.height
        rect = None
        camera = scene.camera
        if (rv3d.view_perspective == 'CAMERA' and scene.render.use_border and camera is not None
                and camera.type == 'CAMERA'):
            frame = [camera.matrix_world @ corner for corner in camera.data.view_frame(scene=scene)]
            rect = border_rect(camera_frame_rect(rv3d.perspective_matrix, frame, width, height),
                               (scene.render.border_min_x, scene.render.border_min_y,
                                scene.render.border_max_x, scene.render.border_max_y),
                               width, height)
            if rect is None:
                return None
        return cls.from_matrices(rv3d.view_matrix, rv3d.window_matrix, width, height, rect)

    def camera(self, divisor: int = 1) -> BlenderCamera:
        """The core camera of the view's rectangle traced at 1 / divisor of its resolution."""
        x0, y0, x1, y1 = self.rect
        projection = self.window_matrix
        if self.rect != (0, 0, self.width, self.height):
            projection = crop_projection(projection, self.width, self.height, self.rect)
        return view_camera(self.view_matrix, projection,
                           max(1, (x1 - x0) // divisor), max(1, (y1 - y0) // divisor))


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


class ProgressiveRender:
    """The refinement of one (scene, view) on a worker thread.

    ``frame`` is the latest finished pass (None before the first); ``cancel`` stops the
    worker between tiles (``core.render``'s should_cancel) and no later pass replaces the
    frame; ``on_frame`` (called on the worker thread, so it must not touch Blender data) is
    told of each new frame.
    """

    def __init__(self, scene: Scene, view: ViewportView, settings: RenderSettings,
                 pixel_size: int = 1,
                 on_frame: Optional[Callable[[ViewportFrame], None]] = None,
                 denoise: bool = False):
        self.scene, self.view = scene, view
        x0, y0, x1, y1 = view.rect
        self.schedule = refinement_schedule(x1 - x0, y1 - y0, settings, pixel_size,
                                            path_traced(scene, settings))
        self.frame: Optional[ViewportFrame] = None
        self.error: Optional[BaseException] = None
        self.started = time.perf_counter()
        self.frame_times: list[float] = []    # seconds from start to each finished pass
        self._on_frame = on_frame
        self._denoise = denoise
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name="glint-viewport", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for index, step in enumerate(self.schedule):
            scene = dataclasses.replace(self.scene, camera=self.view.camera(step.divisor))
            final = index == len(self.schedule) - 1
            denoise = final and self._denoise and denoise_available()
            settings = (dataclasses.replace(step.settings, guides=True) if denoise
                        else step.settings)
            try:
                result = render(scene, settings, should_cancel=self._stop.is_set,
                                image_dtype=np.float32,
                                on_pass=self._pass_watcher(index, scene, settings))
            except RenderCancelled:
                return
            except BaseException as error:  # shown in the viewport's status line
                self.error = error
                return
            image = result.image
            if denoise and result.albedo is not None:
                image = np.array(image, np.float32, copy=True)
                image[..., :3] = denoise_image(image[..., :3], result.albedo, result.normal)
            if not self._publish(image, index, result.semantics):
                return

    def _publish(self, image, index: int, semantics: str, final: bool = True) -> bool:
        """Show ``image`` as the frame of pass ``index`` (final False: one of its progressive
        passes, more to come); False once cancelled."""
        with self._lock:
            if self._stop.is_set():
                return False
            self.frame = ViewportFrame(image, index, len(self.schedule), self.view.rect,
                                       semantics, complete=final)
            self.frame_times.append(time.perf_counter() - self.started)
        if self._on_frame is not None:
            self._on_frame(self.frame)
        return True

    def _pass_watcher(self, index: int, scene, settings):
        """For a path-traced pass: an on_pass that publishes the frame as each progressive
        pass completes, so the view sharpens sample by sample; None for other passes."""
        if not path_traced(scene, settings):
            return None

        def on_pass(samples, image):
            if samples < settings.samples:
                self._publish(np.array(image[..., :4], np.float32), index,
                              settings.semantics, final=False)
        return on_pass

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    @property
    def cancelled(self) -> bool:
        return self._stop.is_set()

    def cancel(self) -> None:
        with self._lock:
            self._stop.set()

    def wait(self, timeout: Optional[float] = None) -> bool:
        self._thread.join(timeout)
        return self.done


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
