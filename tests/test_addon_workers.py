"""Worker processes (core.workers) through Blender's paths, with headless pip bpy: F12 /
``render(write_still=True)`` and render.py render in processes with progress and cancel as
on threads and the same image for any worker count; the parallelism setting reaches the core;
the add-on's unregister ends the workers (register, unregister, register with workers alive
leaves no process behind); a Python that cannot start workers falls back with one line."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import bpy
import numpy as np
import pytest

from addon_support import REPOSITORY, RENDER_SCRIPT, depsgraph, glint, read_png, simple_scene
from glint.addon.engine.final import FrameRequest, requesting_frames
from glint.addon.engine.job import prepare_job
from glint.core import workers
from process_support import all_ended, sigint_disposition

TILE = 32
COLUMNS, ROWS = 5, 4


@pytest.fixture
def small_renders_in_processes(monkeypatch):
    """Let test-sized renders use processes (renders under MIN_PIXELS stay in-process)."""
    monkeypatch.setattr(workers, "MIN_PIXELS", 0)


def tiled_scene(parallelism: str, threads: int):
    """simple_scene() at COLUMNS x ROWS tiles of TILE pixels (through a tile size the engine
    passes on), Glint's parallelism and Blender's Performance > Threads set."""
    scene = simple_scene()
    scene.render.engine = 'GLINT'
    scene.render.resolution_x, scene.render.resolution_y = COLUMNS * TILE, ROWS * TILE
    scene.glint.parallelism = parallelism
    scene.render.threads_mode = 'FIXED'
    scene.render.threads = threads
    return scene


@pytest.fixture
def small_tiles(monkeypatch):
    """The engine's settings with TILE-pixel tiles, so a small frame has many tiles."""
    import dataclasses

    from glint.addon.engine import job as job_module

    render_settings = job_module.render_settings
    monkeypatch.setattr(job_module, "render_settings", lambda *args: dataclasses.replace(
        render_settings(*args), tile_size=TILE))


def f12(scene, path, request: FrameRequest):
    """bpy.ops.render.render(write_still=True), as F12 + save or ``blender -b -f``: the frame's
    (job, result) from the request, and the PNG Blender wrote."""
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.render.filepath = str(path)
    with requesting_frames(request):
        bpy.ops.render.render(write_still=True)
    return request.frames[-1] if request.frames else None


def test_the_parallelism_setting_reaches_the_core():
    for parallelism in ('PROCESSES', 'THREADS', 'AUTO'):
        tiled_scene(parallelism, 3)
        settings = prepare_job(depsgraph()).settings
        assert (settings.parallelism, settings.threads) == (parallelism.lower(), 3)


def test_f12_in_processes_gives_the_threads_image_with_progress_for_every_tile(
        tmp_path, small_renders_in_processes, small_tiles):
    reference_scene = tiled_scene('THREADS', 1)
    _, reference = f12(reference_scene, tmp_path / "threads.png", FrameRequest())
    assert reference.parallelism == "threads"
    reference_png = read_png(str(tmp_path / "threads.png"))
    for parallelism, count in (('PROCESSES', 1), ('PROCESSES', 2), ('PROCESSES', 3),
                               ('AUTO', 2)):
        scene = tiled_scene(parallelism, count)
        fractions = []
        path = tmp_path / f"{parallelism}{count}.png"
        job, result = f12(scene, path,
                          FrameRequest(progress=lambda job, fraction: fractions.append(fraction)))
        assert result.parallelism == "processes", (parallelism, count)
        assert len(workers.worker_pids()) >= count
        assert np.array_equal(result.image, reference.image), (parallelism, count)
        assert np.array_equal(read_png(str(path)), reference_png), (parallelism, count)
        # Progress came tile by tile, in the parent, up to the whole frame (the last tile cut
        # so that the tiles are a multiple of the workers: 21 pieces on 3).
        tiles = COLUMNS * ROWS
        assert len(fractions) == tiles + (-tiles % count) and fractions == sorted(fractions)
        assert fractions[-1] == 1.0


def test_f12_with_passes_in_processes_gives_the_threads_passes(
        tmp_path, small_renders_in_processes, small_tiles):
    """Render passes (old files keep Blender's former default Z pass on) no longer keep the
    tiles on threads: this process fills a tile's passes as it lands from a worker, the same
    values as beside each tile on threads."""
    frames = {}
    for parallelism, count in (('THREADS', 1), ('PROCESSES', 2)):
        scene = tiled_scene(parallelism, count)
        layer = scene.view_layers[0]
        for flag in ("use_pass_z", "use_pass_normal", "use_pass_object_index",
                     "use_pass_material_index"):
            setattr(layer, flag, True)
        frames[parallelism] = f12(scene, tmp_path / f"{parallelism}.png", FrameRequest())[1]
    threads, processes = frames['THREADS'], frames['PROCESSES']
    assert (threads.parallelism, processes.parallelism) == ("threads", "processes")
    assert np.array_equal(processes.image, threads.image)
    for name in ("depth", "position", "normal", "primitive", "material"):
        assert np.array_equal(getattr(processes.passes, name), getattr(threads.passes, name))
    assert (threads.passes.primitive >= 0).any() and (threads.passes.primitive < 0).any()


def test_a_cancelled_f12_in_processes_stops_within_the_tiles_in_flight(
        tmp_path, small_renders_in_processes, small_tiles):
    scene = tiled_scene('PROCESSES', 2)
    path = tmp_path / "frame.png"
    landed = []
    request = FrameRequest(should_cancel=lambda: len(landed) >= 2,
                           progress=lambda job, fraction: landed.append(fraction))
    assert f12(scene, path, request) is None           # the frame never finished
    # Tiles already rendering or queued when the cancel came may still land: at most two per
    # worker (TILES_IN_FLIGHT), then the stop byte ends the rest.
    assert 2 <= len(landed) <= 2 + 2 * workers.TILES_IN_FLIGHT < COLUMNS * ROWS
    # The same workers render the next frame, whole.
    _, result = f12(scene, path, FrameRequest())
    assert result.parallelism == "processes"
    assert result.image[..., 3].min() == 1.0


def child_processes() -> dict[int, str]:
    """{pid: state} of this process's children, zombies included (Linux's /proc)."""
    children = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == os.getpid():
            children[int(name)] = fields[0]
    return children


def test_register_unregister_register_with_workers_alive_leaves_no_process(
        tmp_path, small_renders_in_processes, small_tiles):
    workers.shutdown()
    before = child_processes()
    scene = tiled_scene('PROCESSES', 2)
    _, result = f12(scene, tmp_path / "a.png", FrameRequest())
    assert result.parallelism == "processes"
    alive = set(workers.worker_pids())
    assert len(alive) == 2 and alive <= set(child_processes())

    glint.unregister()            # as when the extension is disabled in Preferences
    try:
        after = child_processes()
        assert not alive & set(after), "a worker outlived the add-on (or is a zombie)"
        assert all(state != "Z" for state in after.values())
        assert set(after) <= set(before)       # nothing new left behind
        assert workers.worker_pids() == []
    finally:
        glint.register()

    scene = tiled_scene('PROCESSES', 2)
    _, again = f12(scene, tmp_path / "b.png", FrameRequest())
    assert again.parallelism == "processes"
    assert np.array_equal(again.image, result.image)
    fresh = set(workers.worker_pids())
    assert len(fresh) == 2 and not fresh & alive


def run_render_py(arguments, prelude=""):
    """render.py in its own process (a fresh Python: cold workers), with ``prelude`` run
    first."""
    code = prelude + textwrap.dedent(f"""
        import runpy, sys
        sys.argv = [{RENDER_SCRIPT!r}] + {list(arguments)!r}
        runpy.run_path({RENDER_SCRIPT!r}, run_name="__main__")
    """)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=300)


#: The article's scene, big enough (360,000 pixels, 28 tiles) for processes without a patch.
RENDER_PY_SIZE = ["--width", "800", "--height", "450"]


def test_render_py_with_processes_writes_the_threads_pixels(tmp_path):
    images = {}
    for parallelism in ("threads", "processes", "auto"):
        output = tmp_path / f"{parallelism}.png"
        done = run_render_py([*RENDER_PY_SIZE, "--parallelism", parallelism, "--output",
                              str(output)])
        assert done.returncode == 0, done.stderr
        assert "warning" not in (done.stdout + done.stderr).lower()
        images[parallelism] = read_png(str(output))
    assert np.array_equal(images["processes"], images["threads"])
    assert np.array_equal(images["auto"], images["threads"])


def test_render_py_where_workers_cannot_start_falls_back_with_one_line(tmp_path):
    output = tmp_path / "out.png"
    done = run_render_py([*RENDER_PY_SIZE, "--parallelism", "processes", "--output",
                          str(output)],
                         prelude="import sys\nsys.executable = '/bin/sh'\n")
    assert done.returncode == 0, done.stderr
    lines = [line for line in (done.stdout + done.stderr).splitlines()
             if "worker processes" in line]
    assert len(lines) == 1
    assert "is not a Python" in lines[0] and "rendered on threads" in lines[0]
    reference = tmp_path / "threads.png"
    assert run_render_py([*RENDER_PY_SIZE, "--parallelism", "threads", "--output",
                          str(reference)]).returncode == 0
    assert np.array_equal(read_png(str(output)), read_png(str(reference)))


def test_blender_rendering_one_frame_from_its_command_line_is_told_so():
    from glint.addon import renders_one_frame

    assert bpy.app.background   # headless, as on a render farm
    assert renders_one_frame(["blender", "-b", "scene.blend", "-f", "7"])
    assert renders_one_frame(["blender", "-b", "scene.blend", "--render-frame", "+1"])
    for several in (["-f", "1,3"], ["-f", "1..5"], ["-a"], ["-s", "1", "-e", "9", "-a"],
                    ["--python", "render.py", "--", "--frames", "1-9"], []):
        assert not renders_one_frame(["blender", "-b", "scene.blend", *several]), several


def test_ctrl_c_cancels_render_py_rendering_in_workers(tmp_path):
    """render.py's SIGINT cancel with the tiles in worker processes: exit 130 with one line,
    the previous file intact, and no worker left behind."""
    import signal
    import time

    output = tmp_path / "out.png"
    output.write_bytes(b"previous render")
    process = subprocess.Popen(
        [sys.executable, RENDER_SCRIPT, "--width", "1920", "--height", "1080", "--samples",
         "64", "--parallelism", "processes", "--quiet", "--output", str(output)],
        cwd=REPOSITORY, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=sigint_disposition())

    def children():
        return subprocess.run(["ps", "-o", "pid=", "--ppid", str(process.pid)],
                              capture_output=True, text=True).stdout.split()

    deadline = time.monotonic() + 60
    while len(children()) < 2 and time.monotonic() < deadline:   # bpy's import, then
        time.sleep(0.2)                                        # the workers start
    workers_seen = children()
    time.sleep(1.0)                                           # and render
    assert process.poll() is None, "the render ended before the signal: make it bigger"
    assert len(workers_seen) >= 2
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    (line,) = [text for text in err.splitlines() if text.strip()]
    assert "cancelled by SIGINT" in line
    assert output.read_bytes() == b"previous render"

    assert all_ended(workers_seen, seconds=10)   # they end as their socket closes
