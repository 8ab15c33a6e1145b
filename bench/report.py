"""The Markdown report: the results table, the targets with PASS/FAIL, the cost curves."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .suite import BASELINE_LABEL, CURVE_GLINTS, GLINT_PLAIN, Bench, CurvePoint, Glint, Row

MIB = 2 ** 20

#: Target (1): float64-accurate means a max error of at most this (in [0, 1] units).
ACCURATE = 1e-6
#: The article scene's speed targets at article-hd's size.
BASELINE_SPEEDUP, CYCLES1_SPEEDUP = 12.0, 10.0
DEFAULT_OVER_ARTICLE = 1.3      # default/auto's time at most this times article/float64's
TWO_WORKERS_SPEEDUP = 1.8       # 2 worker processes against 1
MAX_SPREAD = 1.2                # max / min of the article row's timed runs
ADAPTIVE_TIME_FRACTION, CYCLES16_SPEEDUP = 0.25, 20.0
#: Target (2b): on the dense field adaptive AA reaches fixed 16's RMS in this share of its time.
DENSE_TIME_FRACTION = 1 / 3
SPHERES_SLOWDOWN = 5.0
#: Time linear in pixels: time per pixel at the largest size over that at the reference size.
LINEAR_RANGE = (0.8, 1.25)
#: Memory flat: working memory (peak minus the image) at the largest size over the reference.
FLAT_MEMORY_RATIO = 1.25


def _seconds(value: Optional[float]) -> str:
    if value is None:
        return "—"
    return f"{value:.3g}" if value < 100 else f"{value:.0f}"


def _error(value: Optional[float]) -> str:
    if value is None:
        return "—"
    return "0" if value == 0 else f"{value:.2g}"


def _memory(row: Row) -> str:
    if row.timing.peak_bytes is None:
        return "—"
    mib = row.timing.peak_bytes / MIB
    text = f"{mib:,.0f}" if mib >= 10 else f"{mib:.2g}"
    return text + " (RSS)" if row.memory_kind == "rss" else text


def _runs(row: Row) -> str:
    runs = row.timing.runs
    if row.kind == "per-pixel" or len(runs) == 1:  # per-pixel runs are unscaled: not shown
        return str(len(runs))
    return f"{len(runs)} ({_seconds(min(runs))}–{_seconds(max(runs))})"


def _speedup(row: Row, baseline: Optional[Row]) -> str:
    if baseline is None or row is baseline:
        return "—" if baseline is None else "1x"
    return f"{baseline.seconds / row.seconds:.2g}x"


def table(bench: Bench) -> list[str]:
    lines = [
        "| Workload | Contender | Precision | Time (s) | Timed runs (min–max s) | Speed-up vs baseline "
        "| Peak memory (MiB) | Max err (8-bit) | RMS err (8-bit) | Silhouette ≠ Workbench (outside floor band) "
        "| Notes |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for row in bench.rows:
        baseline = next((r for r in bench.rows if r.workload == row.workload
                         and r.kind == "baseline"), None)
        max_error = "ref" if row.is_reference else _error(row.max_error)
        rms_error = "ref" if row.is_reference else _error(row.rms_error)
        silhouette = ("—" if row.silhouette is None
                      else f"{row.silhouette} ({row.silhouette_outside_band})")
        lines.append(
            f"| {row.title} | {row.contender} | {row.precision or '—'} | "
            f"{_seconds(row.seconds)} | {_runs(row)} | {_speedup(row, baseline)} | "
            f"{_memory(row)} | {max_error} | {rms_error} | {silhouette} | "
            f"{'; '.join(row.notes)} |")
    return lines


# --------------------------------------------------------------------------------------------
# Targets

@dataclass
class Target:
    name: str
    status: str        # PASS | FAIL | NOT MEASURED | MEASURED (no target figure)
    details: str

    def line(self) -> str:
        return f"- **{self.status}** {self.name}: {self.details}"


def _find(bench: Bench, workload: str, contender: str) -> Optional[Row]:
    return next((r for r in bench.rows if r.workload == workload and r.contender == contender),
                None)


def _missing(name: str, what: str) -> Target:
    return Target(name, "NOT MEASURED", f"needs {what} (run without --only/--no-blender)")


def _status(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def target_accurate_speed(bench: Bench) -> Target:
    width, height = bench.plan.article_sizes["article-hd"]
    name = (f"(1) article {width}x{height} depth 3, float64-accurate: >= {BASELINE_SPEEDUP:g}x "
            f"the baseline and >= {CYCLES1_SPEEDUP:g}x Cycles at 1 spp (Glint on any number of "
            f"threads or workers; the baseline on one, Cycles on all cores)")
    candidates = [r for r in bench.rows if r.workload == "article-hd" and r.kind == "glint"
                  and r.semantics == "article" and r.max_error_raw is not None
                  and r.max_error_raw <= ACCURATE]
    # The parallelism workload's article/float64 images equal its accurate 1-thread image bit
    # for bit (asserted there), so its rows are float64-accurate too.
    if any(r.contender == Glint("article", "float64").label for r in candidates):
        candidates += [r for r in bench.rows if r.workload == "parallelism"
                       and r.contender.startswith(Glint("article", "float64").label + ",")
                       and "cold" not in r.contender]
    baseline = _find(bench, "article-hd", BASELINE_LABEL)
    cycles = _find(bench, "article-hd", "Cycles CPU, 1 spp")
    if not candidates or baseline is None or cycles is None:
        return _missing(name, "the article-hd workload with the baseline and Cycles")
    best = min(candidates, key=lambda r: r.seconds)
    vs_baseline = baseline.seconds / best.seconds
    vs_cycles = cycles.seconds / best.seconds
    return Target(name, _status(vs_baseline >= BASELINE_SPEEDUP and vs_cycles >= CYCLES1_SPEEDUP),
                  f"fastest accurate Glint = {best.contender} at {best.seconds:.3g} s; baseline "
                  f"{baseline.seconds:.3g} s -> {vs_baseline:.2f}x (needs {BASELINE_SPEEDUP:g}x); "
                  f"Cycles 1 spp {cycles.seconds:.3g} s -> {vs_cycles:.2f}x (needs "
                  f"{CYCLES1_SPEEDUP:g}x)")


def target_default_semantics(bench: Bench) -> Target:
    name = (f"(1b) article scene, default/auto within {DEFAULT_OVER_ARTICLE:g}x of "
            f"article/float64 (one run, all cores)")
    article = _find(bench, "article-hd", Glint("article", "float64").label)
    default = _find(bench, "article-hd", Glint("default", "auto").label)
    if article is None or default is None:
        return _missing(name, "the article-hd workload")
    ratio = default.seconds / article.seconds
    return Target(name, _status(ratio <= DEFAULT_OVER_ARTICLE),
                  f"{default.seconds:.3g} s / {article.seconds:.3g} s = {ratio:.2f}x")


def target_two_workers(bench: Bench) -> Target:
    name = (f"(1c) article scene, 2 worker processes >= {TWO_WORKERS_SPEEDUP:g}x as fast as 1 "
            f"(article/float64 and default/auto)")
    found = []
    for semantics, precision in (("article", "float64"), ("default", "auto")):
        label = Glint(semantics, precision).label
        one = _find(bench, "parallelism", f"{label}, 1 process")
        two = _find(bench, "parallelism", f"{label}, 2 processes")
        if one is None or two is None:
            return _missing(name, "the parallelism workload")
        found.append((label, one.seconds / two.seconds))
    return Target(name, _status(all(ratio >= TWO_WORKERS_SPEEDUP for _, ratio in found)),
                  "; ".join(f"{label}: {ratio:.2f}x" for label, ratio in found))


def target_spread(bench: Bench) -> Target:
    name = (f"(1d) run-to-run spread of the article row (max / min of its timed runs) under "
            f"{MAX_SPREAD:g}x")
    row = _find(bench, "article-hd", Glint("article", "float64").label)
    if row is None or len(row.timing.runs) < 2:
        return _missing(name, "the article-hd workload with at least 2 timed runs")
    spread = max(row.timing.runs) / min(row.timing.runs)
    return Target(name, _status(spread < MAX_SPREAD),
                  f"{row.contender}: {spread:.3f}x over {len(row.timing.runs)} runs")


def target_adaptive(bench: Bench) -> Target:
    name = (f"(2) adaptive AA ({bench.plan.aa_size[0]}x{bench.plan.aa_size[1]}) reaches "
            f"fixed-16's RMS error (vs {bench.plan.aa_reference_samples} spp) in <= 1/4 of its "
            f"time, and is >= 20x faster than Cycles at 16 spp")
    fixed = _find(bench, "aa-fixed16", Glint("article", "float64", "fixed", 16).label)
    adaptive = [r for r in bench.rows if r.workload == "aa-adaptive"
                and r.glint is not None and r.glint.semantics == "article"]
    size = bench.plan.aa_size
    cycles = next((r for r in bench.rows if r.contender == "Cycles CPU, 16 spp"
                   and r.title.startswith(f"article {size[0]}x{size[1]}")), None)
    if fixed is None or not adaptive or cycles is None:
        return _missing(name, "the aa-adaptive and aa-fixed16 workloads and Cycles at 16 spp")
    tried = ", ".join(f"{r.contender}: RMS {r.rms_error:.3g} in {r.seconds:.3g} s"
                      for r in adaptive)
    reaching = [r for r in adaptive if r.rms_error <= fixed.rms_error]
    head = (f"fixed 16 spp: RMS {fixed.rms_error:.3g} (8-bit steps) in {fixed.seconds:.3g} s; "
            f"{tried}")
    if not reaching:
        return Target(name, "FAIL", f"{head}; no adaptive setting reached fixed-16's RMS")
    best = min(reaching, key=lambda r: r.seconds)
    fraction = best.seconds / fixed.seconds
    vs_cycles = cycles.seconds / best.seconds
    ok = fraction <= ADAPTIVE_TIME_FRACTION and vs_cycles >= CYCLES16_SPEEDUP
    return Target(name, _status(ok),
                  f"{head}; fastest reaching it: {best.contender}, {fraction:.2f} of fixed-16's "
                  f"time (needs <= {ADAPTIVE_TIME_FRACTION:g}); Cycles 16 spp {cycles.seconds:.3g} s "
                  f"-> {vs_cycles:.2f}x (needs {CYCLES16_SPEEDUP:g}x)")


def target_dense_adaptive(bench: Bench) -> Target:
    width, height = bench.plan.dense_size
    name = (f"(2b) on {bench.plan.dense_count:,} spheres ({width}x{height}), adaptive AA "
            f"reaches fixed-16's RMS error (vs {bench.plan.dense_reference_samples} spp) in "
            f"<= 1/3 of its time")
    fixed = _find(bench, "aa-dense", Glint("article", "float64", "fixed", 16).label)
    adaptive = [r for r in bench.rows if r.workload == "aa-dense" and r.glint is not None
                and r.glint.semantics == "article" and r.glint.anti_aliasing == "adaptive"]
    if fixed is None or not adaptive:
        return _missing(name, "the aa-dense workload")
    tried = ", ".join(f"{r.contender}: RMS {r.rms_error:.3g} in {r.seconds:.3g} s"
                      for r in adaptive)
    head = (f"fixed 16 spp: RMS {fixed.rms_error:.3g} (8-bit steps) in {fixed.seconds:.3g} s; "
            f"{tried}")
    reaching = [r for r in adaptive if r.rms_error <= fixed.rms_error]
    if not reaching:
        return Target(name, "FAIL", f"{head}; no adaptive setting reached fixed-16's RMS")
    best = min(reaching, key=lambda r: r.seconds)
    fraction = best.seconds / fixed.seconds
    return Target(name, _status(fraction <= DENSE_TIME_FRACTION),
                  f"{head}; fastest reaching it: {best.contender}, {fraction:.2f} of fixed-16's "
                  f"time (needs <= {DENSE_TIME_FRACTION:.2f})")


def _reference_point(points: list[CurvePoint]) -> CurvePoint:
    """1920x1080 if the curve has it, else the point in the middle."""
    full_hd = [p for p in points if (p.width, p.height) == (1920, 1080)]
    return full_hd[0] if full_hd else points[len(points) // 2]


def target_scaling(bench: Bench) -> Target:
    width, height = bench.plan.spheres_size
    name = (f"(3) 1,000 spheres at {width}x{height} within 5x the article's time; time linear "
            f"in pixels; peak memory flat in resolution apart from the image")
    parts, ok, measured = [], True, False
    ratios = []
    for glint in GLINT_PLAIN:
        spheres = _find(bench, "spheres", glint.label)
        article = _find(bench, "article-hd", glint.label)
        if spheres is not None and article is not None:
            ratios.append(f"{glint.semantics}/{glint.precision} {spheres.seconds / article.seconds:.2f}x")
            ok &= spheres.seconds <= SPHERES_SLOWDOWN * article.seconds
    if ratios:
        measured = True
        parts.append("1,000 spheres / article (same size, each Glint setting): " + ", ".join(ratios)
                     + f" (each needs <= {SPHERES_SLOWDOWN:g}x)")
    for glint in CURVE_GLINTS:
        points = sorted((p for p in bench.curve_points
                         if p.curve == "cost-pixels" and p.contender == glint.label),
                        key=lambda p: p.pixels)
        if len(points) < 3:
            continue
        measured = True
        largest, reference = points[-1], _reference_point(points)
        per_pixel = (largest.seconds / largest.pixels) / (reference.seconds / reference.pixels)
        linear = LINEAR_RANGE[0] <= per_pixel <= LINEAR_RANGE[1]
        sizes = ", ".join(f"{p.width}x{p.height} {p.seconds / p.pixels * 1e6:.2f}"
                          for p in points if p.pixels >= reference.pixels)
        text = (f"{glint.label}: time per pixel at {largest.width}x{largest.height} = "
                f"{per_pixel:.2f} x that at {reference.width}x{reference.height} "
                f"(needs {LINEAR_RANGE[0]:g}..{LINEAR_RANGE[1]:g}; µs per pixel: {sizes})")
        ok &= linear
        if largest.peak_bytes is not None and reference.peak_bytes is not None:
            working_large = largest.peak_bytes - largest.image_bytes
            working_ref = reference.peak_bytes - reference.image_bytes
            ratio = working_large / max(working_ref, 1)
            ok &= ratio <= FLAT_MEMORY_RATIO
            text += (f"; working memory (peak - image) {working_large / MIB:.0f} MiB vs "
                     f"{working_ref / MIB:.0f} MiB = {ratio:.2f}x (needs <= {FLAT_MEMORY_RATIO:g}x)")
        parts.append(text)
    if not measured:
        return _missing(name, "the spheres, article-hd and cost-pixels workloads")
    if not ratios:
        parts.append("sphere ratio not measured")
        ok = False
    return Target(name, _status(ok), "; ".join(parts))


def target_float32(bench: Bench) -> Target:
    name = ("(4) float32 measurably faster than float64 where 'auto' picks it "
            "(1,000 spheres without the floor, default semantics)")
    f32 = _find(bench, "spheres-nofloor", Glint("default", "float32").label)
    f64 = _find(bench, "spheres-nofloor", Glint("default", "float64").label)
    auto = _find(bench, "spheres-nofloor", Glint("default", "auto").label)
    if f32 is None or f64 is None or auto is None:
        return _missing(name, "the spheres-nofloor workload")
    speedup = f64.seconds / f32.seconds
    separated = max(f32.timing.runs) < min(f64.timing.runs)
    ok = auto.precision == "float32" and speedup > 1.0 and separated
    return Target(name, _status(ok),
                  f"auto picked {auto.precision}; float64 {f64.seconds:.3g} s, float32 "
                  f"{f32.seconds:.3g} s -> {speedup:.2f}x; slowest float32 run "
                  f"{max(f32.timing.runs):.3g} s vs fastest float64 run {min(f64.timing.runs):.3g} s "
                  f"({'separated' if separated else 'overlapping'}); float32 error vs float64 "
                  f"reference: max {f32.max_error:.2g}, RMS {f32.rms_error:.2g} (8-bit steps)")


#: The scale targets: Glint's F12 within this factor of Cycles' on a million
#: point-cloud spheres, and faster than Cycles on 100,000 instanced spheres.
POINTS_SLOWDOWN, INSTANCES_SLOWDOWN = 5.0, 1.0


def _largest(bench: Bench, kinds) -> list[dict]:
    """The ``bench.scale`` results of these kinds at the largest count each was run at."""
    chosen = []
    for kind in kinds:
        results = [r for r in bench.scale_results if r["kind"] == kind]
        if results:
            chosen.append(max(results, key=lambda r: r["count"]))
    return chosen


def _versus_cycles(result: dict) -> str:
    glint, cycles, alike = result["glint"], result["cycles"], result["similarity"]
    r = "—" if alike["r"] is None else f"{alike['r']:.3f}"
    return (f"{result['title']}: Glint {glint['median_s']:.3g} s (export "
            f"{glint['export_s']:.3g} s, core {glint['core_s']:.3g} s) vs Cycles "
            f"{cycles['median_s']:.3g} s = {glint['median_s'] / cycles['median_s']:.2f}x "
            f"Cycles' time; similarity r {r}")


def target_scale_points(bench: Bench) -> Target:
    name = (f"(scale 1) 1,000,000 point-cloud spheres at 640x360: Glint's F12 (export "
            f"included) within {POINTS_SLOWDOWN:g}x Cycles' (1 spp, whole render)")
    results = _largest(bench, ("points",))
    if not results:
        return _missing(name, "the scale-points workload")
    (result,) = results
    ratio = result["glint"]["median_s"] / result["cycles"]["median_s"]
    partial = "" if result["count"] >= 1_000_000 else " (fewer points than the target's)"
    return Target(name, _status(ratio <= POINTS_SLOWDOWN),
                  _versus_cycles(result) + f" (needs <= {POINTS_SLOWDOWN:g}x){partial}")


def target_scale_instances(bench: Bench) -> Target:
    name = ("(scale 2) 100,000 instanced sphere objects at 640x360 faster than Cycles, export "
            "included (Geometry Nodes instances, vertex instances, linked duplicates)")
    results = _largest(bench, ("instances", "vertex-instances", "duplicates"))
    if not results:
        return _missing(name, "the scale-instances workload")
    ok = all(r["glint"]["median_s"] < INSTANCES_SLOWDOWN * r["cycles"]["median_s"]
             for r in results)
    return Target(name, _status(ok), "; ".join(_versus_cycles(r) for r in results))


def target_scale_suzanne(bench: Bench) -> Target:
    name = "(scale 3) a 1,000,000-triangle Suzanne over a floor at 1920x1080, Cycles beside it"
    results = _largest(bench, ("suzanne",))
    if not results:
        return _missing(name, "the scale-suzanne workload")
    return Target(name, "MEASURED", _versus_cycles(results[0]) + " (no time target)")


def target_scale_export(bench: Bench) -> Target:
    name = "(scale 4) export time for a million instances"
    results = [r for r in bench.scale_results if r["kind"] == "export"]
    if not results:
        return _missing(name, "the scale-export workload")
    return Target(name, "MEASURED", "; ".join(
        f"{r['count']:,} {r['case']}: export_scene {r['export_s']:.3g} s" for r in results))


def target_scale_noise(bench: Bench) -> Target:
    name = ("(scale 5) instanced spheres at equal noise: Glint's F12 at each world-sample "
            "count against Cycles' time to the same noise (bench.noise; no time target)")
    results = [r for r in bench.scale_results if r["kind"] == "noise"]
    if not results:
        return _missing(name, "the scale-noise workload")
    from .noise import summary

    result = results[-1]
    return Target(name, "MEASURED", f"{result['title']}: " + "; ".join(
        summary(result)[:len(result["glint"])]))


def targets(bench: Bench) -> list[Target]:
    return [target_accurate_speed(bench), target_default_semantics(bench),
            target_two_workers(bench), target_spread(bench),
            target_adaptive(bench), target_dense_adaptive(bench),
            target_scaling(bench), target_float32(bench)] + scale_targets(bench)


def scale_targets(bench: Bench) -> list[Target]:
    return [target_scale_points(bench), target_scale_instances(bench),
            target_scale_suzanne(bench), target_scale_export(bench), target_scale_noise(bench)]


# --------------------------------------------------------------------------------------------

def curve_table(bench: Bench, curve: str) -> list[str]:
    points = [p for p in bench.curve_points if p.curve == curve]
    if not points:
        return []
    lines = ["| Contender | Size | Spheres | Time (s) | Timed runs | µs per pixel | "
             "Peak (MiB) | Image (MiB) | Peak − image (MiB) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for p in points:
        peak = "—" if p.peak_bytes is None else f"{p.peak_bytes / MIB:,.1f}"
        working = "—" if p.peak_bytes is None else f"{(p.peak_bytes - p.image_bytes) / MIB:,.1f}"
        lines.append(f"| {p.contender} | {p.width}x{p.height} | {p.spheres} | "
                     f"{_seconds(p.seconds)} | {p.runs} | {p.seconds / p.pixels * 1e6:.3g} | "
                     f"{peak} | {p.image_bytes / MIB:,.1f} | {working} |")
    return lines


def fitted_exponent(counts, seconds) -> float:
    """k of the least-squares fit seconds ~ counts^k (a straight line in log-log)."""
    return float(np.polyfit(np.log(counts), np.log(seconds), 1)[0])


def curve_exponents(bench: Bench, curve: str) -> list[str]:
    """For each contender and size of a sphere-count curve: the fitted exponent over all its
    points and over its last decade (logarithmic cost would fit near 0), of the whole render
    and, for Glint, of its tiles alone: the tracing, whose cost a tree makes logarithmic,
    without the frame's set-up, whose build is linear in the spheres at best."""
    if curve == "cost-pixels":
        return []
    lines = []
    groups = {}
    for p in bench.curve_points:
        if p.curve == curve:
            groups.setdefault((p.contender, p.width, p.height), []).append(p)
    for (contender, width, height), points in groups.items():
        points = sorted(points, key=lambda p: p.spheres)
        if len(points) < 3:
            continue
        counts = np.array([p.spheres for p in points], float)
        measured = [("", [p.seconds for p in points])]
        if all(p.tile_seconds for p in points):
            measured.append((" (tiles alone)", [p.tile_seconds for p in points]))
        for what, seconds in measured:
            seconds = np.array(seconds)
            tail = counts >= counts[-1] / 10
            tail_text = (f", {fitted_exponent(counts[tail], seconds[tail]):.2f} from "
                         f"{int(counts[tail][0]):,}" if tail.sum() >= 2 else "")
            lines.append(f"- {contender} at {width}x{height}{what}: time ~ spheres^k with k = "
                         f"{fitted_exponent(counts, seconds):.2f} over {int(counts[0]):,} to "
                         f"{int(counts[-1]):,}{tail_text}")
        if all(p.rays for p in points):
            lines.append(_per_ray_line(contender, width, height, points, counts))
    return lines + ([""] if lines else [])


def _per_ray_line(contender, width, height, points, counts) -> str:
    """A curve's time split into the rays the scene makes (camera, shadow and reflection
    rays a pixel: more spheres, more of the frame hit) and the cost of each: the render's
    time a ray (the median's wall time: the tiles' own timers are summed over threads, and
    a thread waiting for the GIL or for a table another builds counts its wait), fitted as
    the time is, and the box and primitive tests a ray at each point (a logarithmic
    structure adds about as many per decade)."""
    per_ray = np.array([p.seconds / p.rays for p in points])
    per_pixel = [p.rays / p.pixels for p in points]
    tests = ", ".join(f"{p.tests / p.rays:.1f} at {p.spheres:,}" for p in points)
    return (f"- {contender} at {width}x{height}, per traced ray ({min(per_pixel):.2f}-"
            f"{max(per_pixel):.2f} rays a pixel): the render's time a ray ~ spheres^k with k = "
            f"{fitted_exponent(counts, per_ray):.2f} over {int(counts[0]):,} to "
            f"{int(counts[-1]):,} ({1e6 * per_ray[0]:.2f} to {1e6 * per_ray[-1]:.2f} us); "
            f"box and primitive tests a ray: {tests}")


def phase_table(bench: Bench) -> list[str]:
    """Where the time goes: the per-phase timers of one single-thread render per row."""
    if not bench.phases:
        return []
    names = list(bench.phases[0][2].phases())
    lines = ["| Workload | Contender | Tiles (s) | " + " | ".join(names) + " |",
             "|---|---|---:|" + "---:|" * len(names)]
    for title, contender, stats in bench.phases:
        total = stats.seconds_tiles
        cells = [f"{seconds:.3f} ({100 * seconds / total:.0f} %)" if total else "—"
                 for seconds in stats.phases().values()]
        lines.append(f"| {title} | {contender} | {total:.3f} | " + " | ".join(cells) + " |")
    return lines
