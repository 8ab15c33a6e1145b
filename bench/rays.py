"""Rays per second by kind: how fast the geometry answers a path tracer's rays.

``python -m bench.rays [--samples N] [--repeats R] SCENE ...`` renders each scene on one
thread and reports, for each kind of ray, how many the geometry traced, the CPU seconds it
spent on them (this process's CPU time, which other work on a shared machine disturbs far
less than wall time), microseconds a ray and rays a second, with the box and primitive
tests a ray made:

* camera: nearest hits of batches that share an origin (the eye);
* bounce: nearest hits of rays leaving surfaces;
* shadow: occlusion of segments (next-event estimation's, the world's).

A SCENE is a pickle of ``(core.Scene, core.RenderSettings)`` (as the add-on exports them;
rendered with ``samples`` samples a pixel, no adaptive stop) or a bench scene:
``mesh-and-spheres`` (``bench.scenes.mesh_and_spheres_scene``: triangles and spheres under
the path integrator).  The best of ``repeats`` renders is reported (after one render
that builds nothing twice).  To compare two checkouts, run this from each in turn,
alternating, on the same scenes.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import os
import pickle
import pkgutil
import sys
import time
import types
from contextlib import contextmanager

import core
from core.geometry import Aggregate

from .scenes import mesh_and_spheres_scene

KINDS = ("camera", "bounce", "shadow")


def _alias_glint():
    """Pickles the add-on writes name the core as ``glint.core``: alias it to ``core``."""
    if "glint.core" in sys.modules:
        return
    glint = types.ModuleType("glint")
    glint.__path__ = []
    sys.modules["glint"] = glint
    sys.modules["glint.core"] = core
    for module in pkgutil.walk_packages(core.__path__, "core."):
        if not module.name.split(".")[-1].startswith("_"):
            sys.modules["glint." + module.name] = importlib.import_module(module.name)


def load(scene: str, samples: int):
    """(name, core.Scene, core.RenderSettings) of a SCENE argument (module docstring)."""
    if scene == "mesh-and-spheres":
        return scene, mesh_and_spheres_scene(), core.RenderSettings(samples=samples, threads=1)
    _alias_glint()
    with open(scene, "rb") as file:
        loaded, settings = pickle.load(file)
    settings = dataclasses.replace(settings, threads=1, samples=samples, noise_threshold=0)
    return os.path.basename(scene), loaded, settings


@contextmanager
def timed_kinds(totals: dict):
    """Within: every ``Aggregate.nearest`` and ``occluded`` call adds its rays, CPU seconds,
    box tests and primitive tests to ``totals[kind]``."""
    nearest, occluded = Aggregate.nearest, Aggregate.occluded

    def count(kind, call, self, rays, stats):
        before = (stats.node_tests, stats.triangle_tests + stats.sphere_tests)
        start = time.process_time()
        try:
            return call(self, rays, stats)
        finally:
            entry = totals.setdefault(kind, [0, 0.0, 0, 0])
            entry[0] += len(rays)
            entry[1] += time.process_time() - start
            entry[2] += stats.node_tests - before[0]
            entry[3] += stats.triangle_tests + stats.sphere_tests - before[1]

    Aggregate.nearest = lambda self, rays, stats: count(
        "camera" if rays.shared is not None else "bounce", nearest, self, rays, stats)
    Aggregate.occluded = lambda self, rays, stats: count("shadow", occluded, self, rays, stats)
    try:
        yield totals
    finally:
        Aggregate.nearest, Aggregate.occluded = nearest, occluded


def measure(scene, settings, repeats: int) -> dict:
    """{kind: (rays, seconds, box tests, primitive tests)}, the best of ``repeats`` renders
    per kind, and 'frame': the best render's CPU seconds."""
    core.render(scene, settings)
    best = {}
    for _ in range(repeats):
        totals = {}
        start = time.process_time()
        with timed_kinds(totals):
            core.render(scene, settings)
        totals["frame"] = [0, time.process_time() - start, 0, 0]
        for kind, entry in totals.items():
            if kind not in best or entry[1] < best[kind][1]:
                best[kind] = entry
    return best


def report(name: str, best: dict) -> str:
    parts = [f"{name}: frame {best['frame'][1]:.2f} s CPU"]
    for kind in KINDS:
        if kind not in best:
            continue
        rays, seconds, boxes, prims = best[kind]
        per_ray = 1e6 * seconds / max(rays, 1)
        parts.append(f"{kind} {rays} rays {seconds:.3f} s {per_ray:.2f} us/ray "
                     f"{rays / max(seconds, 1e-9) / 1e3:.0f}k rays/s, "
                     f"{boxes / max(rays, 1):.1f} boxes {prims / max(rays, 1):.1f} prims a ray")
    return "\n  ".join(parts)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="+", metavar="SCENE")
    parser.add_argument("--samples", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true",
                        help="print each scene's figures as one JSON line instead")
    args = parser.parse_args(argv)
    for scene in args.scenes:
        name, loaded, settings = load(scene, args.samples)
        best = measure(loaded, settings, args.repeats)
        print(json.dumps({"scene": name, **best}) if args.json else report(name, best),
              flush=True)


if __name__ == "__main__":
    main()
