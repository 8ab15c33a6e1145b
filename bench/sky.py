"""The Sky Texture's cost: its table's precomputation and its evaluation per direction.

``python -m bench.sky [--width W --height H --repeats N] [--cycles]`` times, for the
physical skies (Multiple and Single Scattering, Blender's defaults: sun 15 degrees up,
100 m, densities 1), the computation of the 512 x 256 table and of the sun disc's two
pixels that a process does once per set of options (``core.shader.sky.sky_table``,
``sun_pixels``, their caches cleared before each run); then the node's evaluation over the
directions of the W x H pixel centres of an equirectangular frame of the whole sphere
(1920 x 1080: 2,073,600 directions by default), the table cached, for each sky type, with
the sun disc and without, and for scale an Environment Texture (a 1024 x 512 float image,
Linear) over the same directions.

It prints the median over the timed runs (after a warm-up) of the process's CPU time and of
the wall time: seconds for a table, nanoseconds per direction for the evaluation.  CPU time,
because NumPy runs on one core here and other work on the machine lengthens the wall time
but not it.  With ``--cycles`` (pip bpy) it also times Cycles' own precomputation in the
same run, as the wall time a 1 x 1 render of a world-only scene takes with the sky (a new
sun elevation each run, so that Cycles computes its table again) less the same render with
a constant world: Cycles computes the table on every core, so compare wall times.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from core.environment import equirectangular_directions
from core.shader import sky
from core.shader.images import environment_texture, image_from_pixels
from core.shader.world import world_points

from .measure import load_average
from .textures import time_case

PHYSICAL = ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING")
ATMOSPHERE = (100.0, 1.0, 1.0, 1.0)   # altitude, air, aerosol, ozone: Blender's defaults


def sphere_directions(width: int, height: int) -> np.ndarray:
    """(3, width * height) float32 unit directions at an equirectangular frame's pixel
    centres, row by row from the zenith down."""
    rows, columns = np.divmod(np.arange(width * height), width)
    return equirectangular_directions((columns + 0.5) / width,
                                      1 - (rows + 0.5) / height).astype(np.float32)


def precompute(sky_type: str):
    elevation = float(sky.sun_position(np.radians(15.0), 0.0)[0])

    def work():
        sky.sky_table.cache_clear()
        sky.sun_pixels.cache_clear()
        sky.sky_table(sky_type, elevation, *ATMOSPHERE)
        sky.sun_pixels(sky_type, elevation, 0.009512, *ATMOSPHERE)
    return work


def evaluation_cases(directions):
    """(name, callable) per case."""
    points = world_points(directions)

    def evaluate(**options):
        return lambda: sky.sky_texture(points, directions, **options)

    image = image_from_pixels("environment", np.random.default_rng(1).random(
        (512, 1024, 3), np.float32))
    return [("Multiple Scattering, sun disc", evaluate()),
            ("Multiple Scattering, no disc", evaluate(sun_disc=False)),
            ("Single Scattering, sun disc", evaluate(sky_type="SINGLE_SCATTERING")),
            ("Preetham", evaluate(sky_type="PREETHAM")),
            ("Hosek / Wilkie", evaluate(sky_type="HOSEK_WILKIE")),
            ("(Environment Texture, 1024 x 512, Linear)",
             lambda: environment_texture(points, directions, image=image))]


def cycles_precompute(repeats: int) -> dict:
    """{sky type: median wall seconds} Cycles spends on the sky's table and sun (module
    docstring)."""
    import statistics
    import tempfile
    import time

    import bpy

    from .blender import quiet_output
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.render.resolution_x = scene.render.resolution_y = 1
    scene.cycles.device, scene.cycles.samples = 'CPU', 1
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    world = scene.world = bpy.data.worlds.new("world")
    tree = world.node_tree
    node = tree.nodes.new("ShaderNodeTexSky")

    def render() -> float:
        with tempfile.TemporaryDirectory() as folder, quiet_output():
            scene.render.filepath = f"{folder}/frame.png"
            start = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            return time.perf_counter() - start

    render()
    constant = statistics.median(render() for _ in range(repeats))
    link = tree.links.new(node.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    times = {}
    for sky_type in PHYSICAL:
        node.sky_type = sky_type
        runs = []
        for run in range(repeats + 1):
            node.sun_elevation = np.radians(15.0) + 1e-3 * run
            runs.append(render())
        times[sky_type] = statistics.median(runs[1:]) - constant
    tree.links.remove(link)
    return times


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.sky", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per case")
    parser.add_argument("--cycles", action="store_true",
                        help="time Cycles' own precomputation too (pip bpy)")
    args = parser.parse_args(argv)
    print(f"load average {load_average()}")
    cycles = cycles_precompute(args.repeats) if args.cycles else {}
    print("| table and sun of | CPU s | wall s |" + (" Cycles wall s |" if cycles else ""))
    print("|---|---|---|" + ("---|" if cycles else ""))
    for sky_type in PHYSICAL:
        cpu, wall = time_case(precompute(sky_type), args.repeats)
        theirs = f" {cycles[sky_type]:.2f} |" if cycles else ""
        print(f"| {sky_type.replace('_', ' ').title()} | {cpu:.2f} | {wall:.2f} |{theirs}",
              flush=True)
    directions = sphere_directions(args.width, args.height)
    count = directions.shape[1]
    print(f"\n{count:,} directions ({args.width} x {args.height}, the whole sphere)")
    print("| evaluation | CPU ns / direction | wall ns / direction |")
    print("|---|---|---|")
    for name, work in evaluation_cases(directions):
        cpu, wall = time_case(work, args.repeats)
        print(f"| {name} | {cpu / count * 1e9:,.0f} | {wall / count * 1e9:,.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
