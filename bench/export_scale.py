"""Export time for large point clouds and instance counts (the target: a million
spheres go from bpy attributes to a validated core scene in well under a second).

    .venv/bin/python -m bench.export_scale [--counts 100000 1000000] [--repeat 3]

Each case is a Geometry Nodes object built in a fresh file (pip bpy, headless):

* ``points``: a Points node, N points with a radius: one POINTCLOUD instance -> SphereSet;
* ``sphere instances``: Instance on Points of a smooth 32 x 16 UV sphere: N instances read in
  bulk from the evaluated geometry -> one SphereSet;
* ``cube instances``: the same with a cube -> one TriangleMesh with N transforms;
* ``sphere instances, walked``: sphere instances with the bulk path switched off, so every
  instance goes through the depsgraph walk one at a time, as collection instances and
  particles do.

Reported: Blender's own depsgraph evaluation (not Glint's), then ``export_scene`` (the walk,
the conversion and the validation of the core scene), the median of ``--repeat`` runs.  Each
case runs in its own child process, so one case's memory does not weigh on the next.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASES = ("points", "sphere instances", "cube instances", "sphere instances, walked")


def build(case: str, count: int):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.location = (0.0, -60.0, 0.0)
    camera.rotation_euler = (1.5707963, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    host = bpy.data.objects.new("host", bpy.data.meshes.new("host"))
    scene.collection.objects.link(host)
    tree = bpy.data.node_groups.new("scatter", 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = tree.nodes, tree.links
    points = nodes.new("GeometryNodePoints")
    points.inputs["Count"].default_value = count
    points.inputs["Radius"].default_value = 0.02
    scatter = nodes.new("FunctionNodeRandomValue")
    scatter.data_type = 'FLOAT_VECTOR'
    scatter.inputs["Min"].default_value = (-10.0, -10.0, -10.0)
    scatter.inputs["Max"].default_value = (10.0, 10.0, 10.0)
    links.new(scatter.outputs["Value"], points.inputs["Position"])
    output = nodes.new("NodeGroupOutput")
    if case == "points":
        links.new(points.outputs[0], output.inputs[0])
    else:
        if case == "cube instances":
            shape = nodes.new("GeometryNodeMeshCube")
            shape.inputs["Size"].default_value = (0.04, 0.04, 0.04)
        else:
            shape = nodes.new("GeometryNodeMeshUVSphere")
            shape.inputs["Radius"].default_value = 0.02
        smooth = nodes.new("GeometryNodeSetShadeSmooth")
        links.new(shape.outputs[0], smooth.inputs[0])
        place = nodes.new("GeometryNodeInstanceOnPoints")
        links.new(points.outputs[0], place.inputs["Points"])
        links.new(smooth.outputs[0], place.inputs["Instance"])
        links.new(place.outputs[0], output.inputs[0])
    host.modifiers.new("scatter", 'NODES').node_group = tree


def run_case(case: str, count: int, repeat: int) -> dict:
    """Runs in the child process."""
    sys.path.insert(0, REPOSITORY)
    import bpy  # first: it makes Blender's own modules (addon_utils) importable
    import render as render_script

    glint = render_script.import_glint()
    render_script.register_glint(glint)
    from glint.addon.export import export_scene
    from glint.addon.export import instances

    if case.endswith("walked"):
        instances.InstanceExporter._read_source = staticmethod(lambda parent: None)
    build(case, count)
    start = time.perf_counter()
    graph = bpy.context.evaluated_depsgraph_get()
    graph.update()
    evaluation = time.perf_counter() - start
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        exported, _ = export_scene(graph)
        times.append(time.perf_counter() - start)
    drawn = sum(len(s) for s in exported.sphere_sets) + len(exported.spheres) + \
        sum(len(m.transforms) for m in exported.meshes)
    return dict(case=case, count=count, depsgraph_s=evaluation,
                export_s=statistics.median(times), runs=times, drawn=drawn)


def run_child(case: str, count: int, repeat: int) -> dict:
    """``run_case`` in a child process of its own; its result."""
    child = subprocess.run(
        [sys.executable, "-m", "bench.export_scale", "--repeat", str(repeat),
         "--child", case, str(count)], cwd=REPOSITORY, capture_output=True, text=True)
    lines = [line for line in child.stdout.splitlines() if line.startswith("{")]
    if child.returncode != 0 or not lines:
        raise RuntimeError(f"bench.export_scale {case!r} {count}: "
                           f"{child.stderr.strip()[-800:]}")
    return json.loads(lines[-1])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    parser.add_argument("--child", nargs=2, metavar=("CASE", "COUNT"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(run_case(args.child[0], int(args.child[1]), args.repeat)))
        return
    print("| case | N | depsgraph evaluation (s) | export_scene (s) | exported |")
    print("|---|---:|---:|---:|---:|")
    for case in args.cases:
        for count in args.counts:
            result = run_child(case, count, args.repeat)
            print(f"| {case} | {count:,} | {result['depsgraph_s']:.2f} | "
                  f"{result['export_s']:.3f} | {result['drawn']:,} |", flush=True)


if __name__ == "__main__":
    main()
