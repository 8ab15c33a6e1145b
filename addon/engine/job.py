"""What every Glint render does, whoever starts it (render engine, Render button, render.py).

``prepare_job`` runs on Blender's main thread: it exports the evaluated scene and reads the
settings, so the job holds plain data only.  ``RenderJob.run`` touches no Blender data and may
run on any thread; it returns the finished image:

* (H, W, 4) float32, row 0 = top, the core's values: default semantics scene-linear radiance
  (unclipped), article semantics the article's display values; ``scene_linear`` turns
  either into what Blender's render result holds;
* Film > Transparent off: alpha 1, the background is the world colour;
* Film > Transparent on: alpha = sphere coverage, and the background the camera rays saw is
  removed, leaving premultiplied colour (Blender's convention for render results).  A camera
  ray that misses contributes exactly the background (default semantics: unclipped; the
  article's never adds one), so subtracting (1 - coverage) * background removes those samples
  exactly; reflections of the world stay.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ...core import RenderCancelled, RenderSettings, Scene, render
from ..export import export_scene
from ..utils.colour import premultiplied_to_scene_linear


def render_settings(settings) -> RenderSettings:
    """``Scene.glint`` (a GlintRenderSettings) -> core RenderSettings."""
    return RenderSettings(
        semantics=settings.semantics.lower(),
        precision=settings.precision.lower(),
        max_depth=settings.max_depth,
        anti_aliasing=settings.anti_aliasing.lower(),
        samples=settings.samples,
        light_samples=settings.light_samples,
    )


@dataclass
class RenderJob:
    scene: Scene
    settings: RenderSettings
    transparent: bool
    warnings: list[str] = field(default_factory=list)
    precision: Optional[str] = None   # set by run: the precision the core chose

    @property
    def size(self) -> tuple[int, int]:
        return self.scene.camera.width, self.scene.camera.height

    def run(self, progress: Optional[Callable[[float], None]] = None,
            should_cancel: Optional[Callable[[], bool]] = None) -> np.ndarray:
        """The finished image (module docstring).  Raises core.RenderCancelled if
        should_cancel() answers True, core.SceneError for settings the core rejects."""
        result = render(self.scene, self.settings, progress=progress,
                        should_cancel=should_cancel)
        self.precision = result.precision
        return finish_image(result.image, self.scene, self.settings, self.transparent)

    def scene_linear(self, image: np.ndarray) -> np.ndarray:
        """The job's image (``run``) as Blender's scene-linear, premultiplied render result:
        unchanged in default semantics, the inverse sRGB transfer of the article's display
        values in article semantics (so view transform Standard shows the article's numbers)."""
        if self.settings.semantics == "article":
            return premultiplied_to_scene_linear(image)
        return np.asarray(image, np.float32)


def finish_image(image: np.ndarray, scene: Scene, settings: RenderSettings,
                 transparent: bool) -> np.ndarray:
    """The core's (H, W, 4) image -> the job's image (module docstring)."""
    finished = np.array(image, np.float32, copy=True)
    if not transparent:
        finished[..., 3] = 1.0
        return finished
    if settings.semantics == "default":  # the article's semantics never add a background
        background = np.asarray(scene.background, np.float32)
        finished[..., :3] -= (1.0 - finished[..., 3:4]) * background
        np.maximum(finished[..., :3], 0.0, out=finished[..., :3])
    return finished


def prepare_job(depsgraph, camera_override=None) -> RenderJob:
    """Export the scene and read its Glint settings (main thread only).  Raises ExportError
    or core.SceneError with a message meant for the user."""
    scene, warnings = export_scene(depsgraph, camera_override)
    blender_scene = depsgraph.scene_eval
    return RenderJob(scene=scene, settings=render_settings(blender_scene.glint),
                     transparent=blender_scene.render.film_transparent, warnings=warnings)


class ThreadedRender:
    """A RenderJob running on a worker thread, for the Render button's modal operator.

    The thread runs only ``RenderJob.run`` (NumPy, no Blender data); the operator polls
    ``fraction`` and ``done`` from timer events on the main thread and asks for a stop with
    ``cancel``, which the core honours between tiles.
    """

    def __init__(self, job: RenderJob):
        self.job = job
        self.fraction = 0.0
        self.image: Optional[np.ndarray] = None
        self.error: Optional[BaseException] = None
        self.cancelled = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="glint-render", daemon=True)
        self._thread.start()

    def _progress(self, fraction: float) -> None:
        self.fraction = fraction

    def _run(self) -> None:
        try:
            self.image = self.job.run(progress=self._progress, should_cancel=self._stop.is_set)
        except RenderCancelled:
            self.cancelled = True
        except BaseException as error:  # reported to the user by the operator
            self.error = error

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def cancel(self) -> None:
        self._stop.set()

    def wait(self, timeout: Optional[float] = None) -> bool:
        self._thread.join(timeout)
        return self.done
