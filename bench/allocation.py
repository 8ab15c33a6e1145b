"""Page faults and system time per render with and without Glint's malloc settings.

``python -m bench.allocation [--width W --height H --threads N --renders K]`` (or the
bench's ``malloc`` workload) renders the article's scene (depth 3, float64, article
semantics) in fresh child processes, alternating glibc's defaults and ``core.allocator``'s
settings, and reports per render, after one warm-up render in each child: wall, user and
system seconds and minor page faults (``getrusage``).  Child processes, because the settings
cannot be taken back inside one.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = """
import json, resource, sys, time
import core
from core import allocator
tuned, width, height, threads, renders = json.loads(sys.argv[1])
if tuned and not allocator.configure():
    print(json.dumps(None)); sys.exit()
scene = core.article_scene(width, height)
settings = core.article_settings(threads=threads)
core.render(scene, settings)
runs = []
for _ in range(renders):
    before, start = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    core.render(scene, settings)
    after, end = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    runs.append({"wall": end - start, "user": after.ru_utime - before.ru_utime,
                 "sys": after.ru_stime - before.ru_stime,
                 "faults": after.ru_minflt - before.ru_minflt})
print(json.dumps(runs))
"""


def measure(tuned: bool, width: int, height: int, threads: int, renders: int):
    """Per-render measurements of one child process (None: the settings do not apply)."""
    done = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps([tuned, width, height, threads, renders])],
        capture_output=True, text=True, cwd=REPOSITORY, check=True,
        env={**os.environ, "PYTHONPATH": REPOSITORY})
    return json.loads(done.stdout)


def compare(width=1920, height=1080, threads=1, renders=3, children=2) -> dict:
    """{'default': runs, 'tuned': runs}: every render of ``children`` alternating children."""
    results = {"default": [], "tuned": []}
    for _ in range(children):
        for name in results:
            runs = measure(name == "tuned", width, height, threads, renders)
            if runs is None:
                return {"default": results["default"], "tuned": None}
            results[name] += runs
    return results


def summary(runs) -> str:
    def span(key, fmt):
        values = [run[key] for run in runs]
        return f"{fmt(min(values))}-{fmt(max(values))}"

    return (f"faults {span('faults', lambda v: f'{v:,}')}, sys {span('sys', '{:.3f}'.format)} s, "
            f"user {span('user', '{:.3f}'.format)} s, wall {span('wall', '{:.3f}'.format)} s")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.allocation", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--renders", type=int, default=3, help="timed renders per child")
    parser.add_argument("--children", type=int, default=2, help="child processes per mode")
    args = parser.parse_args(argv)
    results = compare(args.width, args.height, args.threads, args.renders, args.children)
    for name, runs in results.items():
        print(f"{name:8} " + ("not applicable (not Linux with glibc)" if runs is None
                              else summary(runs)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
