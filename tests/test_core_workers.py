"""Tiles in worker processes (core.workers): the same image bit for bit as one thread, tiles
finished in the parent, cancel, errors as themselves, fallback to threads, no re-run of the
caller's script."""

import dataclasses
import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import core
from core import shared_memory, workers
from core.failures import RenderCancelled
from core.tiles import render_tile
from core.validation import SceneError
from process_support import all_ended, sigint_disposition

pytestmark = pytest.mark.slow  # every test here takes seconds (child processes)

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def small_renders_in_processes(monkeypatch):
    """Let test-sized renders use processes (renders under MIN_PIXELS stay in-process)."""
    monkeypatch.setattr(workers, "MIN_PIXELS", 0)


def _settings(**values):
    return core.RenderSettings(**{"tile_size": 32, **values})


@pytest.mark.parametrize("semantics, anti_aliasing", [("article", "off"),
                                                      ("default", "adaptive")])
def test_processes_give_the_threads_image_bit_for_bit(small_renders_in_processes, semantics,
                                                      anti_aliasing):
    scene = core.article_scene(150, 100)
    common = dict(semantics=semantics, precision="float64", anti_aliasing=anti_aliasing,
                  samples=4)
    reference = core.render(scene, _settings(threads=1, **common))
    assert reference.parallelism == "threads"
    for count in (1, 2, 3):
        result = core.render(scene, _settings(threads=count, parallelism="processes", **common))
        assert result.parallelism == "processes"
        assert np.array_equal(result.image, reference.image)
        # Summed over the workers' tiles.  20 tiles on 3 workers end on the last one cut in
        # two (``render._even_tail``): a tile more, and with adaptive AA the cut's own
        # apron of pixel centres (more camera rays, the same pixels).
        assert result.stats.tiles == 20 + (count == 3)
        if count < 3 or anti_aliasing == "off":
            assert dataclasses.replace(result.stats, tiles=20) == reference.stats
        else:
            assert result.stats.camera_rays > reference.stats.camera_rays
        assert result.image.dtype == reference.image.dtype
        assert result.semantics == reference.semantics == semantics


def test_tiles_are_finished_in_the_parent(small_renders_in_processes):
    scene = core.article_scene(100, 70)
    landed, progress = [], []
    caller = threading.get_ident()

    def on_tile(tile, rgba):
        assert threading.get_ident() == caller
        landed.append((tile, rgba.copy()))

    result = core.render(scene, _settings(threads=2, parallelism="processes"),
                         on_tile=on_tile, progress=progress.append, image_dtype=np.float32)
    assert result.parallelism == "processes" and result.image.dtype == np.float32
    assert len(landed) == len(progress) == result.stats.tiles == 4 * 3
    assert progress[-1] == 1.0
    for (y0, y1, x0, x1), rgba in landed:
        assert np.array_equal(rgba, result.image[y0:y1, x0:x1])


def test_cancel_stops_the_workers_and_keeps_them_usable(small_renders_in_processes):
    scene = core.article_scene(160, 160)
    settings = _settings(threads=2, parallelism="processes", tile_size=16)
    landed = []
    with pytest.raises(RenderCancelled):
        core.render(scene, settings, on_tile=lambda tile, rgba: landed.append(tile),
                    should_cancel=lambda: len(landed) >= 1)
    assert 1 <= len(landed) < 100          # stopped long before the 100 tiles
    # The same workers render the next frame, whole and right.
    again = core.render(scene, settings)
    assert again.parallelism == "processes"
    assert np.array_equal(again.image, core.render(scene, _settings(threads=1,
                                                                    tile_size=16)).image)


def test_an_error_in_a_worker_is_raised_as_itself(small_renders_in_processes):
    from core.context import make_context

    scene = core.article_scene(64, 64)
    settings = _settings(semantics="article", precision="float64")
    ctx = make_context(scene, settings, np.float64)
    bad_tile = (0, 32)                    # not a (y0, y1, x0, x1) rectangle
    with pytest.raises(ValueError) as in_process:
        render_tile(ctx, scene.camera, bad_tile)
    with pytest.raises(ValueError) as in_worker:
        workers.render_tiles(ctx, scene.camera, [(0, 32, 0, 32), bad_tile], (64, 64, 4),
                             np.float64, 1, lambda *finished: None)
    assert str(in_worker.value) == str(in_process.value)
    assert "in a render worker process" in "".join(getattr(in_worker.value, "__notes__", []))


def test_fallback_to_threads_where_workers_cannot_start(small_renders_in_processes,
                                                        monkeypatch, tmp_path):
    scene = core.article_scene(64, 64)
    reference = core.render(scene, _settings(threads=1))
    fake = tmp_path / "python3"          # named like a Python, exits at once
    fake.write_text("#!/bin/sh\nexit 3\n")
    fake.chmod(0o755)
    workers.shutdown()
    real_python = sys.executable
    monkeypatch.setattr(workers, "unavailable_reason", None)
    monkeypatch.setattr(sys, "executable", str(fake))
    result = core.render(scene, _settings(threads=2, parallelism="processes"))
    assert result.parallelism == "threads"
    assert np.array_equal(result.image, reference.image)
    assert "exited while starting (exit code 3)" in workers.unavailable_reason
    assert workers._pool.workers == []       # no half-started worker is kept

    monkeypatch.setattr(workers, "unavailable_reason", None)
    monkeypatch.setattr(sys, "executable", "/bin/sh")   # not a Python at all
    result = core.render(scene, _settings(threads=2, parallelism="processes"))
    assert result.parallelism == "threads"
    assert "is not a Python" in workers.unavailable_reason

    monkeypatch.setattr(workers, "unavailable_reason", None)  # a real Python again
    monkeypatch.setattr(sys, "executable", real_python)
    assert core.render(scene, _settings(threads=2, parallelism="processes")).parallelism \
        == "processes"


def test_small_renders_and_single_tiles_stay_in_process():
    small = core.render(core.article_scene(64, 64), _settings(threads=2,
                                                              parallelism="processes"))
    assert small.parallelism == "threads"     # 4096 pixels < MIN_PIXELS


def test_parallelism_is_validated():
    with pytest.raises(SceneError, match="settings.parallelism must be one of"):
        core.RenderSettings(parallelism="gpu")


def test_workers_do_not_rerun_the_callers_script(tmp_path):
    """multiprocessing's spawn would run this unguarded script again in every worker."""
    log = tmp_path / "runs.log"
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent(f"""
        import core
        from core import workers
        with open({str(log)!r}, "a") as out:
            out.write("run\\n")
        workers.MIN_PIXELS = 0
        result = core.render(core.article_scene(96, 64), core.RenderSettings(
            tile_size=32, threads=2, parallelism="processes"))
        print(result.parallelism, len(workers._pool.workers))
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          cwd=REPOSITORY, env={**os.environ, "PYTHONPATH": REPOSITORY},
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["processes", "2"]
    assert log.read_text() == "run\n"


def test_shutdown_ends_the_workers(small_renders_in_processes):
    core.render(core.article_scene(64, 64), _settings(threads=2, parallelism="processes"))
    processes = [worker.process for worker in workers._pool.workers]
    assert len(processes) == 2 and all(p.poll() is None for p in processes)
    workers.shutdown()
    assert all(p.poll() is not None for p in processes)
    assert workers._pool.workers == []


def test_workers_import_core_under_a_blender_extension_name(tmp_path):
    """Inside Blender the core is ``bl_ext.<repository>.glint.core``, whose parents a plain
    Python cannot import: the workers stand in for them and load core from its folder."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {os.path.join(REPOSITORY, 'core')!r})
        import _worker_boot
        sys.path.pop(0)
        core = _worker_boot.load_core("bl_ext.user_default.glint.core",
                                      {os.path.join(REPOSITORY, 'core')!r})
        import importlib
        workers = importlib.import_module("bl_ext.user_default.glint.core.workers")
        workers.MIN_PIXELS = 0
        import numpy as np
        scene = core.article_scene(96, 64)
        result = core.render(scene, core.RenderSettings(tile_size=32, threads=2,
                                                        parallelism="processes"))
        alone = core.render(scene, core.RenderSettings(tile_size=32, threads=1))
        print(result.parallelism, np.array_equal(result.image, alone.image),
              "core" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=str(tmp_path), timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["processes", "True", "False"]


def test_ctrl_c_to_the_process_group_stops_parent_and_workers(tmp_path):
    """A terminal's Ctrl-C reaches every process of the group: the workers ignore it, the
    parent cancels, ends them and writes nothing."""
    import signal
    import time

    output = tmp_path / "out.png"
    output.write_bytes(b"previous render")
    process = subprocess.Popen(
        [sys.executable, "-m", "core", "--width", "1920", "--height", "1080",
         "--anti-aliasing", "fixed", "--samples", "64", "--parallelism", "processes",
         "--threads", "2", "--output", str(output)],
        cwd=REPOSITORY, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, preexec_fn=sigint_disposition())
    deadline = time.monotonic() + 30
    children = []
    while len(children) < 2 and time.monotonic() < deadline:   # the 2 workers
        time.sleep(0.2)
        children = subprocess.run(["ps", "-o", "pid=", "--ppid", str(process.pid)],
                                  capture_output=True, text=True).stdout.split()
    time.sleep(1.0)                          # the workers are rendering
    assert process.poll() is None, "the render ended before the signal: make it bigger"
    assert len(children) >= 2
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    (line,) = err.strip().splitlines()
    assert "cancelled by SIGINT" in line
    assert output.read_bytes() == b"previous render"

    assert all_ended(children, seconds=10)


def test_workers_start_from_a_pip_bpy_process():
    """With pip bpy, sys.executable is the venv's Python and core is render.py's glint.core;
    the workers import neither bpy nor the add-on."""
    code = textwrap.dedent(f"""
        import importlib, sys
        sys.path.insert(0, {REPOSITORY!r})
        import bpy, numpy as np
        import render
        render.import_glint()
        core = importlib.import_module("glint.core")
        workers = importlib.import_module("glint.core.workers")
        workers.MIN_PIXELS = 0
        scene = core.article_scene(96, 64)
        result = core.render(scene, core.RenderSettings(tile_size=32, threads=2,
                                                        parallelism="processes"))
        alone = core.render(scene, core.RenderSettings(tile_size=32, threads=1))
        print(result.parallelism, np.array_equal(result.image, alone.image))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=180)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-2:] == ["processes", "True"]


@pytest.mark.parametrize("parallelism", ["threads", "processes"])
def test_a_tile_with_nan_is_the_same_render_error(small_renders_in_processes, monkeypatch,
                                                  parallelism):
    """No accepted scene makes NaN; a bug that did (here: NaN diffuse colours slipped into
    the context) must stop the render with one line, whichever process traced the tile."""
    import dataclasses
    import importlib

    core_render = importlib.import_module("core.render")   # core.render is also the function

    def poisoned_context(*args, **kwargs):
        ctx = make_context(*args, **kwargs)
        materials = dataclasses.replace(ctx.materials, diffuse=ctx.materials.diffuse * np.nan)
        return dataclasses.replace(ctx, materials=materials)

    make_context = core_render.make_context
    monkeypatch.setattr(core_render, "make_context", poisoned_context)
    with pytest.raises(core_render.RenderError, match=r"pixels \d+-\d+ x \d+-\d+ came out NaN"):
        core.render(core.article_scene(64, 64), _settings(threads=2, parallelism=parallelism))


def test_a_tree_scene_of_meshes_and_sphere_sets_renders_the_same_in_workers(
        small_renders_in_processes):
    """The context sent to the workers carries a BVH, triangles and a sphere set."""
    rng = np.random.default_rng(3)
    materials = (core.Material(reflection=0.5), core.Material(diffuse=(0.8, 0.2, 0.1)))
    cloud = core.SphereSet(rng.uniform(-5, 5, (600, 3)), rng.uniform(0.02, 0.3, 600),
                           rng.integers(0, 2, 600), materials, name="cloud")
    corners = rng.uniform(-4, 4, (100, 3, 3))
    soup = core.TriangleMesh(corners.reshape(-1, 3), np.arange(300).reshape(100, 3), None,
                             rng.integers(0, 2, 100), materials, name="soup")
    scene = core.Scene(camera=core.ScreenCamera(96, 64, eye=(0, 0, 12)), sphere_sets=(cloud,),
                       meshes=(soup,), lights=(core.PointLight((3, 20, 8)),))
    reference = core.render(scene, _settings(threads=1))
    result = core.render(scene, _settings(threads=2, parallelism="processes"))
    assert result.parallelism == "processes"
    assert reference.stats.node_tests > 0            # the tree was used
    assert np.array_equal(result.image, reference.image)
    assert result.stats == reference.stats


def _open_files():
    """What this process's descriptors refer to (the listing's own one is gone once read)."""
    files = []
    for name in os.listdir("/proc/self/fd"):
        try:
            files.append(os.readlink(f"/proc/self/fd/{name}"))
        except FileNotFoundError:
            pass
    return sorted(files)


def test_large_arrays_reach_the_workers_through_shared_memory(small_renders_in_processes):
    """A big sphere set's arrays (and its tree's) leave the pickle for the shared file; the
    workers' image is the threads' bit for bit, and no descriptor is left open."""
    rng = np.random.default_rng(5)
    count = 20_000
    cloud = core.SphereSet(rng.uniform(-5, 5, (count, 3)), rng.uniform(0.01, 0.05, count),
                           rng.integers(0, 2, count),
                           (core.Material(), core.Material(diffuse=(0.2, 0.8, 0.1))),
                           name="cloud")
    scene = core.Scene(camera=core.ScreenCamera(96, 64, eye=(0, 0, 12)), sphere_sets=(cloud,),
                       lights=(core.PointLight((3, 20, 8)),))
    settings = _settings(threads=2, parallelism="processes")
    core.render(scene, settings)     # the workers warm: each has ended a render (below)
    result = core.render(scene, settings)
    reference = core.render(scene, _settings(threads=1))
    assert result.parallelism == "processes"
    assert np.array_equal(result.image, reference.image)
    # The shared file is gone everywhere once the render has ended: this process closed
    # its descriptor, and each worker dropped its mapping with the render's context.
    assert not [name for name in _open_files() if "glint-scene" in name]
    for pid in workers.worker_pids():
        with open(f"/proc/{pid}/maps") as maps:
            assert "glint-scene" not in maps.read()

    from core.render import canonical_scene, choose_precision, make_context
    canonical = canonical_scene(scene, settings)
    ctx = make_context(canonical, settings, choose_precision(canonical, settings.precision))
    shared = shared_memory._SharedPayload((ctx, canonical.camera))
    try:
        assert shared.size >= count * 3 * 8           # at least the centres went out of band
        assert all(size >= shared_memory.SHARED_ARRAY_BYTES for _, size, _ in shared.layout)
        assert len(shared.payload) < shared.size / 10
    finally:
        shared.close()
    assert shared.descriptor is None


def test_shared_arrays_load_writable_and_copy_on_write():
    """What a worker loads is the parent's arrays, writable where the parent's were (a write
    stays private), read-only where they were frozen."""
    import mmap

    big = np.arange(shared_memory.SHARED_ARRAY_BYTES // 8 * 3, dtype=np.float64).reshape(3, -1)
    small = np.arange(10)
    frozen = np.ones(shared_memory.SHARED_ARRAY_BYTES)
    frozen.flags.writeable = False
    shared = shared_memory._SharedPayload({"big": big, "small": small, "view": big[1],
                                           "frozen": frozen})
    try:
        assert len(shared.layout) == 3     # big, its row and frozen; small stays in band
        loads = []
        for _ in range(2):
            mapping = mmap.mmap(shared.descriptor, shared.size, flags=mmap.MAP_PRIVATE,
                                prot=mmap.PROT_READ | mmap.PROT_WRITE)
            loads.append(shared_memory._shared_loads(shared.payload, mapping, shared.layout))
    finally:
        shared.close()
    first, second = loads
    assert np.array_equal(first["big"], big) and np.array_equal(first["small"], small)
    assert np.array_equal(first["view"], big[1])
    first["big"][0, 0] = -1.0                         # writable, and private to this load
    assert second["big"][0, 0] == 0.0 and big[0, 0] == 0.0
    assert np.array_equal(first["frozen"], frozen) and not first["frozen"].flags.writeable


def test_the_memory_plan_counts_the_workers(small_renders_in_processes, monkeypatch):
    """Memory that fits a threaded render but not the shared image and the workers: the
    render with processes is refused before anything starts, naming what it needs."""
    import importlib

    memory = importlib.import_module("core.memory")
    scene = core.article_scene(64, 64)
    settings = _settings(threads=2, parallelism="threads")
    threaded = memory.plan(scene, settings, np.float64, 2)
    monkeypatch.setattr(memory, "available_memory",
                        lambda: threaded.total + memory.HEADROOM + 1024)
    assert core.render(scene, settings).parallelism == "threads"
    with pytest.raises(memory.NotEnoughMemory, match="a 64x64 render needs about"):
        core.render(scene, _settings(threads=2, parallelism="processes"))


def test_a_worker_that_dies_is_a_render_error_and_is_replaced(small_renders_in_processes):
    import importlib
    import signal

    scene = core.article_scene(160, 160)
    settings = _settings(threads=2, parallelism="processes", tile_size=16)
    # Two workers, warm: under load the parent can finish a frame before a cold worker is
    # ready (it renders tiles itself meanwhile), and a worker still starting that dies is a
    # worker that failed to start (the parent finishes the frame), not this test's case.
    for _ in range(20):
        core.render(scene, settings)
        if workers.last_render_here == 0:
            break
    assert workers.last_render_here == 0, "the workers never became ready"
    victim = workers.worker_pids()[0]

    def kill_on_first_tile(tile, rgba):
        if victim in workers.worker_pids():
            os.kill(victim, signal.SIGKILL)

    render_module = importlib.import_module("core.render")   # core.render is the function
    with pytest.raises(render_module.RenderError,
                       match=r"a render worker process died \(exit code -9\)"):
        core.render(scene, settings, on_tile=kill_on_first_tile)
    assert victim not in workers.worker_pids()
    again = core.render(scene, settings)             # a new worker takes its place
    assert again.parallelism == "processes" and len(workers.worker_pids()) == 2
    assert np.array_equal(again.image, core.render(scene, _settings(threads=1,
                                                                    tile_size=16)).image)


def test_a_stray_module_at_the_front_of_the_path_does_not_break_the_workers(
        small_renders_in_processes, monkeypatch, tmp_path):
    """pytest puts the checkout's parent folder first on sys.path; a stray inspect.py or
    dataclasses.py there must not shadow the standard library in a worker, which imports
    everything afresh (the parent imported the real ones long before)."""
    for name in ("inspect", "dataclasses"):
        (tmp_path / f"{name}.py").write_text("raise ImportError('a stray module')\n")
    scene = core.article_scene(64, 64)
    reference = core.render(scene, _settings(threads=1))
    workers.shutdown()
    monkeypatch.setattr(workers, "unavailable_reason", None)
    monkeypatch.setattr(sys, "path", [str(tmp_path)] + sys.path)

    result = core.render(scene, _settings(threads=2, parallelism="processes"))

    assert result.parallelism == "processes", workers.unavailable_reason
    assert np.array_equal(result.image, reference.image)
    workers.shutdown()   # later tests start workers with the ordinary path


def test_an_image_the_caller_keeps_is_never_written_by_a_later_render(
        small_renders_in_processes):
    """Workers write straight into the result's memory (a frame every worker maps); a frame
    is used again only once nothing refers to its image, not even a view."""
    settings = _settings(threads=2, parallelism="processes")
    first = core.render(core.article_scene(96, 64), settings)
    kept_view = first.image[10:20]
    first_copy = first.image.copy()
    del first
    for size in ((96, 64), (96, 64), (64, 64)):   # same and smaller frames, several times
        other = core.render(core.article_scene(*size), _settings(
            threads=2, parallelism="processes", semantics="article"))
        assert other.parallelism == "processes"
        assert not np.shares_memory(other.image, kept_view)
    assert np.array_equal(kept_view, first_copy[10:20])


def test_frames_are_reused_and_no_descriptor_leaks(small_renders_in_processes):
    settings = _settings(threads=2, parallelism="processes")
    scene = core.article_scene(96, 64)
    result = core.render(scene, settings)
    result = core.render(scene, settings)          # the first is alive meanwhile: 2 frames
    descriptors = len(os.listdir("/proc/self/fd"))
    seen = set()
    for _ in range(6):
        result = core.render(scene, settings)      # the previous result is alive meanwhile
        seen |= {frame.id for frame in workers._pool.frames}
    assert result.parallelism == "processes"
    assert len(seen) == workers.KEPT_FRAMES == 2   # the two frames, taken in turn
    assert len(os.listdir("/proc/self/fd")) == descriptors


def test_an_image_outlives_shutdown(small_renders_in_processes):
    scene = core.article_scene(96, 64)
    result = core.render(scene, _settings(threads=2, parallelism="processes"))
    workers.shutdown()                               # frames closed, workers gone
    assert workers._pool.frames == []
    reference = core.render(scene, _settings(threads=1, parallelism="threads"))
    assert np.array_equal(result.image, reference.image)
    result.image[:] = 0                              # still the caller's, writable


def test_a_worker_dead_before_its_next_tile_is_sent_is_the_same_render_error(
        small_renders_in_processes):
    """Killed (and gone) just after its tile landed: the parent's next send to it breaks the
    pipe, which must be the RenderError of a dead worker, not a BrokenPipeError."""
    import importlib
    import signal

    scene = core.article_scene(160, 160)
    settings = _settings(threads=2, parallelism="processes", tile_size=16)
    core.render(scene, settings)                      # two workers, warm

    def kill_all_on_first_tile(tile, rgba):
        for worker in list(workers._pool.workers):
            if worker.process.poll() is None:
                os.kill(worker.process.pid, signal.SIGKILL)
                worker.process.wait()

    render_module = importlib.import_module("core.render")
    with pytest.raises(render_module.RenderError,
                       match=r"a render worker process died \(exit code -9\)"):
        core.render(scene, settings, on_tile=kill_all_on_first_tile)
    again = core.render(scene, settings)             # new workers take their place
    assert again.parallelism == "processes" and len(workers.worker_pids()) == 2


def slow_boot(tmp_path, monkeypatch, wait_for=None, then_exit=None):
    """Workers whose start waits (``wait_for``: until that file exists; else 2 s) and then
    either boots (core/_worker_boot.py) or exits with ``then_exit``."""
    real = workers._BOOT_FILE
    wrapper = tmp_path / "slow_boot.py"
    wait = (f"while not os.path.exists({str(wait_for)!r}): time.sleep(0.01)" if wait_for
            else "time.sleep(2.0)")
    finish = (f"sys.exit({then_exit})" if then_exit is not None else
              f"sys.argv[0] = {real!r}; runpy.run_path({real!r}, run_name='__main__')")
    wrapper.write_text(f"import os, runpy, sys, time\n{wait}\n{finish}\n")
    workers.shutdown()
    monkeypatch.setattr(workers, "unavailable_reason", None)
    monkeypatch.setattr(workers, "_BOOT_FILE", str(wrapper))


def test_while_workers_start_this_process_renders_tiles(small_renders_in_processes,
                                                        monkeypatch, tmp_path):
    """A cold start costs the frame nothing it could have rendered meanwhile: here the
    workers take 2 s to start and this process renders the whole (small) frame itself."""
    scene = core.article_scene(96, 64)
    reference = core.render(scene, _settings(threads=1, parallelism="threads"))
    slow_boot(tmp_path, monkeypatch)
    landed = []
    result = core.render(scene, _settings(threads=2, parallelism="processes"),
                         progress=landed.append)
    assert result.parallelism == "processes" and result.fallback is None
    assert workers.last_render_here == len(landed) == 6     # every tile, here
    assert np.array_equal(result.image, reference.image) and result.stats == reference.stats
    # The workers, up by now, owe that render's end: read at the next render's start.
    again = core.render(scene, _settings(threads=2, parallelism="processes"))
    assert again.parallelism == "processes" and workers.last_render_here == 0
    assert np.array_equal(again.image, reference.image)
    workers.shutdown()


def test_workers_that_fail_after_tiles_landed_leave_the_rest_to_this_process(
        small_renders_in_processes, monkeypatch, tmp_path):
    scene = core.article_scene(160, 160)
    settings = _settings(threads=2, parallelism="processes", tile_size=16)
    reference = core.render(scene, _settings(threads=1, parallelism="threads", tile_size=16))
    signal_file = tmp_path / "first tile landed"
    slow_boot(tmp_path, monkeypatch, wait_for=signal_file, then_exit=3)

    def on_tile(tile, rgba):
        signal_file.touch()        # the workers exit once a tile has landed

    result = core.render(scene, settings, on_tile=on_tile)
    assert result.parallelism == "threads"
    assert result.fallback == ("worker processes unavailable (a worker process exited while "
                               "starting (exit code 3)): rendered on threads")
    assert workers.last_render_here == 100     # the first tile, and the rest after the exit
    assert np.array_equal(result.image, reference.image) and result.stats == reference.stats
    assert workers._pool.workers == []


def test_auto_takes_processes_where_their_start_up_pays(monkeypatch):
    import importlib

    render_module = importlib.import_module("core.render")

    def in_processes(width, height, threads=2, tree=False, **settings):
        tiles = len(render_module._tiles(width, height, 128))
        return render_module._in_processes(core.RenderSettings(parallelism="auto", **settings),
                                           width * height, tiles, threads, tree)

    monkeypatch.setattr(workers, "one_render", False)   # a session: workers live on
    assert in_processes(1920, 1080)
    assert not in_processes(1920, 1080, threads=1)      # one worker only moves the work
    assert not in_processes(500, 500)                    # under MIN_PIXELS
    assert in_processes(500, 500, anti_aliasing="fixed", samples=4)   # 1 M samples
    assert in_processes(640, 360, tree=True)             # a tree's samples weigh more
    assert not in_processes(128, 128, tree=True)         # 164 k weighted samples
    monkeypatch.setattr(workers, "one_render", True)    # render once, then exit
    monkeypatch.setattr(workers, "warm", lambda count: False)
    assert not in_processes(1920, 1080)                  # 2 M samples: start-up does not pay
    assert in_processes(1920, 1080, anti_aliasing="fixed", samples=4)     # 8.3 M samples
    assert in_processes(3840, 2160)                      # 8.3 M
    assert in_processes(1920, 1080, tree=True)           # 20.7 M weighted samples
    monkeypatch.setattr(workers, "warm", lambda count: True)
    assert in_processes(1920, 1080)                      # already paid
    for parallelism in ("threads", "processes"):         # explicit choices are kept
        assert render_module._in_processes(core.RenderSettings(parallelism=parallelism),
                                           1920 * 1080, 135, 1) == (parallelism == "processes")


def test_python_m_core_renders_one_frame_so_auto_weighs_the_start_up(tmp_path):
    def run(*arguments):
        done = subprocess.run([sys.executable, "-c", textwrap.dedent(f"""
            import sys
            from core import __main__ as main, workers
            ran = []
            real = main.render
            def recording(*args, **kwargs):
                result = real(*args, **kwargs)
                ran.append(result.parallelism)
                return result
            main.render = recording
            code = main.main({list(arguments)!r} + ["--output", {str(tmp_path / 'o.npy')!r}],
                             own_process=True)
            print(code, ran[0], workers.one_render)
        """)], capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stdout.split()[-3:]     # after main's "wrote ..." line

    size = ["--width", "800", "--height", "450", "--threads", "2"]
    assert run(*size) == ["0", "threads", "True"]
    assert run(*size, "--anti-aliasing", "fixed", "--samples", "32") == ["0", "processes",
                                                                         "True"]
    assert run(*size, "--parallelism", "processes") == ["0", "processes", "True"]
