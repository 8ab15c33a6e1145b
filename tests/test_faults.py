"""Fault injection: an error raised on purpose at each stage of a render, through each entry
point, must leave the previous output byte-for-byte intact, be reported in one line, and
leave no partial or temporary file.

Stages: export (the scene -> core step), tile (a MemoryError inside a tile, as a huge render
raises it), hand-over (the core's image -> the job's result, and for the engine the
job's image -> Blender's render result), write (the image file: render.py and python -m core
write through core.png, which fails on its second block of rows, as a full disk would).
Blender writes the engine's files itself (C code), so there the write stage is Blender's and
not injected; the Render button writes an Image datablock, not a file.

Entry points: the engine (F12 with write_still, which is also what ``blender -b -f`` runs),
the Render button (``bpy.ops.glint.render()``), render.py and ``python -m core`` (the last two
in child processes, as users run them, through tests/fault_child.py).
"""

from __future__ import annotations

import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

from addon_support import REPOSITORY, glint, invert_compositor, read_image, simple_scene

import glint.addon.engine.final as final  # noqa: E402
import glint.addon.engine.job as job  # noqa: E402
import glint.addon.operators as operators  # noqa: E402

pytestmark = pytest.mark.slow  # every test here takes seconds (child processes)

# The module whose tiles the add-on's small renders run (on threads).
core_threads = sys.modules["glint.core.threads"]
FAULT_CHILD = os.path.join(REPOSITORY, "tests", "fault_child.py")


class Injected(Exception):
    pass


def _raise(error):
    def broken(*args, **kwargs):
        raise error
    return broken


ADDON_FAULTS = {
    "export": (job, "export_scene", Injected("injected fault: export")),
    "tile": (core_threads, "render_tile", MemoryError("injected fault: tile")),
    "hand-over": (job, "JobResult", Injected("injected fault: hand-over")),
}


def inject(monkeypatch, stage, own_stages):
    """Make ``stage`` fail: one of ADDON_FAULTS or of the entry point's ``own_stages``
    ({stage: (module, name, error)})."""
    module, name, error = {**ADDON_FAULTS, **own_stages}[stage]
    monkeypatch.setattr(module, name, _raise(error))


def engine_output(tmp_path, name="frame.png"):
    scene = bpy.context.scene
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / name)
    scene.render.image_settings.file_format = 'PNG'
    return tmp_path / name


@pytest.mark.parametrize("stage", [*ADDON_FAULTS, "render result"])
def test_engine_write_still_keeps_the_previous_file(tmp_path, monkeypatch, stage):
    simple_scene()
    output = engine_output(tmp_path)
    bpy.ops.render.render(write_still=True)
    previous = output.read_bytes()
    inject(monkeypatch, stage,
           {"render result": (final, "blender_pixels", Injected("injected fault"))})

    with pytest.raises(RuntimeError) as raised:
        bpy.ops.render.render(write_still=True)

    (line,) = str(raised.value).strip().splitlines()
    assert line.startswith("Error: ")
    if stage == "tile":
        assert "ran out of memory" in line and "lower the resolution" in line
    else:
        assert "Injected" in line and "internal error" in line
    assert output.read_bytes() == previous
    assert os.listdir(tmp_path) == ["frame.png"]


def test_engine_animation_stops_at_a_failed_frame_and_keeps_earlier_files(tmp_path,
                                                                           monkeypatch):
    scene = simple_scene()
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "frame_")
    scene.render.image_settings.file_format = 'PNG'
    scene.frame_start, scene.frame_end = 1, 3
    # Blender writes the render time and date into each PNG: frame 1, rendered again, must
    # come out byte for byte the same, so leave them out.
    scene.render.use_stamp_render_time = scene.render.use_stamp_date = False
    scene.render.use_stamp_time = False
    bpy.ops.render.render(animation=True)
    previous = {name: (tmp_path / name).read_bytes() for name in os.listdir(tmp_path)}
    assert len(previous) == 3
    frame_3_written = (tmp_path / "frame_0003.png").stat().st_mtime_ns
    run = job.RenderJob.run

    def fail_on_frame_2(self, *args, **kwargs):
        if bpy.context.scene.frame_current == 2:
            raise Injected("injected fault on frame 2")
        return run(self, *args, **kwargs)

    monkeypatch.setattr(job.RenderJob, "run", fail_on_frame_2)
    with pytest.raises(RuntimeError, match="frame 2"):
        bpy.ops.render.render(animation=True)

    # Frame 1 was rendered again; the failed frame 2 and frame 3, where the animation
    # stopped, keep their previous files.
    assert sorted(os.listdir(tmp_path)) == sorted(previous)
    for name in ("frame_0002.png", "frame_0003.png"):
        assert (tmp_path / name).read_bytes() == previous[name]
    assert (tmp_path / "frame_0003.png").stat().st_mtime_ns == frame_3_written


@pytest.mark.parametrize("stage", [*ADDON_FAULTS, "image write"])
def test_render_button_keeps_the_previous_image(monkeypatch, stage):
    simple_scene()
    assert bpy.ops.glint.render() == {'FINISHED'}
    image = bpy.data.images["Glint Render"]
    previous = read_image(image)
    bpy.data.objects["small"].location.x -= 0.5  # a new render would differ
    inject(monkeypatch, stage,
           {"image write": (operators, "write_image", Injected("injected fault"))})

    with pytest.raises(RuntimeError) as raised:
        bpy.ops.glint.render()

    (line,) = str(raised.value).strip().splitlines()
    assert "Injected" in line or "ran out of memory" in line
    np.testing.assert_array_equal(read_image(bpy.data.images["Glint Render"]), previous)
    assert [i.name for i in bpy.data.images] == ["Glint Render"]


def run_with_fault(stage, entry, *arguments):
    return subprocess.run([sys.executable, FAULT_CHILD, stage, entry, *map(str, arguments)],
                          capture_output=True, text=True, timeout=300, cwd=REPOSITORY)


STAGES = ["export", "tile", "hand-over", "write"]


def script_source(tmp_path, source):
    """render.py's arguments for a 40 x 30 frame and the file they write: the article's
    scene to --output (the engine's frame saved by render.py), a .blend with a compositor
    (Blender's render result after compositing), or a .blend's own output path and format
    (no --output)."""
    if source == "article":
        output = tmp_path / "out.png"
        return output, ["--output", output, "--width", 40, "--height", 30]
    scene = simple_scene()
    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    output = tmp_path / "out_1.png"
    if source == "compositor":
        invert_compositor(scene)
        arguments = ["--output", output]
    else:
        scene.render.filepath = str(tmp_path / "out_#")
        scene.render.image_settings.file_format = 'PNG'
        arguments = ["--frame", 1]
    blend = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    return output, [blend, *arguments]


@pytest.mark.parametrize("source", ["article", "compositor", "scene output"])
@pytest.mark.parametrize("stage", STAGES)
def test_render_script_keeps_the_previous_file(tmp_path, stage, source):
    output, arguments = script_source(tmp_path, source)
    output.write_bytes(b"the user's previous render")
    before = sorted(os.listdir(tmp_path))

    result = run_with_fault(stage, "render.py", *arguments)

    assert result.returncode == 1, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("render.py: error:") and "injected fault" in line or \
        "ran out of memory" in line
    assert output.read_bytes() == b"the user's previous render"
    assert sorted(os.listdir(tmp_path)) == before


# (The .npy writer is NumPy's np.save into core.png.atomic_file; the write stage injected
# is the PNG encoder's.)
@pytest.mark.parametrize("stage, suffix", [("export", ".png"), ("tile", ".png"),
                                           ("write", ".png"), ("export", ".npy"),
                                           ("tile", ".npy")])
def test_core_command_keeps_the_previous_file(tmp_path, stage, suffix):
    output = tmp_path / f"out{suffix}"
    output.write_bytes(b"the user's previous render")

    result = run_with_fault(stage, "core", "--output", output, "--width", 40, "--height", 30)

    assert result.returncode != 0
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error:")
    assert "injected fault" in line or "out of memory" in line
    assert output.read_bytes() == b"the user's previous render"
    assert os.listdir(tmp_path) == [f"out{suffix}"]
