"""The scale rows: Glint and Cycles on the same scene, built in bpy, in one process.

    .venv/bin/python -m bench.scale CASE:COUNT:WIDTHxHEIGHT ... [--repeats N] [--budget S]

Cases (each built from nothing with ``bpy``, in a fresh file; nothing is read from disk):

* ``points``: COUNT Geometry Nodes points (a Points node: random positions in a slab in front
  of the camera, a random ``radius`` attribute of 0.02-0.04): a POINTCLOUD, which Cycles
  draws as spheres and Glint's ``pointclouds`` exporter reads into one SphereSet;
* ``instances``: COUNT Geometry Nodes instances (Instance on Points) of one smooth 32 x 16 UV
  sphere of radius 0.05 on the same kind of slab (``instances``' bulk read);
* ``vertex-instances``: COUNT instances of one smooth UV-sphere object, placed by the
  vertices of a COUNT-vertex parent mesh (instancing Verts): instances the depsgraph yields
  one by one (Glint walks them, as it walks collection instances and particles);
* ``duplicates``: COUNT linked-duplicate objects (one shared UV-sphere mesh), each an object
  of the scene;
* ``suzanne``: Suzanne with a Subdivision Surface of COUNT levels, applied (968 x 4^L / 3 ~
  2 x 1968 x 4^(L-1) triangles: L = 5 gives 1,007,616), smooth shaded, over a floor plane.

Every case has a sun (angle 0: one shadow ray) and a dim grey world, view transform Standard,
Film Transparent (alpha = coverage).  Both contenders go through the same Blender pipeline,
``bpy.ops.render.render`` (F12): Blender evaluates the render depsgraph, then the engine
syncs (Glint: ``export_scene``, core scene, BVH and trace; Cycles: sync, BVH build and
trace).  Glint: the Whitted integrator, anti-aliasing off (one camera ray per pixel, through
its centre, where Cycles' one sample lands too: at 48x27 the sphere cases' images agree at
r = 1.00, Suzanne's at 0.98), its other settings the add-on's defaults (default semantics,
precision auto, depth 3, one thread per core); Cycles: CPU, 1 sample, no adaptive sampling,
no denoising, its default light paths.  Each is timed as ``bench.measure`` times every
contender: one warm-up, then the median of up to ``--repeats``
runs within ``--budget`` seconds, or the first run alone when it took longer than the
budget (``measure_render``).  Glint's F12s are split as they run (``GlintSplit``):
the export (``prepare_job``) and the core's render (``RenderJob.run``), medians over the
timed runs; the rest is Blender's (depsgraph evaluation, the render result).

Similarity: Pearson r of both images' RGB box-downsampled by 8 (as
``shared/tools/compare_with_cycles.py`` computes it; Cycles' 1-sample noise averages out
over the 8 x 8 boxes), the ratio of their mean brightness, and the pixels whose coverage
(alpha > 0.5) differs.  Each case prints one JSON line and writes
``OUT/scale-CASE-COUNT.png``: Glint left, Cycles right.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import statistics
import sys
import time
from dataclasses import dataclass

import numpy as np

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASES = ("points", "instances", "vertex-instances", "duplicates", "suzanne")
SEED = 20240601
#: The slab the points and instances fill: x and z across the view, y away from the camera.
SLAB_HALF_EXTENT = (6.0, 10.0, 3.5)
CAMERA_DISTANCE = 25.0     # from the slab's centre, along -y
POINT_RADII = (0.02, 0.04)
INSTANCE_RADIUS = 0.05
#: Box size of the similarity's downsampling (as compare_with_cycles.py).
SIMILARITY_BOX = 8


@dataclass(frozen=True)
class Case:
    """One scale row: what (``CASES``), how many (points, instances, objects, or Suzanne's
    subdivision levels) and the image size."""

    kind: str
    count: int
    width: int
    height: int

    @property
    def spec(self) -> str:
        return f"{self.kind}:{self.count}:{self.width}x{self.height}"

    @classmethod
    def parse(cls, text: str) -> "Case":
        try:
            kind, count, size = text.split(":")
            width, height = (int(v) for v in size.lower().split("x"))
            case = cls(kind, int(count), width, height)
        except ValueError:
            raise ValueError(f"case {text!r}: expected KIND:COUNT:WIDTHxHEIGHT") from None
        if kind not in CASES:
            raise ValueError(f"case {text!r}: kind must be one of {', '.join(CASES)}")
        if case.count < 1 or width < 1 or height < 1:
            raise ValueError(f"case {text!r}: count and size must be positive")
        return case

    @property
    def title(self) -> str:
        size = f"{self.width}x{self.height}"
        if self.kind == "suzanne":
            return (f"Suzanne, {suzanne_triangles(self.count):,} triangles, over a floor "
                    f"{size}")
        what = {"points": "point-cloud spheres", "instances": "GN-instanced UV spheres",
                "vertex-instances": "vertex-instanced UV spheres",
                "duplicates": "linked-duplicate UV spheres"}[self.kind]
        return f"{self.count:,} {what} {size}"


def suzanne_triangles(levels: int) -> int:
    """Triangles of Suzanne under ``levels`` of Catmull-Clark: 500 faces (468 quads, 32
    triangles, 968 triangles) become 1,968 quads at level 1, 4x more at each level after."""
    return 968 if levels == 0 else 2 * 1968 * 4 ** (levels - 1)


# --------------------------------------------------------------------------------------------
# Building the scenes (bpy)

def _slab_positions(count: int) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    return rng.uniform(-1.0, 1.0, (count, 3)) * np.asarray(SLAB_HALF_EXTENT)


def _node_tree(name: str):
    import bpy

    tree = bpy.data.node_groups.new(name, 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    return tree, tree.nodes, tree.links


def _random(nodes, data_type, low, high, seed):
    node = nodes.new("FunctionNodeRandomValue")
    node.data_type = data_type
    node.inputs["Min" if data_type == 'FLOAT_VECTOR' else 2].default_value = low
    node.inputs["Max" if data_type == 'FLOAT_VECTOR' else 3].default_value = high
    node.inputs["Seed"].default_value = seed
    return node


def _material(name: str, colour):
    import bpy

    material = bpy.data.materials.new(name)
    material.use_nodes = True
    principled = material.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (*colour, 1.0)
    principled.inputs["Roughness"].default_value = 0.6
    return material


def _uv_sphere_mesh(name: str, radius: float):
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    shape = bmesh.new()
    bmesh.ops.create_uvsphere(shape, u_segments=32, v_segments=16, radius=radius)
    shape.to_mesh(mesh)
    shape.free()
    mesh.shade_smooth()
    return mesh


def _link(obj):
    import bpy

    bpy.context.scene.collection.objects.link(obj)
    return obj


def _host(name: str, tree, material):
    import bpy

    host = _link(bpy.data.objects.new(name, bpy.data.meshes.new(name)))
    host.data.materials.append(material)
    host.modifiers.new(name, 'NODES').node_group = tree
    return host


def _slab_points(nodes, links, count: int):
    """A Points node of ``count`` points at random positions in the slab."""
    points = nodes.new("GeometryNodePoints")
    points.inputs["Count"].default_value = count
    sx, sy, sz = SLAB_HALF_EXTENT
    links.new(_random(nodes, 'FLOAT_VECTOR', (-sx, -sy, -sz), (sx, sy, sz), 1).outputs["Value"],
              points.inputs["Position"])
    return points


def build_points(count: int) -> None:
    tree, nodes, links = _node_tree("points")
    points = _slab_points(nodes, links, count)
    links.new(_random(nodes, 'FLOAT', *POINT_RADII, 2).outputs[1], points.inputs["Radius"])
    links.new(points.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    _host("points", tree, _material("points", (0.8, 0.35, 0.1)))


def build_instances(count: int) -> None:
    tree, nodes, links = _node_tree("instances")
    points = _slab_points(nodes, links, count)
    sphere = nodes.new("GeometryNodeMeshUVSphere")
    sphere.inputs["Segments"].default_value = 32
    sphere.inputs["Rings"].default_value = 16
    sphere.inputs["Radius"].default_value = INSTANCE_RADIUS
    smooth = nodes.new("GeometryNodeSetShadeSmooth")
    links.new(sphere.outputs[0], smooth.inputs[0])
    place = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(points.outputs[0], place.inputs["Points"])
    links.new(smooth.outputs[0], place.inputs["Instance"])
    links.new(place.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    _host("instances", tree, _material("instances", (0.2, 0.45, 0.8)))


def build_vertex_instances(count: int) -> None:
    import bpy

    sphere = _link(bpy.data.objects.new("ball", _uv_sphere_mesh("ball", INSTANCE_RADIUS)))
    sphere.data.materials.append(_material("balls", (0.2, 0.7, 0.3)))
    cloud = bpy.data.meshes.new("placement")
    cloud.vertices.add(count)
    cloud.vertices.foreach_set("co", _slab_positions(count).astype(np.float32).ravel())
    parent = _link(bpy.data.objects.new("placement", cloud))
    parent.instance_type = 'VERTS'
    parent.show_instancer_for_render = False
    sphere.parent = parent


def build_duplicates(count: int) -> None:
    import bpy

    mesh = _uv_sphere_mesh("ball", INSTANCE_RADIUS)
    mesh.materials.append(_material("balls", (0.7, 0.2, 0.5)))
    collection = bpy.context.scene.collection
    for index, position in enumerate(_slab_positions(count).tolist()):
        obj = bpy.data.objects.new(f"ball {index}", mesh)
        obj.location = position
        collection.objects.link(obj)


def build_suzanne(levels: int) -> None:
    import bpy

    bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0.0, 0.0, 0.0))
    monkey = bpy.context.object
    subdivision = monkey.modifiers.new("subdivision", 'SUBSURF')
    subdivision.levels = subdivision.render_levels = levels
    # Applied, so that both renderers draw the same million triangles instead of each
    # subdividing (Blender's depsgraph would subdivide for both, every render).
    graph = bpy.context.evaluated_depsgraph_get()
    applied = bpy.data.meshes.new_from_object(monkey.evaluated_get(graph))
    old = monkey.data
    monkey.modifiers.remove(subdivision)
    monkey.data = applied
    bpy.data.meshes.remove(old)
    applied.shade_smooth()
    applied.materials.append(_material("suzanne", (0.8, 0.6, 0.2)))
    bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 0.0, -1.0))
    bpy.context.object.data.materials.append(_material("floor", (0.5, 0.5, 0.5)))


BUILDERS = {"points": build_points, "instances": build_instances,
            "vertex-instances": build_vertex_instances, "duplicates": build_duplicates,
            "suzanne": build_suzanne}


def build(case: Case) -> None:
    """A fresh file holding ``case``'s scene, camera, sun and world."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = _link(bpy.data.objects.new("camera", bpy.data.cameras.new("camera")))
    if case.kind == "suzanne":
        camera.location = (0.0, -5.5, 0.9)
        camera.rotation_euler = (math.radians(82.0), 0.0, 0.0)
    else:
        camera.location = (0.0, -CAMERA_DISTANCE, 0.0)
        camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = camera
    sun = bpy.data.lights.new("sun", 'SUN')
    sun.energy = 3.0
    sun.angle = 0.0
    _link(bpy.data.objects.new("sun", sun)).rotation_euler = (math.radians(40.0), 0.0,
                                                              math.radians(30.0))
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)
    scene.world = world
    render = scene.render
    render.resolution_x, render.resolution_y = case.width, case.height
    render.resolution_percentage = 100
    render.film_transparent = True
    render.dither_intensity = 0.0
    render.use_compositing = render.use_sequencer = False
    scene.view_settings.view_transform = 'Standard'
    settings = render.image_settings
    settings.file_format = 'PNG'
    settings.color_mode = 'RGBA'
    settings.color_depth = '16'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 1
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    BUILDERS[case.kind](case.count)
    scene.glint.integrator, scene.glint.anti_aliasing = 'WHITTED', 'OFF'


# --------------------------------------------------------------------------------------------
# Measuring (bpy)

def _render_image(engine: str, folder: str) -> np.ndarray:
    """(H, W, 4) float64 of the last render, row 0 = top, RGB over black (as bench.blender)."""
    import bpy

    from .blender import render_result_rgba
    return render_result_rgba(bpy, bpy.context.scene,
                              os.path.join(folder, f"scale-{engine.lower()}.png"))


def _boxes(rgb: np.ndarray, box: int = SIMILARITY_BOX) -> np.ndarray:
    height, width = rgb.shape[0] // box * box, rgb.shape[1] // box * box
    if height == 0 or width == 0:
        return rgb[..., :3]
    return rgb[:height, :width, :3].reshape(height // box, box, width // box, box, 3).mean((1, 3))


def similarity(glint: np.ndarray, cycles: np.ndarray) -> dict:
    """Pearson r of the box-downsampled RGB, mean brightness ratio, coverage mismatches."""
    small_glint, small_cycles = _boxes(glint), _boxes(cycles)
    if small_glint.std() > 0 and small_cycles.std() > 0:
        r = float(np.corrcoef(small_glint.ravel(), small_cycles.ravel())[0, 1])
    else:
        r = None
    return {"r": r, "brightness_ratio": float((small_glint.mean() + 1e-6) /
                                              (small_cycles.mean() + 1e-6)),
            "coverage_mismatch": int(np.count_nonzero((glint[..., 3] > 0.5) !=
                                                      (cycles[..., 3] > 0.5))),
            "pixels": int(glint.shape[0] * glint.shape[1]), "box": SIMILARITY_BOX}


def _save_side_by_side(path: str, glint: np.ndarray, cycles: np.ndarray) -> None:
    import bpy

    gap = np.ones((glint.shape[0], 4, 4))
    side = np.concatenate([glint, gap, cycles], axis=1)
    side[..., 3] = 1.0
    image = bpy.data.images.new("side by side", side.shape[1], side.shape[0], float_buffer=True)
    try:
        image.colorspace_settings.name = 'Non-Color'  # the values are display values already
        image.pixels.foreach_set(np.clip(side[::-1], 0, 1).astype(np.float32).ravel())
        image.filepath_raw = path
        image.file_format = 'PNG'
        image.save()
    finally:
        bpy.data.images.remove(image)


def _drawn(scene) -> dict:
    return {"spheres": scene.sphere_count, "triangles": scene.triangle_count,
            "mesh_instances": sum(len(m.transforms) for m in scene.meshes)}


class GlintSplit:
    """Times the two halves of Glint's F12 inside the renders being timed: the export
    (``prepare_job``: ``export_scene`` and the settings) and the core's render
    (``RenderJob.run``); the rest of an F12 is Blender's (the render depsgraph's evaluation,
    the render result).  Wraps the engine's functions for this process only (a bench child),
    and keeps what the last render drew, its warnings and its ray counts."""

    def __init__(self):
        from glint.addon.engine import final, job

        self.export: list[float] = []
        self.core: list[float] = []
        self.last: dict = {}
        prepare, run = final.prepare_job, job.RenderJob.run

        def timed_prepare(*args, **kwargs):
            start = time.perf_counter()
            try:
                return prepare(*args, **kwargs)
            finally:
                self.export.append(time.perf_counter() - start)

        def timed_run(render_job, *args, **kwargs):
            start = time.perf_counter()
            result = run(render_job, *args, **kwargs)
            self.core.append(time.perf_counter() - start)
            stats = result.stats
            self.last = {"drawn": _drawn(render_job.scene), "warnings": render_job.warnings,
                         "precision": result.precision,
                         "parallelism": result.parallelism,
                         "phases": dict(stats.phases(), tiles=stats.seconds_tiles),
                         "rays": {"camera": stats.camera_rays, "shadow": stats.shadow_rays,
                                  "reflection": stats.reflection_rays,
                                  "node_tests": stats.node_tests,
                                  "sphere_tests": stats.sphere_tests,
                                  "triangle_tests": stats.triangle_tests}}
            return result

        final.prepare_job = timed_prepare
        job.RenderJob.run = timed_run


def measure_render(work, repeats: int, budget: float) -> tuple[list, float]:
    """(timed runs, first run's seconds): as ``bench.measure`` times every contender (a
    warm-up, then up to ``repeats`` runs within ``budget`` seconds), except that a first
    render longer than ``budget`` is the one timed run: a render of minutes has nothing to
    warm up (no kernels to load) and a second one would double the bench's time."""
    from .measure import run_count, timed_runs

    gc.collect()
    start = time.perf_counter()
    work()
    first = time.perf_counter() - start
    if first > budget:
        return [first], first
    return timed_runs(work, run_count(repeats, first, budget)), first


def f12(scene, engine: str, spec: str):
    """A callable that renders ``scene`` through F12 with its current engine and raises
    unless Blender reports it finished (``engine`` and ``spec`` name it in the message)."""
    import bpy

    def work():
        done = bpy.ops.render.render(scene=scene.name)
        if 'FINISHED' not in done:
            raise RuntimeError(f"{engine} render of {spec} did not finish: {done}")
    return work


def run_case(case: Case, repeats: int, budget: float, out: str, split: GlintSplit) -> dict:
    """Build, render with both engines (Glint's F12 split by ``split``); the case's JSON
    result."""
    import bpy

    start = time.perf_counter()
    build(case)
    result = {"case": case.spec, "kind": case.kind, "count": case.count, "width": case.width,
              "height": case.height, "title": case.title,
              "build_s": time.perf_counter() - start}
    scene = bpy.context.scene
    images = {}
    for engine in ("GLINT", "CYCLES"):
        scene.render.engine = engine
        split.export.clear()
        split.core.clear()
        runs, first = measure_render(f12(scene, engine, case.spec), repeats, budget)
        entry = result[engine.lower()] = {"runs": runs, "median_s": statistics.median(runs),
                                          "first_s": first, "first_counted": runs == [first]}
        if engine == "GLINT":
            renders = len(runs) + (0 if entry["first_counted"] else 1)
            if len(split.core) != renders:
                raise RuntimeError(f"Glint's F12 of {case.spec} did not render "
                                   f"({len(split.core)} core renders for {renders} F12s)")
            # The warm-up's halves are left out, as its time is (unless it is the run).
            timed = slice(len(split.core) - len(runs), None)
            entry["export_s"] = statistics.median(split.export[timed])
            entry["core_s"] = statistics.median(split.core[timed])
            entry.update(split.last)
        images[engine] = _render_image(engine, out)

    result["similarity"] = similarity(images["GLINT"], images["CYCLES"])
    picture = os.path.join(out, f"scale-{case.kind}-{case.count}.png")
    _save_side_by_side(picture, images["GLINT"], images["CYCLES"])
    result["picture"] = picture
    return result


def start_blender(out: str) -> None:
    """In a bench child: bpy imported, the add-on registered (quietly), ``out`` made."""
    sys.path.insert(0, REPOSITORY)
    import bpy  # noqa: F401 - first: it makes Blender's own modules importable

    import render as render_script
    from .blender import quiet_output

    with quiet_output():
        render_script.register_glint(render_script.import_glint())
    os.makedirs(out, exist_ok=True)


def child_result(command: list, timeout: float) -> dict:
    """Run a bench child (``command``, from the repository) and return the last JSON line it
    printed; a failure raises with the end of its stderr."""
    import subprocess

    done = subprocess.run(command, cwd=REPOSITORY, capture_output=True, text=True,
                          timeout=timeout)
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode != 0 or not lines:
        raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()[-800:]}")
    return json.loads(lines[-1])


def _child(specs, repeats: int, budget: float, out: str) -> None:
    from .blender import quiet_output

    start_blender(out)
    split = GlintSplit()
    for spec in specs:
        case = Case.parse(spec)
        with quiet_output():
            result = run_case(case, repeats, budget, out, split)
        print(json.dumps(result), flush=True)


def run(cases, repeats: int, budget: float, out: str, timeout: float = 3600) -> list[dict]:
    """Each case in a child process of its own (a million objects' memory stays there); the
    child's JSON results."""
    return [child_result([sys.executable, "-m", "bench.scale", case.spec, "--repeats",
                          str(repeats), "--budget", str(budget), "--out", out], timeout)
            for case in cases]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.scale",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", metavar="KIND:COUNT:WIDTHxHEIGHT")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget", type=float, default=40.0)
    parser.add_argument("--out", default=os.path.join(REPOSITORY, "bench", "out"))
    args = parser.parse_args(argv)
    try:
        for spec in args.cases:
            Case.parse(spec)
    except ValueError as error:
        parser.error(str(error))
    _child(args.cases, args.repeats, args.budget, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
