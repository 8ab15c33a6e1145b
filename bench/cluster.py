"""Rendering on a Dask cluster against local worker processes, on the same cores, and a model of
scale-out from what was measured.

    .venv-dask/bin/python -m bench.cluster [--quick] [--repeats N] [--bandwidth MB_PER_S]

Needs ``dask[distributed]`` (requirements-dev.txt) and ``wheel`` (to build the core for the
workers without a download).  It installs the core as a worker does (``install_worker_core``:
pip, from pyproject.toml, into a temporary folder), starts a scheduler and 2 worker
processes of one thread each as the user guide says (``dask scheduler``, ``dask worker
ADDRESS --nthreads 1 --nworkers 2``, with GLINT_MALLOC_TUNING=1), and renders each frame in
turn with 2 local worker processes (``parallelism='processes'``) and through the cluster,
alternating, after a warm-up of each (the workers' imports and first frame are not timed);
time = median.

Frames: the article's scene at 1920x1080; a million spheres (``random_sphere_set_scene``) at
640x360; a 20-frame animation of the article's scene at 960x540 whose camera moves every
frame (each frame a new scene, sent once as any frame is).  Per frame it reports the bytes
sent (the scattered scene, to each worker, and the tiles' pixels back) and the phases the
model needs: the submitter's serial part, the time to pickle and scatter the scene, and the
tiles' seconds on the workers.

The model (``scale_out``): a frame on N workers takes its serial part (the context built
here, the workers checked), plus pickling and scattering the scene as measured here, plus
its travel over links of ``bandwidth``: Dask's scatter sends it from the submitter to the
scheduler and on to one worker, then ``replicate`` copies it in rounds in which every
holder serves up to two more workers (1, 3, 9, 27, 81 holders), each round two copies on a
holder's link: ``(2 + 2 ceil(log3 N))`` times its bytes over the bandwidth; plus the
longest of the tiles' seconds over N, the longest tile, and the pixels coming back over the
submitter's link; plus the cluster's cost per tile measured here (the tiles' phase on 2
workers less their work, divided by the tiles), which the model keeps at every N.
Speed-up is against the 2 local processes' time.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Workers of the model.
MODEL_WORKERS = (2, 4, 16, 64)
#: The link the model assumes between the submitter, the scheduler and the workers: 1 Gbit/s
#: Ethernet's payload, about 117 MB/s (the measurement here is over loopback).
DEFAULT_BANDWIDTH = 117e6


def install_worker_core(folder: str) -> str:
    """Glint's core installed by pip from the repository's pyproject.toml into ``folder``, as
    on a worker (without a download: no build isolation, no dependencies); returns the
    folder that holds the package."""
    source = os.path.join(folder, "source")
    site = os.path.join(folder, "site")
    os.makedirs(source)
    shutil.copy(os.path.join(REPOSITORY, "pyproject.toml"), source)
    shutil.copytree(os.path.join(REPOSITORY, "core"), os.path.join(source, "core"),
                    ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--no-index", "--no-build-isolation", "--target", site, source],
                   check=True, capture_output=True)
    return site


@contextlib.contextmanager
def dask_cluster(site: str, folder: str, workers: int = 2):
    """The address of a scheduler and ``workers`` worker processes started with Dask's
    command line, the core importable from ``site`` (ended on leaving)."""
    import distributed

    environment = {**os.environ, "PYTHONPATH": site, "GLINT_MALLOC_TUNING": "1"}
    scheduler_file = os.path.join(folder, "scheduler.json")
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=environment)
    started = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--port", "0",
                                 "--dashboard-address", ":0", "--scheduler-file",
                                 scheduler_file], **quiet)]
    try:
        deadline = time.monotonic() + 60
        while not os.path.exists(scheduler_file) and time.monotonic() < deadline:
            time.sleep(0.1)
        started.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", "--scheduler-file", scheduler_file,
             "--nthreads", "1", "--nworkers", str(workers), "--no-dashboard"], **quiet))
        with distributed.Client(scheduler_file=scheduler_file) as client:
            client.wait_for_workers(workers, timeout=120)
            address = client.scheduler.address
        yield address
    finally:
        for process in reversed(started):
            process.terminate()
            process.wait(30)


def _article_animation(frames: int, width: int, height: int):
    """The article's scene with its camera stepped sideways each frame."""
    import core

    base = core.article_scene(width, height)
    eye = np.asarray(base.camera.eye, float)
    return [dataclasses.replace(base, camera=dataclasses.replace(
        base.camera, eye=tuple(eye + (0.02 * k, 0.0, 0.0)))) for k in range(frames)]


def workloads(quick: bool) -> dict:
    """name -> (list of scenes rendered one after the other, settings)."""
    import core
    from bench.scenes import random_sphere_set_scene

    scale = 4 if quick else 1
    article = core.article_settings()
    return {
        "article 1920x1080": ([core.article_scene(1920 // scale, 1080 // scale)], article),
        "1,000,000 spheres 640x360": (
            [random_sphere_set_scene(1_000_000 // scale ** 2, 640, 360)],
            core.RenderSettings(semantics="article")),
        "20-frame animation 960x540": (_article_animation(20 // scale, 960, 540), article),
    }


def _render_all(scenes, settings) -> tuple[float, list[dict]]:
    """(seconds, what each frame sent) rendering ``scenes`` in turn."""
    import core
    from core import cluster

    sent = []
    start = time.perf_counter()
    for scene in scenes:
        began = time.perf_counter()
        core.render(scene, settings)
        if settings.cluster:
            sent.append({**cluster.last_render, "wall": time.perf_counter() - began})
    return time.perf_counter() - start, sent


def measure(name, scenes, settings, address, repeats: int) -> dict:
    local = dataclasses.replace(settings, threads=2, parallelism="processes")
    remote = dataclasses.replace(settings, threads=2, cluster=address)
    _render_all(scenes, local)        # warm-up: the local workers start
    _render_all(scenes, remote)       # warm-up: the cluster's workers import the core
    local_times, remote_times, frames = [], [], []
    for _ in range(repeats):
        local_times.append(_render_all(scenes, local)[0])
        seconds, sent = _render_all(scenes, remote)
        remote_times.append(seconds)
        frames = sent
    return {"name": name, "frames": len(scenes), "local": local_times, "cluster": remote_times,
            "sent": frames}


def scale_out(result: dict, bandwidth: float) -> dict:
    """Modelled seconds per frame and speed-up against 2 local processes for MODEL_WORKERS
    workers, and the worker count past which a frame gets no faster (module docstring)."""
    frames = result["sent"]
    local_frame = statistics.median(result["local"]) / result["frames"]
    cluster_frame = statistics.median(result["cluster"]) / result["frames"]
    tiles = statistics.mean(f["tiles"] for f in frames)
    tile_seconds = statistics.mean(sum(f["tile_seconds"]) for f in frames)
    longest = max(max(f["tile_seconds"]) for f in frames)
    scene_bytes = statistics.mean(f["frame_bytes"] for f in frames)
    result_bytes = statistics.mean(f["result_bytes"] for f in frames)
    pickle_seconds = statistics.mean(f["send_seconds"] for f in frames)
    tiles_wall = statistics.mean(f["tiles_wall_seconds"] for f in frames)
    # The submitter's serial part: the frame's wall time less sending the scene and the
    # tiles (the scene made canonical, the context and its tables built, the workers checked).
    serial = statistics.mean(f["wall"] - f["send_seconds"] - f["tiles_wall_seconds"]
                             for f in frames)
    # What the tiles' phase took on 2 workers beyond their work: the cluster's cost per
    # tile (a task's round trip, its pixels' transfer, landing), kept at every N.
    per_tile = max(0.0, tiles_wall - max(tile_seconds / 2, longest)) / tiles

    def seconds(n: int) -> float:
        rounds = math.ceil(math.log(n, 3) - 1e-9) if n > 1 else 0
        send = (2 + 2 * rounds) * scene_bytes / bandwidth
        tiles_part = max(tile_seconds / n, longest, result_bytes / bandwidth)
        return serial + pickle_seconds + send + tiles_part + per_tile * tiles

    model = {n: (seconds(n), local_frame / seconds(n)) for n in MODEL_WORKERS}
    best = min(range(1, 4097), key=seconds)
    return {"model": model, "best": best, "serial": serial, "pickle": pickle_seconds, "best_speedup": local_frame / seconds(best),
            "tiles": tiles, "tile_seconds": tile_seconds, "longest": longest,
            "scene_bytes": scene_bytes, "result_bytes": result_bytes, "per_tile": per_tile,
            "local_frame": local_frame, "cluster_frame": cluster_frame}


def report(results, models, bandwidth: float) -> list[str]:
    lines = ["| frame | 2 local processes | 2 cluster workers | overhead | scene sent per "
             "worker | pixels back | tiles |", "|---|---:|---:|---:|---:|---:|---:|"]
    for result in results:
        local, remote = statistics.median(result["local"]), statistics.median(result["cluster"])
        model = models[result["name"]]
        lines.append(
            f"| {result['name']} | {local:.3f} s ({min(result['local']):.3f}-"
            f"{max(result['local']):.3f}) | {remote:.3f} s ({min(result['cluster']):.3f}-"
            f"{max(result['cluster']):.3f}) | {100 * (remote / local - 1):+.1f} % | "
            f"{model['scene_bytes'] / 1e6:.3f} MB | {model['result_bytes'] / 1e6:.1f} MB | "
            f"{model['tiles']:.0f} |")
    lines += ["", f"Scale-out model at {bandwidth / 1e6:.0f} MB/s (per frame; speed-up "
                  f"against 2 local processes):", "",
              "| frame | tiles' seconds (longest) | serial + scene pickled and scattered "
              "here + per tile + a copy's travel | " +
              " | ".join(f"{n} workers" for n in MODEL_WORKERS) + " | best |",
              "|---|---:|---:|" + "---:|" * len(MODEL_WORKERS) + "---:|"]
    for result in results:
        model = models[result["name"]]
        cells = [f"{s:.2f} s ({x:.1f}x)" for s, x in model["model"].values()]
        lines.append(
            f"| {result['name']} (per frame) | {model['tile_seconds']:.2f} s "
            f"({model['longest']:.3f} s) | {model['serial']:.3f} s + "
            f"{model['pickle']:.3f} s + {model['per_tile'] * 1e3:.1f} ms/tile + "
            f"{model['scene_bytes'] / bandwidth:.3f} s/copy | " + " | ".join(cells) +
            f" | {model['best']} workers, {model['best_speedup']:.1f}x |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.cluster", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="smaller frames, one repeat")
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--bandwidth", type=float, default=DEFAULT_BANDWIDTH / 1e6,
                        metavar="MB_PER_S", help="the model's link (default 117: 1 Gbit/s)")
    parser.add_argument("--out", default=os.path.join(REPOSITORY, "bench", "out"),
                        help="folder for cluster.json, the measurements (default bench/out)")
    args = parser.parse_args(argv)
    repeats = args.repeats or (1 if args.quick else 3)
    bandwidth = args.bandwidth * 1e6

    from bench.measure import load_average, machine_lines
    from core import allocator, cluster

    allocator.configure()          # (this process is Glint's, as in python -m bench)
    header = [line.replace("python -m bench", "python -m bench.cluster")
              for line in machine_lines()]

    with tempfile.TemporaryDirectory(prefix="glint-bench-cluster-") as folder:
        with dask_cluster(install_worker_core(folder), folder) as address:
            results, models = [], {}
            for name, (scenes, settings) in workloads(args.quick).items():
                print(f"bench.cluster: {name} ...", file=sys.stderr, flush=True)
                result = measure(name, scenes, settings, address, repeats)
                models[name] = scale_out(result, bandwidth)
                results.append(result)
            cluster.close_clients()
    lines = header + [f"Load average at end: {load_average()}", ""] + report(results, models,
                                                                            bandwidth)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "cluster.json"), "w") as stream:
        json.dump({"lines": lines, "results": results, "models": models}, stream, indent=1)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
