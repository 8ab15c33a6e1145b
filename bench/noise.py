"""Speed against noise: Glint's world samples and Cycles' samples on one of bench.scale's scenes.

    .venv/bin/python -m bench.noise CASE:COUNT:WIDTHxHEIGHT [--glint 1,4,9,16]
        [--glint-reference 256] [--cycles 1,2,4,8,16,32] [--cycles-reference 1024]
        [--repeats N] [--budget S] [--out DIR]

bench.scale times Glint's F12 (the Whitted integrator, anti-aliasing off) against Cycles' at 1
sample a pixel; the two images are not equally noisy. Glint's only noise in these scenes (a sun
of angle 0) is the world's occlusion, estimated from ``world_samples`` fixed directions a point
(``core.shading``); Cycles' is its path tracing at ``samples`` a pixel. This module renders
the case's scene (``bench.scale.build``: the same scene, camera, sun and world) through F12
with Glint at several world-sample counts and Cycles at several sample counts, each timed as
bench.scale times them (``measure_render``), and measures each image's noise against the same
engine's own converged image (Glint at ``--glint-reference`` world samples, Cycles at
``--cycles-reference`` samples): the RMS difference of the display values (view transform
Standard, 8-bit steps, RGB over black), per pixel and in 8 x 8 boxes. Each engine against its
own reference, so this is noise, not bias (Glint, a Whitted tracer, has no indirect light and
converges to a darker picture than Cycles). Glint's images are not anti-aliased (its pixel
centres), Cycles' are (its samples spread over each pixel), so Cycles' noise includes the
edges' sampling as well.

``equal_noise`` then reads off, for each Glint count, the time Cycles takes to reach the same
per-pixel RMS: interpolated in log-log between the two Cycles counts that bracket it, or,
when Glint's image is less noisy than every Cycles image measured, extrapolated (and flagged
so): the samples from the two least noisy counts' noise, the time affine in the samples.
It writes ``OUT/noise-KIND-COUNT.png``: the image's central quarter, Glint on the left and
Cycles on the right, at the fewest samples timed, the most and the reference, top to bottom.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time

import numpy as np

from . import scale

#: The 8-bit steps the errors are counted in.
STEPS = 255.0
#: Box size of the box RMS (bench.scale's similarity box).
BOX = scale.SIMILARITY_BOX


def noise(image: np.ndarray, reference: np.ndarray) -> dict:
    """RMS difference of two (H, W, 4) display images' RGB in 8-bit steps: per pixel
    ('rms'), of 8 x 8 box means ('box_rms', what is left once a viewer's eye averages the
    grain), and the 99th percentile of the per-pixel differences ('p99')."""
    difference = (np.asarray(image, np.float64)[..., :3]
                  - np.asarray(reference, np.float64)[..., :3]) * STEPS
    boxes = scale._boxes(difference, BOX)
    return {"rms": float(np.sqrt(np.mean(difference ** 2))),
            "box_rms": float(np.sqrt(np.mean(boxes ** 2))),
            "p99": float(np.percentile(np.abs(difference), 99))}


def equal_noise(rms: float, points: list) -> dict:
    """The samples (a real number) and seconds at which the engine measured at ``points``
    [(samples, seconds, rms), ...] reaches per-pixel ``rms``. The samples: a straight line in
    log-log (noise against samples) between the two counts whose noise brackets ``rms``,
    else through the two least (or most) noisy counts, flagged 'extrapolated'. The seconds:
    between bracketing counts, the same straight line in log-log (time against samples);
    beyond them, time affine in the samples (a fixed cost and a cost a sample, fitted to
    every count) and never less than the slowest count measured. Needs two points with
    distinct noise."""
    points = sorted(points, key=lambda p: -p[2])          # noisiest first
    if len(points) < 2:
        raise ValueError("equal_noise needs at least two measured counts")
    logs = [(math.log(n), math.log(s), math.log(e)) for n, s, e in points]
    target = math.log(rms)
    pair = next(((a, b) for a, b in zip(logs, logs[1:]) if b[2] <= target <= a[2]), None)
    extrapolated = pair is None
    if pair is None:
        pair = (logs[-2], logs[-1]) if target < logs[-1][2] else (logs[0], logs[1])
    (n0, s0, e0), (n1, s1, e1) = pair
    if e0 == e1:
        raise ValueError("equal_noise: two counts measured the same noise")
    f = (target - e0) / (e1 - e0)
    samples = math.exp(n0 + f * (n1 - n0))
    if not extrapolated:
        seconds = math.exp(s0 + f * (s1 - s0))
    else:
        counts = np.array([p[0] for p in points], float)
        times = np.array([p[1] for p in points], float)
        per_sample, fixed = np.polyfit(counts, times, 1)
        seconds = max(fixed + per_sample * samples, times.max()) if samples > counts.max() \
            else min(max(fixed + per_sample * samples, 0.0), times.min())
    return {"samples": samples, "seconds": float(seconds), "extrapolated": extrapolated}


def _crops(images: list) -> np.ndarray:
    """The central quarter of each (H, W, 4) image, one above the other."""
    height, width = images[0].shape[:2]
    rows, columns = slice(height // 4, height // 4 + max(height // 2, 1)), \
        slice(width // 4, width // 4 + max(width // 2, 1))
    return np.concatenate([image[rows, columns] for image in images], axis=0)


def _counts(text: str) -> tuple:
    try:
        counts = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected counts like 1,4,9") from None
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: counts must be positive")
    return counts


def measure_case(case: scale.Case, glint_counts, glint_reference: int, cycles_counts,
                 cycles_reference: int, repeats: int, budget: float, out: str) -> dict:
    """Build ``case`` and render it (bpy, this process); the JSON result (module docstring)."""
    import bpy

    scale.build(case)
    scene = bpy.context.scene
    result = {"case": case.spec, "title": case.title}
    strips = {}
    for engine, counts, reference in (("GLINT", glint_counts, glint_reference),
                                      ("CYCLES", cycles_counts, cycles_reference)):
        scene.render.engine = engine
        entries, images = [], {}
        for count in tuple(counts) + (reference,):
            if engine == "GLINT":
                scene.glint.world_samples = count
            else:
                scene.cycles.samples = count
            work = scale.f12(scene, engine, case.spec)
            if count == reference:          # a reference is rendered once, not timed
                start = time.perf_counter()
                work()
                runs = [time.perf_counter() - start]
            else:
                runs, _ = scale.measure_render(work, repeats, budget)
            images[count] = scale._render_image(engine, out)
            entries.append({"samples": count, "runs": runs,
                            "median_s": statistics.median(runs)})
        for entry in entries:
            entry.update(noise(images[entry["samples"]], images[reference]))
        result[engine.lower()] = entries[:-1]
        result[engine.lower() + "_reference"] = entries[-1]
        strips[engine] = _crops([images[counts[0]], images[counts[-1]], images[reference]])
    picture = os.path.join(out, f"noise-{case.kind}-{case.count}.png")
    scale._save_side_by_side(picture, strips["GLINT"], strips["CYCLES"])
    result["picture"] = picture
    cycles = [(e["samples"], e["median_s"], e["rms"]) for e in result["cycles"]]
    result["equal_noise"] = [dict(equal_noise(e["rms"], cycles), world_samples=e["samples"])
                             for e in result["glint"]] if len(cycles) >= 2 else []
    return result


def run(case: scale.Case, glint_counts, glint_reference: int, cycles_counts,
        cycles_reference: int, repeats: int, budget: float, out: str,
        timeout: float = 7200) -> dict:
    """``measure_case`` in a child process of its own (as bench.scale runs its cases)."""
    return scale.child_result(
        [sys.executable, "-m", "bench.noise", case.spec,
         "--glint", ",".join(map(str, glint_counts)), "--glint-reference", str(glint_reference),
         "--cycles", ",".join(map(str, cycles_counts)),
         "--cycles-reference", str(cycles_reference),
         "--repeats", str(repeats), "--budget", str(budget), "--out", out], timeout)


def summary(result: dict) -> list[str]:
    """One line per Glint count: its time and noise, and Cycles' time at the same noise."""
    lines = []
    matched = {m["world_samples"]: m for m in result["equal_noise"]}
    for entry in result["glint"]:
        line = (f"Glint, {entry['samples']} world samples: {entry['median_s']:.3g} s, "
                f"RMS {entry['rms']:.3g} steps (boxes {entry['box_rms']:.2g})")
        match = matched.get(entry["samples"])
        if match is not None:
            how = "extrapolated" if match["extrapolated"] else "interpolated"
            line += (f"; Cycles at that noise: {match['seconds']:.3g} s "
                     f"(~{match['samples']:.3g} samples, {how})")
        lines.append(line)
    for entry in result["cycles"]:
        lines.append(f"Cycles, {entry['samples']} samples: {entry['median_s']:.3g} s, RMS "
                     f"{entry['rms']:.3g} steps (boxes {entry['box_rms']:.2g})")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.noise",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("case", metavar="KIND:COUNT:WIDTHxHEIGHT")
    parser.add_argument("--glint", type=_counts, default=(1, 4, 9, 16),
                        help="Glint's world samples to time (default 1,4,9,16)")
    parser.add_argument("--glint-reference", type=int, default=256)
    parser.add_argument("--cycles", type=_counts, default=(1, 2, 4, 8, 16, 32),
                        help="Cycles' samples to time (default 1,2,4,8,16,32)")
    parser.add_argument("--cycles-reference", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget", type=float, default=40.0)
    parser.add_argument("--out", default=os.path.join(scale.REPOSITORY, "bench", "out"))
    args = parser.parse_args(argv)
    try:
        case = scale.Case.parse(args.case)
    except ValueError as error:
        parser.error(str(error))
    for name, counts, reference in (("glint", args.glint, args.glint_reference),
                                    ("cycles", args.cycles, args.cycles_reference)):
        if reference <= max(counts):
            parser.error(f"--{name}-reference must exceed every --{name} count")
    from .blender import quiet_output

    scale.start_blender(args.out)
    with quiet_output():
        result = measure_case(case, args.glint, args.glint_reference, args.cycles,
                              args.cycles_reference, args.repeats, args.budget, args.out)
    for line in summary(result):
        print(line, file=sys.stderr)
    print(json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
