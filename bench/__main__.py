"""``python -m bench [--quick | --full] [--only WORKLOAD ...] [--repeats N] [--budget S]``

Runs every workload in this one process, one after another (never two at once, so that
contenders do not share the cores), prints a Markdown report (machine, table, targets, cost
curves) and writes plots, results.md and results.json to bench/out/.  Progress goes to stderr.
Run it from the repository root with the project's Python (.venv/bin/python).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

from core import allocator

from . import report
from .measure import load_average, machine_lines
from .plots import PlotsUnavailable, write_plots
from .suite import FULL, QUICK, WORKLOADS, Bench

OUT_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "out")


def parse_args(argv):
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_true",
                      help="small sizes and one timed run each: a smoke run of about 2 minutes")
    mode.add_argument("--full", action="store_true", help="the real sizes (the default)")
    parser.add_argument("--only", action="append", metavar="WORKLOAD",
                        help=f"run only these workloads (repeatable or comma-separated): "
                             f"{', '.join(WORKLOADS)}")
    parser.add_argument("--repeats", type=int, metavar="N",
                        help="timed runs per contender after the warm-up (default 3, quick 1)")
    parser.add_argument("--budget", type=float, metavar="SECONDS",
                        help="a slow contender gets only as many timed runs as fit in this "
                             "(at least one; default 40, quick 5)")
    parser.add_argument("--no-blender", action="store_true",
                        help="skip the Cycles and Workbench contenders")
    parser.add_argument("--no-malloc-tuning", action="store_true",
                        help="keep glibc's default malloc thresholds (core.allocator)")
    parser.add_argument("--out", default=OUT_DIR, help="output folder (default bench/out)")
    args = parser.parse_args(argv)
    names = []
    for item in args.only or []:
        for name in filter(None, (part.strip() for part in item.split(","))):
            if name not in WORKLOADS:
                parser.error(f"--only: unknown workload {name!r}; choose from "
                             f"{', '.join(WORKLOADS)}")
            names.append(name)
    args.workloads = names or list(WORKLOADS)
    if args.repeats is not None and args.repeats < 1:
        parser.error("--repeats must be at least 1")
    if args.budget is not None and args.budget < 0:
        parser.error("--budget must be >= 0")
    return args


def plan_lines(plan, quick: bool) -> list[str]:
    def size(pair):
        return f"{pair[0]}x{pair[1]}"

    return [
        f"Plan: {'QUICK (reduced sizes; targets indicative only)' if quick else 'FULL'}; "
        f"{plan.repeats} timed run(s) per contender after one warm-up (fewer if a contender's "
        f"warm-up exceeds the {plan.budget:g} s budget); time = median.  The machine may be "
        f"shared with other work: see the load averages and each row's min–max.",
        f"Sizes: article {', '.join(size(s) for s in plan.article_sizes.values())}; "
        f"{plan.sphere_count} spheres {size(plan.spheres_size)} (errors at "
        f"{size(plan.spheres_error_size)}); AA {size(plan.aa_size)} (errors at "
        f"{size(plan.aa_error_size)} vs {plan.aa_reference_samples} spp); dense field "
        f"{plan.dense_count:,} spheres {size(plan.dense_size)} (errors vs "
        f"{plan.dense_reference_samples} spp); per-pixel program "
        f"timed at {size(plan.per_pixel_article_size)} (article) and "
        f"{size(plan.per_pixel_spheres_size)} (spheres); sphere sets of "
        f"{', '.join(f'{c:,}' for c in plan.sphere_set_counts)} at "
        f"{size(plan.sphere_set_size)} and {', '.join(f'{c:,}' for c in plan.sphere_set_hd[1])} "
        f"at {size(plan.sphere_set_hd[0])}.",
        f"Scale cases (bench.scale, KIND:COUNT:WIDTHxHEIGHT): "
        f"{'; '.join(', '.join(cases) for cases in plan.scale_cases.values())}; export of "
        f"{', '.join(f'{c:,}' for c in plan.scale_export_counts)} instances; noise "
        f"(bench.noise) on {plan.noise_case[0]}: Glint at {plan.noise_case[1]} world samples "
        f"against {plan.noise_case[2]}, Cycles at {plan.noise_case[3]} spp against "
        f"{plan.noise_case[4]}.",
        "Threads: Glint one per core; baseline and per-pixel program one (NumPy); Cycles all "
        "cores.  Memory: tracemalloc peak of the warm-up run (Python/NumPy contenders), "
        "resident-set growth of one render in a child process (Blender, marked RSS).",
        "Errors: 8-bit steps (x255) vs a float64 reference of the same semantics (article: "
        "the baseline; default: Glint float64 with contribution_cutoff=0).  Silhouette: pixels "
        "where alpha > 0.5 differs from Workbench's (render_aa OFF, film_transparent); in "
        "brackets, those outside the floor band (pixels where the analytic floor sphere and "
        "Blender's 64x32 UV-sphere floor, sagitta ~10 units, disagree on their own).",
    ]


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if not args.no_malloc_tuning:
        allocator.configure()  # the bench's process is Glint's own (core.allocator)
    plan = QUICK if args.quick else FULL
    overrides = {}
    if args.repeats is not None:
        overrides["repeats"] = args.repeats
    if args.budget is not None:
        overrides["budget"] = args.budget
    plan = dataclasses.replace(plan, **overrides)
    tuning = ("on (core.allocator: mmap threshold 32 MiB, trim threshold 512 MiB)"
              if allocator.configure() else "off") if not args.no_malloc_tuning else "off"
    header = ["# Glint bench", ""] + [f"- {line}" for line in machine_lines()] + [
        f"- glibc malloc tuning: {tuning}"]
    bench = Bench(plan, args.out, use_blender=not args.no_blender)
    start = time.perf_counter()
    bench.run(args.workloads)
    elapsed = time.perf_counter() - start

    lines = header + [f"- Load average at end: {load_average()}; bench took {elapsed:.0f} s",
                      ""]
    lines += [f"- {line}" for line in plan_lines(plan, args.quick)] + [""]
    lines += report.table(bench) + [""]
    if bench.notes:
        lines += ["Notes:", ""] + [f"- {note}" for note in bench.notes] + [""]
    lines += ["## Targets (ratios measured in this run)", ""]
    lines += [target.line() for target in report.targets(bench)] + [""]
    phases = report.phase_table(bench)
    if phases:
        lines += ["## Where the time goes (per-phase timers, one thread)", ""] + phases + [""]
    for curve, title in (("cost-pixels", "Cost against pixel count (article scene)"),
                         ("cost-spheres", "Cost against sphere count"),
                         ("cost-sphere-sets", "Cost against sphere count, spheres as one "
                                              "SphereSet")):
        rows = report.curve_table(bench, curve)
        if rows:
            lines += [f"## {title}", ""] + rows + [""] + report.curve_exponents(bench, curve)

    os.makedirs(args.out, exist_ok=True)
    try:
        written = write_plots(bench, args.out)
        lines += ["Plots: " + ", ".join(_shown(path) for path in written)]
    except PlotsUnavailable as error:
        lines += [f"Plots skipped: {error}."]
    text = "\n".join(lines) + "\n"
    print(text)
    with open(os.path.join(args.out, "results.md"), "w") as out:
        out.write(text)
    with open(os.path.join(args.out, "results.json"), "w") as out:
        json.dump({"rows": [_row_json(r) for r in bench.rows],
                   "curves": [dataclasses.asdict(p) for p in bench.curve_points],
                   "targets": [dataclasses.asdict(t) for t in report.targets(bench)],
                   "notes": bench.notes, "scale": bench.scale_results}, out, indent=1)
    return 0


def _shown(path: str) -> str:
    """A path relative to the working directory when it lies inside it."""
    relative = os.path.relpath(path)
    return path if relative.startswith("..") else relative


def _row_json(row) -> dict:
    data = dataclasses.asdict(row)
    data["glint"] = None if row.glint is None else row.glint.label
    return data


if __name__ == "__main__":
    sys.exit(main())
