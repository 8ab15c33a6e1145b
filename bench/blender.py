"""Blender's own renderers (Cycles on the CPU, Workbench) on the article's scene, via pip bpy.

The scene is the add-on's own builder (``addon.utils.article_scene.build_article_scene``): UV
spheres of 64 x 32 segments on the article's radii, in the article's Y-up coordinates, the
camera at (0, 0, 1) with no rotation, sensor_width / lens = 2 fitted horizontally, the point
light at (5, 5, 5), a black world, view transform Standard.  On top of that the bench sets:
film_transparent (alpha = coverage, for silhouettes), no dithering, Cycles on the CPU with a
fixed sample count (no adaptive sampling, no denoising), Workbench with render_aa OFF.

Renders run in this process (``BlenderSession``).  Resident memory cannot be attributed
inside a process that also holds the other contenders, so ``measure_memory`` renders once
more in a child process (``python -m bench.blender ...``, this module's ``main``) that resets
its high-water mark (``/proc/self/clear_refs``) just before the render and reports VmHWM minus
VmRSS: the memory the render added.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CYCLES, WORKBENCH = "CYCLES", "BLENDER_WORKBENCH"


class BlenderUnavailable(RuntimeError):
    """bpy (or the add-on's scene builder) cannot be imported here."""


@dataclass(frozen=True)
class BlenderJob:
    """One Blender render of the article's scene: engine, samples (Cycles), size."""

    engine: str
    samples: int
    width: int
    height: int
    floor_only: bool = False  # every sphere but the floor hidden (for silhouette bands)

    @property
    def label(self) -> str:
        if self.engine == CYCLES:
            return f"Cycles CPU, {self.samples} spp"
        return "Workbench (render_aa OFF)" + (", floor only" if self.floor_only else "")


@contextlib.contextmanager
def quiet_output():
    """Send the C-level stdout and stderr (Blender's per-render chatter) to /dev/null."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


def render_result_rgba(bpy, scene, path: str) -> np.ndarray:
    """(H, W, 4) float64 of Blender's last render ("Render Result" saved through ``scene``'s
    colour management to the PNG ``path``, removed after), row 0 = top, RGB composited over
    black like Glint's images; alpha = coverage."""
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    image = bpy.data.images.load(path, check_existing=False)
    try:
        image.colorspace_settings.name = 'Non-Color'
        width, height = image.size
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
        os.remove(path)
    rgba = pixels.reshape(height, width, 4)[::-1].astype(np.float64)
    rgba[..., :3] *= rgba[..., 3:]  # PNG alpha is straight; Glint's RGB is over black
    return rgba


class BlenderSession:
    """bpy imported and the add-on registered, once per process."""

    def __init__(self):
        if REPOSITORY not in sys.path:
            sys.path.insert(0, REPOSITORY)
        try:
            with quiet_output():
                import bpy
                import render as render_script  # the repository's render.py

                glint = render_script.import_glint()
                bpy.ops.wm.read_factory_settings(use_empty=True)
                render_script.register_glint(glint)
                from glint.addon.utils.article_scene import build_article_scene
        except ImportError as error:
            raise BlenderUnavailable(f"cannot import Blender ({error})") from None
        self._bpy = bpy
        self._build = build_article_scene
        self._scenes = {}
        self._folder = tempfile.mkdtemp(prefix="glint-bench-")

    def scene(self, job: BlenderJob):
        """The article's scene set up for ``job`` (built once per job)."""
        if job in self._scenes:
            return self._scenes[job]
        scene = self._build(f"bench {len(self._scenes)}", width=job.width, height=job.height,
                            engine=job.engine)
        scene.render.film_transparent = True
        scene.render.dither_intensity = 0.0
        settings = scene.render.image_settings
        settings.file_format = 'PNG'
        settings.color_mode = 'RGBA'
        settings.color_depth = '16'
        if job.engine == CYCLES:
            scene.cycles.device = 'CPU'
            scene.cycles.samples = job.samples
            scene.cycles.use_adaptive_sampling = False
            scene.cycles.use_denoising = False
        else:
            scene.display.render_aa = 'OFF'
        if job.floor_only:
            meshes = [obj for obj in scene.objects if obj.type == 'MESH']
            floor = max(meshes, key=lambda obj: max(obj.dimensions))
            for obj in meshes:
                obj.hide_render = obj.name != floor.name
        self._scenes[job] = scene
        return scene

    def render(self, job: BlenderJob) -> None:
        scene = self.scene(job)
        with quiet_output():
            self._bpy.ops.render.render(scene=scene.name)

    def last_image(self, job: BlenderJob) -> np.ndarray:
        """(H, W, 4) float64 of the last render, row 0 = top: RGB as displayed (view transform
        Standard), composited over black like Glint's images; alpha = coverage."""
        with quiet_output():
            return render_result_rgba(self._bpy, self.scene(job),
                                      os.path.join(self._folder, "result.png"))


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field}")


def measure_memory(job: BlenderJob, timeout: float = 1800) -> int:
    """Resident memory in bytes that one render of ``job`` adds, in a child process."""
    command = [sys.executable, "-m", "bench.blender", job.engine, str(job.samples),
               str(job.width), str(job.height)]
    done = subprocess.run(command, cwd=REPOSITORY, capture_output=True, text=True,
                          timeout=timeout)
    for line in reversed(done.stdout.splitlines()):
        if line.startswith("{"):
            return int(json.loads(line)["added_bytes"])
    raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()[-500:]}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench.blender",
        description="Render the article's scene once and print the resident memory it added.")
    parser.add_argument("engine", choices=[CYCLES, WORKBENCH])
    parser.add_argument("samples", type=int)
    parser.add_argument("width", type=int)
    parser.add_argument("height", type=int)
    args = parser.parse_args(argv)
    job = BlenderJob(args.engine, args.samples, args.width, args.height)
    session = BlenderSession()
    session.scene(job)
    with open("/proc/self/clear_refs", "w") as clear_refs:
        clear_refs.write("5")  # resets VmHWM to the current VmRSS
    before = _status_kib("VmRSS")
    session.render(job)
    peak = _status_kib("VmHWM")
    print(json.dumps({"added_bytes": (peak - before) * 1024}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
