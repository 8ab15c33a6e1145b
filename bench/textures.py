"""The procedural textures' cost per shading point.

``python -m bench.textures [--width W --height H --repeats N]`` evaluates Noise (3D fBM,
Detail 1 and 7: 2 and 8 octaves) and Voronoi (3D F1) over the W x H pixel centres of a
frame (1920 x 1080: 2,073,600 points by default), as coordinates in [0, 1] like the
Generated coordinate of a plane filling the view, in scanline order as a frame's hits come,
Scale 5, the other inputs at Blender's defaults.  Each texture runs with only its first
output read (``needed``) and with all of them (Noise's Color is two more fractal sums).
The IES lookup (``core.shader.ies.ies_intensity``) reads the same points less (0.5, 0.5,
1) as directions (down, up to 45 degrees off), in a type C profile of 10 vertical by 7
horizontal angles (a half circle, mirrored to 13 columns).

It prints, per case, the median over the timed runs (after a warm-up) of the process's CPU
time and of the wall time, in nanoseconds per point: CPU time, because NumPy runs on one
core here and other work on the machine lengthens the wall time but not it.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from core.shader.ies import ies_intensity, parse_ies
from core.shader.textures import noise_texture_node, voronoi_texture_node

from .measure import load_average


def frame_points(width: int, height: int) -> np.ndarray:
    """(3, width * height) float32: the pixel centres of a frame, scaled to [0, 1], z 0.5."""
    rows, columns = np.divmod(np.arange(width * height), width)
    return np.stack([(columns + 0.5) / width, (rows + 0.5) / height,
                     np.full(width * height, 0.5)]).astype(np.float32)


def _value(x):
    return np.asarray(x, np.float32)


def ies_profile():
    """A type C IES profile of 10 vertical angles (0..90) by 7 horizontal ones (0..180)."""
    v_angles = np.linspace(0, 90, 10)
    h_angles = np.linspace(0, 180, 7)
    candela = 1000 * np.cos(np.radians(v_angles))[None, :] * (1.5 + np.cos(
        np.radians(h_angles)))[:, None]
    numbers = [f"1 1000 1 {len(v_angles)} {len(h_angles)} 1 2 0 0 0", "1 1 100",
               " ".join(map(str, v_angles)), " ".join(map(str, h_angles))]
    numbers += [" ".join(f"{value:.3f}" for value in row) for row in candela]
    return parse_ies("IESNA:LM-63-2002\nTILT=NONE\n" + "\n".join(numbers) + "\n")


def cases(vector):
    """(name, callable) per case."""
    w, scale = _value(0.0), _value(5.0)
    profile = ies_profile()
    directions = vector - np.array([[0.5], [0.5], [1.0]], np.float32)

    def noise(detail, needed):
        return lambda: noise_texture_node(None, vector, w, scale, _value(detail), _value(0.5),
                                          _value(2.0), _value(0.0), _value(1.0), _value(0.0),
                                          needed=needed)

    def voronoi(needed):
        return lambda: voronoi_texture_node(None, vector, w, scale, _value(0.0), _value(0.5),
                                            _value(2.0), _value(1.0), _value(0.5), _value(1.0),
                                            needed=needed)

    return [("Noise 3D fBM, 2 octaves, Fac", noise(1.0, {"Fac"})),
            ("Noise 3D fBM, 2 octaves, Fac + Color", noise(1.0, None)),
            ("Noise 3D fBM, 8 octaves, Fac", noise(7.0, {"Fac"})),
            ("Noise 3D fBM, 8 octaves, Fac + Color", noise(7.0, None)),
            ("Voronoi 3D F1, Distance", voronoi({"Distance"})),
            ("Voronoi 3D F1, all outputs", voronoi(None)),
            ("IES Texture lookup", lambda: ies_intensity(profile, directions))]


def time_case(work, repeats: int) -> tuple[float, float]:
    """(median CPU seconds, median wall seconds) of ``repeats`` runs after a warm-up."""
    work()
    cpu, wall = [], []
    for _ in range(repeats):
        start_cpu, start_wall = time.process_time(), time.perf_counter()
        work()
        cpu.append(time.process_time() - start_cpu)
        wall.append(time.perf_counter() - start_wall)
    return statistics.median(cpu), statistics.median(wall)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.textures", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per case")
    args = parser.parse_args(argv)
    vector = frame_points(args.width, args.height)
    count = vector.shape[1]
    print(f"{count:,} points ({args.width} x {args.height}); load average {load_average()}")
    print("| case | CPU ns / point | wall ns / point |")
    print("|---|---|---|")
    for name, work in cases(vector):
        cpu, wall = time_case(work, args.repeats)
        print(f"| {name} | {cpu / count * 1e9:,.0f} | {wall / count * 1e9:,.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
