"""Memory is planned, not discovered: the plan bounds what a render really allocates, a
render that cannot fit is refused at once with one line, and every step after tracing works
in place or a block of rows at a time.

Sizes stay small here (at most 1024 x 1024, or a 2K image for the streaming steps); the 8K
and 16K peak-RSS figures in docs/performance.md were measured with the command given there,
not in CI.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest

import core
from core import memory
from core.png import decode_png, write_png

pytestmark = pytest.mark.slow  # every test here takes seconds (child processes)

REPOSITORY = __file__.rsplit("/tests/", 1)[0]


def traced_peak(function):
    tracemalloc.start()
    try:
        result = function()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak


def spheres_scene(count, size=64, soft=True):
    rng = np.random.default_rng(7)
    centres = rng.uniform(-5, 5, (count, 3)) + (0, 0, -12)
    spheres = tuple(core.Sphere(tuple(c), 0.05, name=f"s{i}") for i, c in enumerate(centres))
    return core.Scene(camera=core.ScreenCamera(size, size), spheres=spheres,
                      lights=(core.PointLight((5, 5, 5), radius=0.5 if soft else 0.0),))


def sphere_set_scene(count, soft):
    centres = np.random.default_rng(8).uniform(-5, 5, (count, 3)) + (0, 0, -12)
    points = core.SphereSet(centres, np.full(count, 0.02), np.zeros(count, int),
                            (core.Material(),), "points")
    return core.Scene(camera=core.ScreenCamera(64, 64), sphere_sets=(points,),
                      lights=(core.PointLight((5, 5, 5), radius=0.5 if soft else 0.0),))


def mesh_scene(rings=60, instances=6):
    """A UV-sphere-like grid mesh (2 (rings - 1)^2 triangles) drawn ``instances`` times."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, rings), np.linspace(0.05, np.pi - 0.05, rings))
    vertices = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1)
    grid = np.arange(rings * rings).reshape(rings, rings)
    triangles = np.concatenate([
        np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:]], -1).reshape(-1, 3),
        np.stack([grid[:-1, :-1], grid[1:, 1:], grid[:-1, 1:]], -1).reshape(-1, 3)])
    transforms = np.tile(np.eye(4), (instances, 1, 1))
    transforms[:, 0, 3] = np.linspace(-6, 6, instances)
    transforms[:, 2, 3] = -15
    mesh = core.TriangleMesh(vertices.reshape(-1, 3), triangles, None,
                             np.zeros(len(triangles), int), (core.Material(),), transforms,
                             "grid")
    return core.Scene(camera=core.ScreenCamera(64, 64), meshes=(mesh,),
                      lights=(core.PointLight((5, 5, 5)),))


# Threads, not 'auto': tracemalloc sees this process only, and the plan is about tracing
# memory (worker processes are planned in test_core_workers).
CASES = {
    "article 1024x1024, 2 threads": (lambda: core.article_scene(1024, 1024),
                                     core.RenderSettings(threads=2, parallelism="threads")),
    "article 512x512, fixed 64 samples": (lambda: core.article_scene(512, 512),
                                          core.RenderSettings(threads=2, anti_aliasing="fixed",
                                                              samples=64,
                                                              parallelism="threads")),
    "5,000 spheres at 64x64, soft light": (lambda: spheres_scene(5000),
                                           core.RenderSettings(threads=2, light_samples=16)),
    "a 100,000-sphere set at 64x64, hard light": (lambda: sphere_set_scene(100_000, False),
                                                  core.RenderSettings(threads=2)),
    "a 20,000-sphere set at 64x64, soft light": (lambda: sphere_set_scene(20_000, True),
                                                 core.RenderSettings(threads=2,
                                                                     light_samples=16)),
    "a 7,000-triangle mesh drawn 6 times": (mesh_scene, core.RenderSettings(threads=2)),
}


@pytest.mark.parametrize("case", CASES)
def test_the_plan_covers_what_a_render_allocates_without_wild_overestimates(case):
    make_scene, settings = CASES[case]
    scene = make_scene()
    result, peak = traced_peak(lambda: core.render(scene, settings))
    plan = memory.plan(scene, settings, result.image.dtype, settings.threads)
    assert plan.image == result.image.nbytes
    assert peak <= plan.total, f"allocated {peak / 1e6:.0f} MB, planned {plan.total / 1e6:.0f}"
    assert plan.total < 12 * peak, "the plan refuses far more than it needs to"


def test_a_render_that_cannot_fit_is_refused_before_tracing_in_one_line():
    scene = core.article_scene(100_000, 100_000)
    with pytest.raises(memory.NotEnoughMemory) as raised:  # threads: the image alone
        core.render(scene, core.RenderSettings(parallelism="threads"))
    message = str(raised.value)
    assert "100000x100000 render needs about 320.0 GB" in message
    assert "lower the resolution" in message and "\n" not in message


def test_the_advice_names_the_largest_term():
    settings = core.RenderSettings()
    small = core.article_scene(64, 64)
    plan = memory.plan(small, settings, np.float32, threads=2)
    assert "resolution" in memory.MemoryPlan(10**12, plan.tracing, plan.scene).what_to_lower()
    assert "spheres" in memory.MemoryPlan(plan.image, plan.tracing, 10**12).what_to_lower()
    with pytest.raises(memory.NotEnoughMemory, match="fewer spheres"):
        memory.check(memory.MemoryPlan(1, 1, 10**12), 64, 64, available=10**9)
    memory.check(memory.MemoryPlan(1, 1, 10**6), 64, 64, available=10**9)  # fits


@pytest.mark.parametrize("arguments, words", [
    (["--width", "100000", "--height", "100000"], ["100000x100000", "GB", "resolution"]),
])
def test_python_m_core_refuses_a_size_that_cannot_fit_in_one_line(tmp_path, arguments, words):
    result = subprocess.run([sys.executable, "-m", "core", *arguments, "--output",
                             str(tmp_path / "o.png")], capture_output=True, text=True,
                            cwd=REPOSITORY, timeout=120)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert all(word in line for word in words)
    assert list(tmp_path.iterdir()) == []


def test_the_png_writer_streams_rows(tmp_path):
    rng = np.random.default_rng(3)

    def peak_for(height):
        image = rng.random((height, 2048, 4)).astype(np.float32)
        path = tmp_path / f"{height}.png"
        _, peak = traced_peak(lambda: write_png(str(path), image, convert=lambda r: r * 1.0))
        expected = np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)
        np.testing.assert_array_equal(decode_png(path.read_bytes()), expected)
        return peak, image.nbytes

    short, _ = peak_for(256)
    tall, tall_bytes = peak_for(2048)
    # A block of rows converted, quantised and compressed at a time: eight times the rows
    # cost no more memory (a whole-image conversion would cost 8x, and more than the image).
    assert tall < 1.5 * short, f"{short / 1e6:.1f} MB for 256 rows, {tall / 1e6:.1f} for 2048"
    assert tall < tall_bytes / 4


def test_a_million_spheres_at_64x64_stay_within_their_plan():
    """A million spheres (an early tracer took 13-20 GB for them, then a MemoryError).  A million
    spheres is the size the claim is about, so this test builds them (about 5 s here)."""
    scene = sphere_set_scene(1_000_000, False)
    settings = core.RenderSettings(threads=2)
    result, peak = traced_peak(lambda: core.render(scene, settings))
    plan = memory.plan(scene, settings, result.image.dtype, 2)
    assert peak <= plan.total < 4e9, f"allocated {peak / 1e9:.2f} GB, planned {plan.total / 1e9:.2f}"
    assert result.image[..., 3].mean() > 0.2  # the spheres are there (a third of the frame)


def test_render_py_hands_its_frame_to_blender_in_place():
    """render.py's colour-managed PNG path converts the job's image to Blender's rows in place,
    a block of rows at a time (at 8K each full-frame copy is another 0.5 GB, and the sRGB
    curve works in float64): the same values as the whole-frame conversion, flipped, for a
    small fraction of the image's size."""
    if REPOSITORY not in sys.path:
        sys.path.insert(0, REPOSITORY)
    import render as render_script

    render_script.import_glint()   # the package the add-on's colour helpers live in
    from glint.addon.cli.output import _to_blender_rows

    class Job:  # RenderJob.scene_linear for the article semantics
        @staticmethod
        def scene_linear(rows):
            from glint.addon.utils.colour import render_result_pixels
            return render_result_pixels(rows, "article")

    rng = np.random.default_rng(4)

    def peak_for(height):
        image = rng.random((height, 512, 4)).astype(np.float32)
        image[..., :3] *= image[..., 3:]   # premultiplied
        expected = Job.scene_linear(image)[::-1]
        result, peak = traced_peak(lambda: _to_blender_rows(image, Job))
        assert np.shares_memory(result, image)
        np.testing.assert_array_equal(result, expected)
        return peak, image.nbytes

    short, _ = peak_for(512)
    tall, tall_bytes = peak_for(4096)
    # A block of rows at a time: eight times the rows cost no more (a whole-frame conversion
    # would cost 8x, several times the image in float64).
    assert tall < 1.5 * short, f"{short / 1e6:.1f} MB for 512 rows, {tall / 1e6:.1f} for 4096"
    assert tall < tall_bytes


def test_textures_are_in_the_plan_and_a_too_big_one_is_named():
    """A material's image is held for the render: the plan counts its texels once, however
    many materials read it, and a render that does not fit because of it says which image."""
    import bpy

    from addon_support import add_camera, add_sphere, depsgraph, empty_file, prepare_job
    from glint.addon.compat import new_material
    from glint.core import memory as glint_memory   # (the add-on's copy of the core)

    empty_file()
    image = bpy.data.images.new("big texture", 1024, 512, alpha=True, float_buffer=True)
    for index in range(2):
        material = new_material(f"textured {index}")
        texture = material.node_tree.nodes.new("ShaderNodeTexImage")
        texture.image = image
        material.node_tree.links.new(texture.outputs["Color"],
                                     material.node_tree.nodes["Principled BSDF"].inputs[0])
        add_sphere(f"ball {index}", (2.0 * index, 0.0, 0.0), 0.8, material=material)
    add_camera()
    job = prepare_job(depsgraph())
    plan = glint_memory.plan(job.scene, job.settings, np.float32, threads=2)
    assert [name for name, _ in plan.images] == ["big texture"]
    assert plan.texture_bytes >= 1024 * 512 * 3 * 2      # at least half floats, RGB
    assert plan.total == (plan.image + plan.tracing + plan.scene + plan.texture_bytes)
    with pytest.raises(glint_memory.NotEnoughMemory, match="image 'big texture' alone takes"):
        glint_memory.check(dataclasses.replace(plan, images=(("big texture", 10**12),)), 64, 64,
                     available=10**11)
