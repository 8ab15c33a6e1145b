"""PNG plots of a bench run (matplotlib, a dev-only dependency imported only here).

``write_plots`` returns the paths written, or raises PlotsUnavailable when matplotlib is not
installed, so that the table is still printed.
"""

from __future__ import annotations

import os

from .suite import Bench

MIB = 2 ** 20
#: Where an error of exactly 0 (the reference itself) is drawn on the log axis.
ZERO_ERROR = 1e-13


class PlotsUnavailable(RuntimeError):
    pass


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise PlotsUnavailable("matplotlib is not installed "
                               "(pip install -r bench/requirements.txt)") from None
    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as pyplot

    return pyplot


def _panels(bench: Bench):
    """(title, rows) per plot panel: one per workload, the two AA workloads together."""
    panels = {}
    for row in bench.rows:
        if row.rms_error is None and not row.is_reference:
            continue
        if row.workload.startswith("aa-"):
            key, title = "aa", row.title.rsplit(",", 1)[0] + ", anti-aliasing (vs 256 spp)"
        else:
            key, title = row.workload, row.title
        panels.setdefault(key, (title, []))[1].append(row)
    return list(panels.values())


def _speed_vs_error(pyplot, bench: Bench, path: str) -> bool:
    panels = _panels(bench)
    if not panels:
        return False
    columns = min(3, len(panels))
    lines = -(-len(panels) // columns)
    figure, axes = pyplot.subplots(lines, columns, figsize=(6.5 * columns, 5 * lines),
                                   squeeze=False)
    for axis in axes.flat[len(panels):]:
        axis.set_visible(False)
    for axis, (title, rows) in zip(axes.flat, panels):
        for row in rows:
            error = 0.0 if row.is_reference else row.rms_error
            y = max(error, ZERO_ERROR)
            marker = {"glint": "o", "baseline": "s", "per-pixel": "^", "cycles": "D"}.get(row.kind, "x")
            axis.scatter(row.seconds, y, marker=marker)
            axis.annotate(row.contender.replace("Glint ", ""), (row.seconds, y), fontsize=7,
                          xytext=(4, 2), textcoords="offset points")
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_xlabel("time (s, median; per-pixel program scaled)")
        axis.set_ylabel(f"RMS error, 8-bit steps (reference drawn at {ZERO_ERROR:g})")
        axis.set_title(title, fontsize=9)
        axis.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    pyplot.close(figure)
    return True


def _curve(pyplot, bench: Bench, curve: str, x_of, y_of, xlabel: str, ylabel: str, title: str,
           path: str, extra=None) -> bool:
    points = [p for p in bench.curve_points if p.curve == curve]
    if not points:
        return False
    figure, axis = pyplot.subplots(figsize=(7, 5))
    for contender in dict.fromkeys(p.contender for p in points):
        mine = sorted((p for p in points if p.contender == contender), key=x_of)
        values = [(x_of(p), y_of(p)) for p in mine if y_of(p) is not None]
        if values:
            axis.plot(*zip(*values), marker="o", label=contender)
    if extra is not None:
        extra(axis, points)
    axis.set_xscale("log")
    axis.set_yscale("log")
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    axis.set_title(title, fontsize=10)
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    pyplot.close(figure)
    return True


def _linear_guide(axis, points):
    """A line of slope 1 through the largest point of the first contender: linear time."""
    first = [p for p in points if p.contender == points[0].contender]
    last = max(first, key=lambda p: p.pixels)
    xs = sorted({p.pixels for p in points})
    axis.plot(xs, [last.seconds * x / last.pixels for x in xs], "k:", label="linear in pixels")


def _image_sizes(axis, points):
    """The output image's size, and each contender's peak minus its image (dashed)."""
    by_size = {}
    for p in points:
        by_size.setdefault(p.pixels, p.image_bytes)
    xs = sorted(by_size)
    axis.plot(xs, [by_size[x] / MIB for x in xs], "k:", label="output image (first contender)")
    colours = {line.get_label(): line.get_color() for line in axis.get_lines()}
    for contender in dict.fromkeys(p.contender for p in points):
        mine = sorted((p for p in points if p.contender == contender and p.peak_bytes),
                      key=lambda p: p.pixels)
        if mine:
            axis.plot([p.pixels for p in mine],
                      [max(p.peak_bytes - p.image_bytes, 1) / MIB for p in mine], "--",
                      color=colours.get(contender), label=f"{contender}: peak - image")


def write_plots(bench: Bench, out_dir: str) -> list[str]:
    pyplot = _pyplot()
    os.makedirs(out_dir, exist_ok=True)
    written = []

    def target(name):
        return os.path.join(out_dir, name)

    if _speed_vs_error(pyplot, bench, target("speed_vs_error.png")):
        written.append(target("speed_vs_error.png"))
    if _curve(pyplot, bench, "cost-pixels", lambda p: p.pixels, lambda p: p.seconds,
              "pixels", "time (s, median)", "Article scene, depth 3: time against pixel count",
              target("cost_pixels.png"), _linear_guide):
        written.append(target("cost_pixels.png"))
    if _curve(pyplot, bench, "cost-spheres", lambda p: p.spheres, lambda p: p.seconds,
              "spheres (random small spheres + the floor)", "time (s, median)",
              "Time against sphere count", target("cost_spheres.png")):
        written.append(target("cost_spheres.png"))
    if _curve(pyplot, bench, "cost-pixels", lambda p: p.pixels,
              lambda p: None if p.peak_bytes is None else p.peak_bytes / MIB,
              "pixels", "peak traced memory (MiB)",
              "Peak memory against pixel count (tracemalloc)", target("memory_pixels.png"),
              _image_sizes):
        written.append(target("memory_pixels.png"))
    return written
