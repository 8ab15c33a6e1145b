"""render.py's animations (--frames, #-padded outputs, Blender's overwrite/placeholder frame
claiming shared by several processes), its progress line, and EXR output."""

from __future__ import annotations

import os
import pty
import subprocess
import sys

import bpy
import numpy as np
import pytest

from addon_support import (RENDER_SCRIPT, REPOSITORY, add_camera, core_image, depsgraph,
                           prepare_job, read_png, simple_scene)
from exr import read_exr

from glint.addon.cli.frames import FrameClaim, frame_path  # noqa: E402


def run_script(*arguments, **kwargs):
    return subprocess.run([sys.executable, RENDER_SCRIPT, *map(str, arguments)],
                          capture_output=True, text=True, timeout=300, cwd=REPOSITORY, **kwargs)


def animated_blend(tmp_path, frames=4, size=(40, 30)):
    """A .blend whose small sphere moves across frames 1..frames (scene range 1..frames)."""
    scene = simple_scene()
    scene.render.resolution_x, scene.render.resolution_y = size
    small = bpy.data.objects["small"]
    for frame in range(1, frames + 1):
        small.location.x = -1.2 + 0.6 * frame
        small.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end = 1, frames
    path = tmp_path / "animated.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def png(path) -> np.ndarray:
    """(H, W, 4) uint8 of a PNG render.py wrote (Blender's encoder: read back by Blender)."""
    return read_png(str(path))


def test_frame_paths_follow_blenders_hash_padding():
    assert frame_path("out/frame_####.png", 7) == "out/frame_0007.png"
    assert frame_path("out/f_#.png", 123) == "out/f_123.png"
    assert frame_path("out/a##_b###.exr", 5) == "out/a##_b005.exr"   # the last run counts
    assert frame_path("out/f_####.png", -3) == "out/f_-0003.png"   # as Blender numbers it
    assert frame_path("out/still.png", -7, animation=True) == "out/still-0007.png"
    assert frame_path("out/still.png", 7) == "out/still.png"
    assert frame_path("out/still.png", 7, animation=True) == "out/still0007.png"
    # Blender's own numbering of the same templates, to its frame limits.
    render = simple_scene().render     # a fresh file: PNG output
    for template in ("/out/f_####.png", "/out/f_#.png", "/out/a##_b###.png"):
        render.filepath = template
        for frame in (-1048574, -3, 0, 7, 123, 1048574):
            assert frame_path(template, frame) == render.frame_path(frame=frame), \
                (template, frame)


def test_frames_renders_each_frame_of_the_range_to_its_file(tmp_path):
    blend = animated_blend(tmp_path)

    (tmp_path / "out").mkdir()
    result = run_script(blend, "--output", tmp_path / "out" / "frame_####.png", "--frames",
                        "2-3")

    assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(tmp_path / "out")) == ["frame_0002.png", "frame_0003.png"]
    second, third = (png(tmp_path / "out" / name) for name in ("frame_0002.png",
                                                                 "frame_0003.png"))
    assert not np.array_equal(second, third)   # the sphere moved
    assert "wrote 2 of 2 frames, skipped 0" in result.stdout
    # Without a value, --frames is the scene's range (1-4 here).
    result = run_script(blend, "--output", tmp_path / "out" / "all_##.png", "--frames")
    assert result.returncode == 0, result.stderr
    assert sorted(n for n in os.listdir(tmp_path / "out") if n.startswith("all_")) == [
        "all_01.png", "all_02.png", "all_03.png", "all_04.png"]
    np.testing.assert_array_equal(png(tmp_path / "out" / "all_02.png"), second)


def test_no_overwrite_skips_existing_frames_and_placeholders_claim_them(tmp_path):
    blend = animated_blend(tmp_path)
    output = tmp_path / "f_#.png"
    (tmp_path / "f_2.png").touch()                      # another process's claim
    (tmp_path / "f_3.png").write_bytes(b"done before")  # a finished frame

    result = run_script(blend, "--output", output, "--frames", "1-4", "--no-overwrite",
                        "--placeholder")

    assert result.returncode == 0, result.stderr
    assert "skipped frame 2" in result.stdout and "skipped frame 3" in result.stdout
    assert (tmp_path / "f_2.png").read_bytes() == b""
    assert (tmp_path / "f_3.png").read_bytes() == b"done before"
    assert png(tmp_path / "f_1.png").shape == (30, 40, 4)
    assert png(tmp_path / "f_4.png").shape == (30, 40, 4)
    # Overwrite on (Blender's default): every frame is rendered again.
    result = run_script(blend, "--output", output, "--frames", "1-4", "--overwrite")
    assert result.returncode == 0 and "wrote 4 of 4" in result.stdout
    assert png(tmp_path / "f_3.png").shape == (30, 40, 4)


def test_two_processes_split_one_range_without_rendering_a_frame_twice(tmp_path):
    # Slow enough frames (16 anti-aliasing samples at 160 x 120) that both processes are at
    # work at once.
    blend = animated_blend(tmp_path, frames=12, size=(160, 120))
    output = tmp_path / "shared" / "frame_####.png"
    output.parent.mkdir()
    command = [sys.executable, RENDER_SCRIPT, str(blend), "--output", str(output), "--frames",
               "--no-overwrite", "--placeholder", "--samples", "16"]
    workers = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, cwd=REPOSITORY) for _ in range(2)]
    outputs = [worker.communicate(timeout=300) for worker in workers]

    assert [worker.returncode for worker in workers] == [0, 0], outputs
    written = [{line.split("(frame ")[1].split(",")[0] for line in out.splitlines()
                if "(frame " in line} for out, _ in outputs]
    assert not written[0] & written[1]              # no frame rendered twice
    assert written[0] | written[1] == {str(f) for f in range(1, 13)}
    names = sorted(os.listdir(output.parent))
    assert names == [f"frame_{f:04d}.png" for f in range(1, 13)]
    assert all(png(output.parent / name).shape == (120, 160, 4) for name in names)
    print("frames per process:", [len(w) for w in written])


def test_a_placeholder_is_released_when_its_frame_was_not_written(tmp_path):
    path = str(tmp_path / "f_0001.png")
    claim = FrameClaim(path, overwrite=False, placeholder=True)
    assert claim.claimed and os.path.getsize(path) == 0
    assert not FrameClaim(path, overwrite=False, placeholder=True).claimed
    claim.release()
    assert not os.path.exists(path)

    written = FrameClaim(path, overwrite=False, placeholder=True)
    open(path, "wb").write(b"a finished frame")
    written.release()                               # a written frame is never removed
    assert open(path, "rb").read() == b"a finished frame"


def run_with_terminal_stderr(*arguments):
    """(exit status, what the child wrote to its stderr, a pseudo-terminal)."""
    leader, follower = pty.openpty()
    child = subprocess.Popen([sys.executable, RENDER_SCRIPT, *map(str, arguments)],
                             stdout=subprocess.DEVNULL, stderr=follower, cwd=REPOSITORY)
    os.close(follower)
    chunks = []
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:       # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(leader)
    return child.wait(timeout=300), b"".join(chunks).decode(errors="replace")


def test_a_progress_line_on_a_terminal_and_none_in_a_pipe_or_with_quiet(tmp_path):
    arguments = ("--output", tmp_path / "p.png", "--width", 600, "--height", 400,
                 "--samples", 4)

    status, terminal = run_with_terminal_stderr(*arguments)

    assert status == 0, terminal
    lines = [part for part in terminal.split("\r") if "tiles" in part]
    assert lines, terminal
    assert "%" in lines[-1] and "/20 tiles" in lines[-1] and "s elapsed" in lines[-1]
    assert any("s left" in line for line in lines)
    piped = run_script(*arguments)
    assert piped.returncode == 0 and "tiles" not in piped.stderr
    status, quiet = run_with_terminal_stderr(*arguments, "--quiet")
    assert status == 0 and "tiles" not in quiet


def test_exr_output_holds_the_scene_linear_render(tmp_path):
    scene = simple_scene()
    scene.render.image_settings.exr_codec = 'NONE'
    expected = prepare_job(depsgraph()).scene_linear(core_image())[..., :3]
    blend = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)

    result = run_script(blend, "--output", tmp_path / "out.exr")

    assert result.returncode == 0, result.stderr
    channels = read_exr(tmp_path / "out.exr")
    assert set(channels) == {"R", "G", "B", "A"}
    rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
    # Blender's float32 result of the job's scene-linear float32 values.
    np.testing.assert_allclose(rgb, expected, atol=1e-5)
    assert (channels["A"] == 1).all()


def test_multilayer_exr_holds_every_view_layer(tmp_path):
    scene = simple_scene()
    scene.view_layers.new("Spheres only")
    for layer in scene.view_layers:
        layer.use_pass_z = layer.use_pass_normal = True
    scene.render.image_settings.exr_codec = 'NONE'
    blend = tmp_path / "layers.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)

    result = run_script(blend, "--output", tmp_path / "layers.exr", "--format",
                        "multilayer-exr")

    assert result.returncode == 0, result.stderr
    channels = read_exr(tmp_path / "layers.exr")
    for layer in ("ViewLayer", "Spheres only"):
        assert {f"{layer}.Combined.{c}" for c in "RGBA"} <= set(channels)
        assert {f"{layer}.Depth.Z"} | {f"{layer}.Normal.{c}" for c in "XYZ"} <= set(channels)
        depth = channels[f"{layer}.Depth.Z"]
        assert (depth < 10).any() and (depth == np.float32(1e10)).any()
    np.testing.assert_array_equal(channels["ViewLayer.Combined.R"],
                                  channels["Spheres only.Combined.R"])


@pytest.mark.parametrize("arguments, message", [
    (("--frames", "5-2"), "the end frame comes before the start"),
    (("--frames", "x"), "--frames must be START-END or N"),
    (("--frames", "1-2", "--frame", "3"), "--frame and --frames exclude each other"),
    (("--format", "exr"), "--format exr writes .exr files"),
    # Blender's frames end at +-1048574 (frame_set would clamp beyond: copies of the last
    # frame under other numbers); a range is checked before a single frame is made.
    (("--frames", "1-100000000"), "frame 100000000 is outside Blender's frame range "
                                  "-1048574 to 1048574"),
    (("--frames", "1048573-1048576"), "frame 1048576 is outside Blender's frame range"),
    (("--frames=-1048575--1048570",), "frame -1048575 is outside Blender's frame range"),
    (("--frames", "99999999999999999999"), "frame 99999999999999999999 is outside"),
    (("--frame", "99999999999999999999"), "--frame 99999999999999999999 is outside"),
])
def test_bad_animation_arguments_fail_with_one_line(tmp_path, arguments, message):
    result = run_script("--output", tmp_path / "o.png", *arguments)
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not os.listdir(tmp_path)


def test_blenders_frame_limits_are_those_the_arguments_check():
    from glint.addon.cli.arguments import MAX_FRAME, MIN_FRAME

    frame = bpy.types.Scene.bl_rna.properties["frame_current"]
    assert (MIN_FRAME, MAX_FRAME) == (frame.hard_min, frame.hard_max)


def test_the_frames_of_a_range_are_made_one_at_a_time():
    from types import SimpleNamespace

    from glint.addon.cli.arguments import MAX_FRAME, MIN_FRAME
    from glint.addon.cli.frames import animation_frames

    scene = simple_scene()
    frames = animation_frames(scene, SimpleNamespace(frame_range=(MIN_FRAME, MAX_FRAME)))
    # Every frame Blender has: as many as asked for, in order, held in constant memory (a
    # list of these two million frames is 75 MB, made before the first frame renders).
    assert len(frames) == 2 * 1048574 + 1 and (frames[0], frames[-1]) == (MIN_FRAME, MAX_FRAME)
    assert sys.getsizeof(frames) < 1000
    scene.frame_start, scene.frame_end, scene.frame_step = 3, 11, 4
    assert list(animation_frames(scene, SimpleNamespace(frame_range=None))) == [3, 7, 11]


def test_sigterm_during_an_animation_says_how_many_frames_were_written(tmp_path):
    """A farm job stopped after some frames: exit 143 and one line saying how many frames
    were written; those files are complete, no other file was touched, and nothing is left
    half-written (here through the .blend's own output path, format and Placeholders)."""
    import signal
    import time

    blend = animated_blend(tmp_path, frames=4, size=(16, 12))
    scene = bpy.context.scene
    scene.render.filepath = str(tmp_path / "out" / "f_#######")
    scene.render.image_settings.file_format = 'PNG'
    scene.render.use_placeholder = True
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    (tmp_path / "out").mkdir()
    later = tmp_path / "out" / "f_1048574.png"
    later.write_bytes(b"a frame rendered before")
    # Waits for 3 frames written and the placeholder of the fourth (beside the later file).
    process = subprocess.Popen([sys.executable, RENDER_SCRIPT, str(blend), "--frames",
                                "1-1048574"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, cwd=REPOSITORY)
    deadline = time.monotonic() + 120
    while len(os.listdir(tmp_path / "out")) < 5 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert process.poll() is None, "the animation ended before the signal"
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=60)

    assert process.returncode == 143, err
    (line,) = err.strip().splitlines()
    written = sorted(name for name in os.listdir(tmp_path / "out") if name != later.name)
    assert len(written) >= 3 and written == [f"f_{f:07d}.png" for f in
                                             range(1, len(written) + 1)]
    assert line.startswith("render.py: error: cancelled by SIGTERM; frame ")
    assert f"wrote {len(written)} of 1048574 frames, skipped 0" in line
    assert len([text for text in out.splitlines() if "render.py: wrote" in text]) == \
        len(written)
    assert all(png(tmp_path / "out" / name).shape == (12, 16, 4) for name in written)
    assert later.read_bytes() == b"a frame rendered before"


def test_a_failed_frame_ends_the_animation_with_one_line_and_keeps_the_frames_before(
        tmp_path):
    """From frame 3 on, a timeline marker makes a panoramic camera the scene's (which Glint
    refuses): frames 1 and 2 are written, then one line names the frame, the reason and how
    many frames were written; nothing of frame 3 or 4 is left (their placeholders are
    removed), and the reason is said once, not again in a report from Blender."""
    animated_blend(tmp_path)
    scene = bpy.context.scene
    panoramic = add_camera("panoramic")
    panoramic.data.type = 'PANO'
    scene.camera = bpy.data.objects["camera"]
    scene.timeline_markers.new("plain", frame=1).camera = scene.camera
    scene.timeline_markers.new("panoramic", frame=3).camera = panoramic
    blend = tmp_path / "faulty.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)

    result = run_script(blend, "--output", tmp_path / "f_#.png", "--frames", "1-4",
                        "--placeholder")

    assert result.returncode == 1, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line == ("render.py: error: frame 3: camera 'panoramic' is panoramic: Glint renders "
                    "perspective and orthographic cameras only; wrote 2 of 4 frames, skipped 0")
    assert "is panoramic" not in result.stdout
    assert sorted(name for name in os.listdir(tmp_path) if name.startswith("f_")) == [
        "f_1.png", "f_2.png"]
