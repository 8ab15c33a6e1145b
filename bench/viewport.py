"""``python -m bench.viewport [--width W] [--height H] [--repeats N]``: how soon the viewport's
Rendered shading shows each pass of the article's scene.

The article's scene is built in Blender (``addon.utils.article_scene``, UV spheres 64 x 32),
exported as the viewport exports it (``export_viewport_scene``) and seen through its camera
as a camera view of a W x H region (default: the factory startup file's 3D View, 1574 x
954).  Reported per pass: seconds from the start of the refinement (``ProgressiveRender``)
to the pass landing, median of N runs; and the export's own time (what view_update adds
before the worker starts).  Run from the repository root with the project's Python.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.viewport", description=__doc__)
    parser.add_argument("--width", type=int, default=1574)
    parser.add_argument("--height", type=int, default=954)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)

    sys.path.insert(0, REPOSITORY)
    import render as render_script

    glint = render_script.import_glint()
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    render_script.register_glint(glint)
    from glint.addon.engine.viewport import ProgressiveRender, export_viewport_scene
    from glint.addon.export.view import ViewportView
    from glint.addon.utils.article_scene import build_article_scene

    scene = build_article_scene()
    bpy.context.window.scene = scene
    graph = bpy.context.evaluated_depsgraph_get()
    exports, passes = [], []
    for _ in range(args.repeats):
        start = time.perf_counter()
        exported, settings, size, _ = export_viewport_scene(graph)
        exports.append(time.perf_counter() - start)
        camera = scene.camera
        view = ViewportView.from_matrices(
            camera.matrix_world.inverted(),
            camera.calc_matrix_camera(graph, x=args.width, y=args.height),
            args.width, args.height)
        progressive = ProgressiveRender(exported, view, settings, size)
        progressive.wait()
        passes.append(progressive.frame_times)
    schedule = progressive.schedule
    print(f"article scene, {args.width}x{args.height} view, {len(exported.spheres)} spheres, "
          f"semantics {settings.semantics}, anti-aliasing {settings.anti_aliasing}; "
          f"median of {args.repeats}")
    print(f"export (view_update): {statistics.median(exports):.3f} s")
    for index, step in enumerate(schedule):
        w, h = view.camera(step.divisor).width, view.camera(step.divisor).height
        seconds = statistics.median(run[index] for run in passes)
        print(f"pass {index + 1}: {w}x{h}, anti-aliasing {step.settings.anti_aliasing}: "
              f"{seconds:.3f} s after the start")
    return 0


if __name__ == "__main__":
    sys.exit(main())
