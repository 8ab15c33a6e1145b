"""Memory planned before tracing, not discovered in a MemoryError.

``plan`` estimates what a render holds at its peak, from three terms:

* the image: H x W x 4 values of the image's dtype, allocated once (every later step, the
  add-on's hand-over and the PNG writer, works on it in place or a block of rows at a time);
* tracing: per worker thread, a bundle of rays (at most ``tile_size^2`` camera rays, or one
  pixel's samples, whichever is more) at ``BYTES_PER_BUNDLE_RAY``, plus the finished tiles in
  flight;
* the scene: ``BYTES_PER_SPHERE`` for each sphere, loose or in a sphere set (its arrays, its
  share of the aggregate and the (ray, node) pairs a packet can see), ``BYTES_PER_TRIANGLE``
  for each triangle of each mesh instance, plus the per-origin terms of every light sample.

The constants are measured peaks (tracemalloc; the article scene, 20,000 and 200,000 random
spheres with a hard and a soft light, a 79,202-triangle mesh drawn 10 times; 64 x 64 to
1024 x 1024, 1 and 2 threads: 320-1,200 bytes a sphere, 404 a triangle), rounded up, so the
plan errs on the side of refusing.  (A dense field's depth-ordered bins for the eye,
``core.geometry.bins``, add about 55 bytes a sphere held and 370 while they are built, once, in the
rendering process, which shares them with its workers (``Aggregate.build_frame_tables``):
tracemalloc on the 10^6 sphere set at 1080p.  A sun's parallel bins,
``core.geometry.bins.ParallelBins``, hold about 6 entries of 24 bytes a sphere in each process that
traces the sun's rays, where they are built: frames of at least as many pixels as the tree
has spheres.)  ``check`` compares the plan with the memory this machine has available
(``/proc/meminfo``'s MemAvailable, and a cgroup's limit if lower) and raises
``NotEnoughMemory`` (a SceneError: every entry point reports it as one line) saying how much
the render needs and what to lower.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .scene import Scene
from .settings import RenderSettings
from .validation import SceneError

#: Peak working bytes per ray of a traced bundle (measured ~800, see the module docstring).
BYTES_PER_BUNDLE_RAY = 1024
#: Peak bytes per sphere through the aggregate (measured 320-1,200).
BYTES_PER_SPHERE = 2 * 1024
#: Peak bytes per triangle of a mesh instance (measured 404 before the SAH build; with it,
#: 511 for 300,000 random triangles through the clustered build, the path of every mesh
#: of 50,000 triangles or more; below that up to 869, at most 43 MB in all).
BYTES_PER_TRIANGLE = 640
#: Per-origin terms per sphere and light sample (float64 values a ray/sphere test reuses).
BYTES_PER_SPHERE_TERMS = 8 * 8
#: What the process needs besides the render (interpreter, NumPy, Blender): not planned for,
#: but kept free.
HEADROOM = 256 * 1024 ** 2


class NotEnoughMemory(SceneError):
    """The render cannot fit in this machine's memory; the message says how much it needs
    and what to lower."""


@dataclass(frozen=True)
class MemoryPlan:
    image: int      # bytes
    tracing: int
    scene: int
    other: int = 0  # bytes the caller holds besides the render (e.g. Blender's result)
    images: tuple = ()  # ((name, bytes), ...) of the textures the scene's shaders read

    @property
    def texture_bytes(self) -> int:
        return sum(size for _, size in self.images)

    @property
    def total(self) -> int:
        return self.image + self.tracing + self.scene + self.other + self.texture_bytes

    def what_to_lower(self) -> str:
        largest = max(("image", self.image + self.other), ("tracing", self.tracing),
                      ("scene", self.scene), ("textures", self.texture_bytes),
                      key=lambda item: item[1])[0]
        if largest == "textures":
            name, size = max(self.images, key=lambda item: item[1])
            return f"use smaller textures (image '{name}' alone takes {_gb(size)})"
        return {"image": "lower the resolution (or its percentage)",
                "tracing": "lower the samples, the tile size or the threads",
                "scene": "use fewer spheres, triangles or light samples"}[largest]


#: The denoising guides' channels beside RGBA (``RenderSettings.guides``: albedo, normal).
GUIDE_CHANNELS = 6


def plan(scene: Scene, settings: RenderSettings, image_dtype, threads: int,
         other_bytes: int = 0) -> MemoryPlan:
    """What a render of ``scene`` holds at its peak (module docstring)."""
    width, height = scene.camera.width, scene.camera.height
    channels = 4 + (GUIDE_CHANNELS if settings.guides else 0)
    image = width * height * channels * np.dtype(image_dtype).itemsize
    from .context import path_traced
    if path_traced(scene, settings):
        # A progressive frame's float32 totals, and the buffer its tiles' sums land in.
        from .progressive import GUIDE_SUM_CHANNELS, SUM_CHANNELS
        sums = SUM_CHANNELS + (GUIDE_SUM_CHANNELS if settings.guides else 0)
        image += 2 * width * height * sums * 4
    samples = settings.samples if settings.anti_aliasing != "off" else 1
    bundle = max(settings.tile_size ** 2, samples)
    in_flight = 2 * threads * settings.tile_size ** 2 * 4 * 8
    tracing = threads * bundle * BYTES_PER_BUNDLE_RAY + in_flight
    spheres, triangles = scene.sphere_count, scene.triangle_count   # (per instance)
    light_samples = sum(settings.light_samples if light.radius > 0 else 1
                        for light in scene.lights)
    scene_bytes = (spheres * (BYTES_PER_SPHERE + (1 + light_samples) * BYTES_PER_SPHERE_TERMS)
                   + triangles * BYTES_PER_TRIANGLE)
    return MemoryPlan(image, tracing, scene_bytes, other_bytes, texture_sizes(scene))


def texture_sizes(scene: Scene) -> tuple:
    """((name, bytes), ...) of each image the scene's shader programs read (materials and
    world), each counted once however many programs share it."""
    from .shader.images import ImageData

    programs = [getattr(material, "program", None) for material in _materials(scene)]
    programs.append(getattr(scene, "world", None))
    found = {}

    def visit(value):
        if isinstance(value, ImageData):
            found.setdefault(id(value.texels), (value.name, int(value.texels.nbytes)))
        elif isinstance(value, (tuple, list)):
            for item in value:
                visit(item)

    for program in programs:
        for instruction in getattr(program, "instructions", ()):
            visit(instruction.arguments)
            visit(tuple(value for _, value in instruction.options))
    return tuple(found.values())


def _materials(scene: Scene):
    for sphere in scene.spheres:
        yield sphere.material
    for group in (*scene.sphere_sets, *scene.meshes):
        yield from group.materials


def available_memory() -> Optional[int]:
    """Bytes this process can still allocate without swapping, or None if unknown."""
    candidates = []
    try:
        with open("/proc/meminfo") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    candidates.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as limit, \
                open("/sys/fs/cgroup/memory.current") as current:
            text = limit.read().strip()
            if text != "max":
                candidates.append(int(text) - int(current.read().strip()))
    except (OSError, ValueError):
        pass
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            return None
    return max(0, min(candidates))


def _texture_text(memory_plan: MemoryPlan) -> str:
    return f", textures {_gb(memory_plan.texture_bytes)}" if memory_plan.images else ""


def _gb(size: int) -> str:
    return f"{size / 1e9:.1f} GB"


def check(memory_plan: MemoryPlan, width: int, height: int,
          available: Optional[int] = None) -> None:
    """Raise NotEnoughMemory when ``memory_plan`` does not fit in ``available`` bytes
    (default: ``available_memory()``; unknown: no check)."""
    available = available_memory() if available is None else available
    if available is None or memory_plan.total + HEADROOM <= available:
        return
    raise NotEnoughMemory(
        f"a {width}x{height} render needs about {_gb(memory_plan.total)} of memory "
        f"(image {_gb(memory_plan.image + memory_plan.other)}, tracing "
        f"{_gb(memory_plan.tracing)}, scene {_gb(memory_plan.scene)}"
        f"{_texture_text(memory_plan)}) but "
        f"{_gb(available)} is available: {memory_plan.what_to_lower()}")
