"""Nested glass: what a path's depth costs, and how soon a render of it stops when cancelled.

``python -m bench.nested_glass [--width W --height H --samples N --layers K]`` renders K
concentric glass balls (a glass of liquid is two) under a sun, in front of a grey floor,
with the Light Paths' transmission and total bounces at 4, 16, 64 and 256, and prints for
each the CPU time of the render (one thread, this process: the machine's other work
lengthens wall time, not it), the peak memory NumPy and Python allocated (tracemalloc), the
rays traced by kind, and the time from a cancel request, made once the render has run a
second, to the render's end.

A path tracer follows one branch at a glass surface (reflection or refraction, chosen by
their Fresnel weights), so a path crosses each surface at most once per bounce: its cost
grows with the bounces its paths actually take, and never as 2^depth; its memory is the
tile's arrays, whatever the depth.  The Whitted integrator follows both branches while a
bounce stays within ``core.trace.BRANCH_BUDGET`` rays a camera ray, and one beyond it: its
rays a bounce are bounded too.
"""

from __future__ import annotations

import argparse
import itertools
import threading
import time

import core
from core.camera import BlenderCamera
from core.light_sources import SunLight
from core.materials import SurfaceMaterial
from core.scene import Scene, Sphere, TriangleMesh
from core.settings import RenderSettings

from .measure import load_average, traced_peak

LOOK_AT_ORIGIN = ((1, 0, 0, 0), (0, 0, -1, -6), (0, 1, 0, 0.3), (0, 0, 0, 1))  # from -Y


def nested_glass_scene(width: int, height: int, layers: int) -> Scene:
    """``layers`` concentric glass balls (radii from 1 down to 0.2) above a floor."""
    glass = SurfaceMaterial.principled(base_color=(1.0, 1.0, 1.0), roughness=0.0,
                                       transmission=1.0, ior=1.45)
    balls = tuple(Sphere((0.0, 0.0, 0.0), 1.0 - 0.8 * i / max(layers, 1), glass)
                  for i in range(layers))
    floor = TriangleMesh(((-6, -6, -1.01), (6, -6, -1.01), (6, 6, -1.01), (-6, 6, -1.01)),
                         ((0, 1, 2), (0, 2, 3)), None, (0, 0),
                         (SurfaceMaterial(diffuse=(0.5, 0.5, 0.5)),), name="floor")
    camera = BlenderCamera(LOOK_AT_ORIGIN, resolution_x=width, resolution_y=height, lens=50.0)
    return Scene(camera, balls, (SunLight((0.3, 0.4, -1.0), strength=3.0),),
                 meshes=(floor,), background=(0.05, 0.05, 0.05))


def settings_at(bounces: int, samples: int, integrator: str = "path") -> RenderSettings:
    if integrator == "whitted":   # (its Max Depth counts the camera ray)
        return RenderSettings(integrator="whitted", samples=samples, threads=1,
                              anti_aliasing="fixed", max_depth=min(bounces + 1, 256))
    return RenderSettings(samples=samples, threads=1, noise_threshold=0.0,
                          max_bounces=bounces, transmission_bounces=bounces,
                          transparent_bounces=bounces)


def cancel_latency(scene: Scene, settings: RenderSettings, after: float = 1.0):
    """Seconds from a cancel request, made ``after`` seconds into the render, to its end
    (None: the render finished first)."""
    asked = threading.Event()
    asked_at = []

    def ask():
        asked_at.append(time.perf_counter())
        asked.set()
    timer = threading.Timer(after, ask)
    timer.start()
    try:
        core.render(scene, settings, should_cancel=asked.is_set)
    except core.RenderCancelled:
        return time.perf_counter() - asked_at[0]
    finally:
        timer.cancel()
    return None


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=90)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--layers", type=int, default=5)
    args = parser.parse_args(argv)
    scene = nested_glass_scene(args.width, args.height, args.layers)
    print(f"# {args.layers} nested glass balls, {args.width} x {args.height}, "
          f"{args.samples} samples; {load_average()}")
    print(f"{'integrator':>10} {'bounces':>8} {'CPU s':>8} {'peak MB':>8} {'camera':>8} {'bounce':>9} "
          f"{'shadow':>9} {'cancel s':>9}")
    for integrator, bounces in itertools.product(("path", "whitted"), (4, 16, 64, 256)):
        settings = settings_at(bounces, args.samples, integrator)
        core.render(scene, settings)   # warm
        start = time.process_time()
        result, peak = traced_peak(lambda: core.render(scene, settings))
        seconds = time.process_time() - start
        stats = result.stats
        latency = cancel_latency(scene, settings_at(bounces, max(args.samples, 64), integrator))
        cancel = "finished" if latency is None else f"{latency:.2f}"
        print(f"{integrator:>10} {bounces:>8} {seconds:>8.2f} {peak / 2 ** 20:>8.1f} {stats.camera_rays:>8} "
              f"{stats.reflection_rays:>9} {stats.shadow_rays:>9} {cancel:>9}")


if __name__ == "__main__":
    main()
