"""What an image texture costs: exporting a big PNG, and looking texels up.

    .venv/bin/python -m bench.images [--sizes 8192 16384] [--points 2073600] [--repeat 3]

For each size, an 8-bit RGBA PNG (opaque, a procedural pattern) is written to a temporary
folder, then a fresh child process (pip bpy, headless) loads it as Blender image (not yet
read) and exports it through the add-on (``addon.export.images.ImageExporter``), reporting:

* the export's peak memory: the process's resident peak (VmHWM, reset just before the
  export through /proc/self/clear_refs) minus its resident size before it;
* what stays for the render: the ImageData's texels, and the process's resident size after
  the export (Blender's own buffer freed, as the exporter does when it loaded it);
* the export's wall time;
* the lookup cost per point, ``lookup`` over ``--points`` points (1920 x 1080 by default),
  Closest, Linear and Cubic, with the points spread over the image in a grid (neighbouring
  points read neighbouring texels, as a render's pixels do) and at random UVs (every read a
  cache miss): the median of ``--repeat`` runs.

Linux only (/proc).  Memory figures are whole-process resident sizes: they count what the
export allocated whether NumPy, Blender or the allocator holds it.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class PatternImage:
    """A (size, size, 4) float image made a block of rows at a time (``core.png.write_png``
    reads it by row slices): smooth gradients with a fine pattern, alpha 1."""

    def __init__(self, size: int):
        self.shape = (size, size, 4)

    def __getitem__(self, rows: slice):
        import numpy as np

        size = self.shape[0]
        y = np.arange(size)[rows][:, None].astype(np.float32)
        x = np.arange(size, dtype=np.float32)[None, :]
        block = np.empty((len(y), size, 4), np.float32)
        block[..., 0] = x / size
        block[..., 1] = y / size
        block[..., 2] = ((x.astype(np.int64) ^ y.astype(np.int64)) & 255) / 255
        block[..., 3] = 1
        return block


def write_pattern_png(path: str, size: int) -> None:
    sys.path.insert(0, REPOSITORY)
    from core.png import write_png

    write_png(path, PatternImage(size))


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"no {field} in /proc/self/status")


def run_child(path: str, points: int, repeat: int) -> dict:
    """Runs in the child process: export the image, then time lookups."""
    sys.path.insert(0, REPOSITORY)
    import bpy  # noqa: F401  (first: it makes Blender's own modules importable)
    import numpy as np
    import render as render_script

    glint = render_script.import_glint()
    render_script.register_glint(glint)
    from glint.addon.export.images import ImageExporter
    from glint.core.shader.images import lookup

    image = bpy.data.images.load(path)
    notes = []
    exporter = ImageExporter(1, notes.append)
    before = _status_kib("VmRSS")
    with open("/proc/self/clear_refs", "w") as refs:
        refs.write("5")            # resets VmHWM, the resident peak
    start = time.perf_counter()
    data = exporter.image(image, None, "bench")
    export_s = time.perf_counter() - start
    peak = _status_kib("VmHWM")
    after = _status_kib("VmRSS")
    width = int(round(np.sqrt(points * 16 / 9)))
    height = points // width
    ys, xs = np.mgrid[0:height, 0:width]
    grid = ((xs.ravel() + 0.5) / width, (ys.ravel() + 0.5) / height)
    rng = np.random.default_rng(1)
    scattered = (rng.random(width * height), rng.random(width * height))
    lookups = {}
    for interpolation in ("Closest", "Linear", "Cubic"):
        for label, (u, v) in (("grid", grid), ("random", scattered)):
            runs = []
            for _ in range(repeat + 1):
                start = time.perf_counter()
                lookup(data, u, v, interpolation, "REPEAT")
                runs.append(time.perf_counter() - start)
            lookups[f"{interpolation} {label}"] = statistics.median(runs[1:])
    return dict(size=image.size[0], channels=data.channels, dtype=str(data.texels.dtype),
                texel_bytes=data.nbytes, export_s=export_s,
                export_peak_bytes=(peak - before) * 1024, resident_before=before * 1024,
                resident_after=after * 1024, points=width * height, lookups=lookups,
                notes=notes)


def measure(size: int, points: int, repeat: int, folder: str) -> dict:
    path = os.path.join(folder, f"pattern_{size}.png")
    start = time.perf_counter()
    write_pattern_png(path, size)
    written = time.perf_counter() - start
    child = subprocess.run(
        [sys.executable, "-m", "bench.images", "--child", path, "--points", str(points),
         "--repeat", str(repeat)], cwd=REPOSITORY, capture_output=True, text=True)
    lines = [line for line in child.stdout.splitlines() if line.startswith("{")]
    if child.returncode != 0 or not lines:
        raise RuntimeError(f"bench.images {size}: {child.stderr.strip()[-800:]}")
    result = json.loads(lines[-1])
    result.update(png_bytes=os.path.getsize(path), png_write_s=written)
    os.remove(path)
    return result


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8192, 16384])
    parser.add_argument("--points", type=int, default=1920 * 1080)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--child", metavar="PNG", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(run_child(args.child, args.points, args.repeat)))
        return
    mib = 2 ** 20
    with tempfile.TemporaryDirectory() as folder:
        for size in args.sizes:
            result = measure(size, args.points, args.repeat, folder)
            peak, before = result["export_peak_bytes"] / mib, result["resident_before"] / mib
            print(f"{size} x {size} PNG ({result['png_bytes'] / mib:.0f} MiB on disk): "
                  f"export {result['export_s']:.1f} s, peak +{peak:.0f} MiB over {before:.0f} "
                  f"MiB; kept texels {result['texel_bytes'] / mib:.0f} MiB "
                  f"({result['channels']} x {result['dtype']}), resident after "
                  f"{result['resident_after'] / mib:.0f} MiB", flush=True)
            for name, seconds in result["lookups"].items():
                print(f"    lookup {name}: {seconds:.3f} s for {result['points']:,} points, "
                      f"{seconds / result['points'] * 1e9:.0f} ns a point", flush=True)


if __name__ == "__main__":
    main()
