"""What every Glint render does, whoever starts it (render engine, Render button, render.py).

``prepare_job`` runs on Blender's main thread: it exports the evaluated scene and reads the
settings, so the job holds plain data only.  ``RenderJob.run`` touches no Blender data and may
run on any thread; it returns a ``JobResult`` whose image is

* (H, W, 4) float32, row 0 = top, the core's values: default semantics unclipped
  scene-linear radiance, article semantics the article's display values (what its PNG
  stores); ``RenderJob.scene_linear`` turns either into what Blender's render result holds;
* Film > Transparent off (the core's film 'opaque'): the background is the world colour,
  alpha 1 except where holdouts cut holes;
* Film > Transparent on (film 'transparent'): camera rays that escape (directly or straight
  through Transparent BSDFs) add nothing and leave alpha < 1, as do holdouts; colour is
  premultiplied (Blender's convention for render results); reflections of the world stay.

The core computes both itself (``RenderSettings.film``, ``core.trace``) and renders straight
into a float32 image, so a job holds one frame-sized array whatever the resolution.
``failure_message`` turns any exception a render can raise into the one line every entry
point reports.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ...core import RenderCancelled, RenderSettings, Scene, SceneError, render
from ...core.render import RayStats
from ..export import ExportError, export_scene
from .ignored import ignored_settings_warning
from ..utils.colour import render_result_pixels
from ..utils.denoise import available as denoise_available, denoise

#: Set (to anything) to have unexpected errors print their traceback to stderr as well.
DEBUG_VARIABLE = "GLINT_DEBUG"


#: Cycles' Light Paths and Film settings (``Scene.cycles``) the path integrator follows:
#: (Cycles' property, RenderSettings' field).
CYCLES_SETTINGS = (
    ("max_bounces", "max_bounces"), ("diffuse_bounces", "diffuse_bounces"),
    ("glossy_bounces", "glossy_bounces"), ("transmission_bounces", "transmission_bounces"),
    ("transparent_max_bounces", "transparent_bounces"),
    ("sample_clamp_direct", "clamp_direct"), ("sample_clamp_indirect", "clamp_indirect"),
    ("caustics_reflective", "caustics_reflective"),
    ("caustics_refractive", "caustics_refractive"), ("blur_glossy", "filter_glossy"),
    ("pixel_filter_type", "filter_type"), ("filter_width", "filter_width"),
)


def cycles_settings(scene) -> dict:
    """The scene's Light Paths and pixel filter as RenderSettings fields, read from Cycles'
    own settings (``Scene.cycles``) so that a file renders with the bounces its author set;
    a Blender without Cycles' add-on has none, and Cycles' defaults apply."""
    cycles = getattr(scene, "cycles", None)
    if cycles is None:
        return {}
    values = {}
    for blender_name, field_name in CYCLES_SETTINGS:
        if hasattr(cycles, blender_name):
            values[field_name] = getattr(cycles, blender_name)
    return values


def render_settings(settings, render=None, scene=None) -> RenderSettings:
    """``Scene.glint`` (a GlintRenderSettings) -> core RenderSettings; ``render`` (the scene's
    RenderSettings), if given, sets the threads: Blender's Performance > Threads, so a farm
    node running several jobs is not oversubscribed (Auto-detect: one per core), and the film
    (Film > Transparent; without ``render``, the core's own 'coverage'); ``scene``, if given,
    the Light Paths and pixel filter (``cycles_settings``).  The cluster address, if any,
    sends the tiles to a Dask cluster (``core.cluster``)."""
    threads = None
    film = "coverage"
    if render is not None:
        film = "transparent" if render.film_transparent else "opaque"
        if render.threads_mode == 'FIXED':
            threads = render.threads
    light_paths = cycles_settings(scene) if scene is not None else {}
    return RenderSettings(
        **light_paths,
        integrator=settings.integrator.lower(),
        noise_threshold=settings.noise_threshold if settings.use_adaptive_sampling else 0.0,
        min_samples=settings.adaptive_min_samples,
        time_limit=settings.time_limit,
        seed=settings.seed,
        semantics=settings.semantics.lower(),
        precision=settings.precision.lower(),
        max_depth=settings.max_depth,
        anti_aliasing=settings.anti_aliasing.lower(),
        samples=settings.samples,
        light_samples=settings.light_samples,
        world_samples=settings.world_samples,
        threads=threads,
        film=film,
        parallelism=settings.parallelism.lower(),
        cluster=settings.cluster_address,
    )


@dataclass
class JobResult:
    """What ``RenderJob.run`` returns: image (module docstring), the precision the core
    rendered in ('float64' or 'float32') and its ray counts; parallelism: how the tiles ran
    ('threads' or 'processes', ``core.RenderResult.parallelism``); fallback: the core's one
    line when worker processes could not start (``core.RenderResult.fallback``), else None."""

    image: np.ndarray
    precision: str
    stats: RayStats
    passes: Optional[object] = None   # core.passes.PrimaryPasses when run(passes=True)
    parallelism: str = "threads"
    fallback: Optional[str] = None
    denoised: bool = False   # the image was denoised after its tiles landed
    #: (H, W, 3) float32 the first hits' albedo and normal (denoising's guides, the
    #: Denoising Albedo and Normal passes), when the job asked for them; else None.
    albedo: Optional[np.ndarray] = None
    normal: Optional[np.ndarray] = None


@dataclass
class RenderJob:
    scene: Scene
    settings: RenderSettings   # its film: Film > Transparent (``render_settings``)
    warnings: list[str] = field(default_factory=list)
    #: Denoise the final image (Glint's Denoise option, path tracing): with Open Image
    #: Denoise guided by the first hits' albedo and normal (``addon.utils.denoise``).
    denoise: bool = False

    @property
    def size(self) -> tuple[int, int]:
        return self.scene.camera.width, self.scene.camera.height

    def scene_linear(self, image: np.ndarray) -> np.ndarray:
        """The job's image (or a part of it) as Blender's scene-linear, premultiplied render
        result, float32 (a copy): unchanged in default semantics, the inverse sRGB of the
        article's display values in article semantics (so view transform Standard shows the
        article's numbers)."""
        return render_result_pixels(image, self.settings.semantics)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one float32 RGBA copy of the frame (what Blender's render result or an
        Image datablock holds)."""
        width, height = self.size
        return width * height * 4 * 4

    def run(self, progress: Optional[Callable[[float], None]] = None,
            should_cancel: Optional[Callable[[], bool]] = None,
            reserve_bytes: int = 0,
            on_tile: Optional[Callable[[tuple, np.ndarray], None]] = None,
            passes=False, guides: bool = False) -> JobResult:
        """The finished frame (module docstring).  Raises core.RenderCancelled if
        should_cancel() answers True, core.SceneError for settings the core rejects or a
        render that cannot fit in memory with ``reserve_bytes`` more (the caller's copies).
        on_tile(tile, rgba): each tile as it lands (``core.render``'s tile, rows from the top),
        its pixels finished as the frame's will be (a copy the callee may keep).
        passes: also compute the render passes (``core.passes``) into JobResult.passes (a
        ``PrimaryPasses`` given here is filled in place, tile by tile, before on_tile).
        guides: also return the denoising guides (JobResult.albedo and .normal)."""
        def finished_tile(tile, rgba):
            on_tile(tile, np.array(rgba, np.float32, copy=True))

        denoising = self.denoise and denoise_available()
        settings = (dataclasses.replace(self.settings, guides=True) if denoising or guides
                    else self.settings)
        result = render(self.scene, settings, progress=progress,
                        should_cancel=should_cancel, image_dtype=np.float32,
                        reserve_bytes=reserve_bytes,
                        on_tile=finished_tile if on_tile is not None else None,
                        passes=passes)
        image = result.image
        denoised = denoising and result.albedo is not None
        if denoised:
            image = np.array(image, np.float32, copy=True)
            image[..., :3] = denoise(image[..., :3], result.albedo, result.normal)
        copy = (lambda a: None if a is None else np.array(a, np.float32, copy=True))  # noqa: E731
        return JobResult(image, result.precision, result.stats, result.passes,
                         result.parallelism, result.fallback, denoised,
                         copy(result.albedo), copy(result.normal))


def failure_message(error: BaseException) -> str:
    """One line for the user about an error that ended a render, whatever it is.

    Glint's own errors (export, validation, memory planning) already are that line; running
    out of memory says what to lower; anything else is a bug, named by its type and first
    line (with ``GLINT_DEBUG`` set, its traceback goes to stderr too)."""
    if isinstance(error, (ExportError, SceneError)):
        return str(error)
    if isinstance(error, MemoryError):
        return ("Glint ran out of memory while rendering: lower the resolution, the samples "
                "or the number of spheres")
    if isinstance(error, KeyboardInterrupt):
        return "Glint render interrupted"
    if os.environ.get(DEBUG_VARIABLE):
        traceback.print_exception(error)
    detail = str(error).strip().splitlines()
    detail = f": {detail[0]}" if detail else ""
    return f"Glint failed with an internal error ({type(error).__name__}{detail})"


def prepare_job(depsgraph, camera_override=None) -> RenderJob:
    """Export the scene and read its Glint settings (main thread only).  Raises ExportError
    or core.SceneError with a message meant for the user."""
    scene, warnings = export_scene(depsgraph, camera_override)
    warnings += ignored_settings_warning(depsgraph, camera_override)
    blender_scene = depsgraph.scene_eval
    settings = render_settings(blender_scene.glint, blender_scene.render, blender_scene)
    return RenderJob(scene=scene, settings=settings, warnings=warnings,
                     denoise=bool(blender_scene.glint.use_denoising)
                     and settings.integrator == "path" and settings.semantics == "default")


class ThreadedRender:
    """Renders on a worker thread, pass after pass, while the main thread stays free: the
    Render button's job (``of_job``: one pass) and the viewport's refinement
    (``viewport.ProgressiveRender``: coarse to final).

    The thread runs only the passes (NumPy, no Blender data).  The main thread polls
    ``fraction`` (of the pass running), ``result`` (the latest finished pass's, None before
    the first) and ``done``, and asks for a stop with ``cancel``, which the core honours
    between tiles; after it no later pass replaces ``result``.  ``cancelled``: a stop was
    asked for; ``error``: what ended the passes otherwise (reported by the caller);
    ``result_times``: seconds from the start to each finished pass.

    passes: callables ``(progress, should_cancel) -> result``.  on_result (called on the
    worker thread, so it must not touch Blender data) is told of each finished pass's result.
    """

    def __init__(self, passes, on_result: Optional[Callable] = None,
                 name: str = "glint-render"):
        self.passes = list(passes)
        self.fraction = 0.0
        self.result = None
        self.error: Optional[BaseException] = None
        self.started = time.perf_counter()
        self.result_times: list[float] = []
        self._on_result = on_result
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @classmethod
    def of_job(cls, job: RenderJob) -> "ThreadedRender":
        """The Render button's render: the job in one pass, with room kept for the Image it
        is stored in."""
        def run(progress, should_cancel) -> JobResult:
            return job.run(progress=progress, should_cancel=should_cancel,
                           reserve_bytes=job.frame_bytes)
        return cls([run])

    def _progress(self, fraction: float) -> None:
        self.fraction = fraction

    def _run(self) -> None:
        for run_pass in self.passes:
            try:
                result = run_pass(self._progress, self._stop.is_set)
            except RenderCancelled:
                return
            except BaseException as error:  # reported to the user by the caller
                self.error = error
                return
            if not self._publish(result):
                return

    def _publish(self, result) -> bool:
        """Make ``result`` the latest (a pass's, or a picture a pass shows on its way) and
        tell on_result; False, and nothing shown, once a stop was asked for."""
        with self._lock:
            if self._stop.is_set():
                return False
            self.result = result
            self.result_times.append(time.perf_counter() - self.started)
        if self._on_result is not None:
            self._on_result(result)
        return True

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
