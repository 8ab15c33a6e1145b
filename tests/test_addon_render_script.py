"""render.py: ``python render.py [scene.blend] --output OUT.png [options]`` with the pip bpy
module, in a child process as a user runs it (``blender -b scene.blend --python render.py --
...`` takes the same arguments after '--')."""

from __future__ import annotations

import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

from addon_support import (RENDER_SCRIPT, REPOSITORY, add_point_light, add_sphere, add_world,
                           animate_small_sphere, empty_file, invert_compositor, read_png,
                           simple_scene)

from glint.addon.compat import new_effect_strip, set_file_format  # noqa: E402

ARTICLE_REFERENCE = os.path.join(REPOSITORY, "tests", "data", "article_300x200.npy")


def run_script(*arguments, cwd=None):
    return subprocess.run([sys.executable, RENDER_SCRIPT, *map(str, arguments)],
                          capture_output=True, text=True, timeout=300, cwd=cwd or REPOSITORY)


def save_blend(path) -> str:
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return str(path)


def button_render(tmp_path=None):
    """The Render button's Image as Blender saves it with the scene's colour management."""
    bpy.ops.glint.render()
    path = os.path.join(str(tmp_path or bpy.app.tempdir), "button.png")
    bpy.data.images["Glint Render"].save_render(path, scene=bpy.context.scene)
    return read_png(path)


def read_script_png(path) -> np.ndarray:
    """(H, W, 4) uint8 of a PNG render.py wrote, checking it is 8-bit RGBA."""
    data = open(path, "rb").read()
    bit_depth, colour_type = data[24], data[25]  # in the IHDR chunk, which comes first
    assert (bit_depth, colour_type) == (8, 6), "not an 8-bit RGBA PNG"
    return read_png(str(path))


def error_lines(result) -> list[str]:
    return [line for line in result.stderr.splitlines() if line.startswith("render.py: error:")]


@pytest.mark.slow
def test_without_a_blend_it_renders_the_articles_scene(tmp_path):
    output = tmp_path / "article.png"

    result = run_script("--output", output)

    assert result.returncode == 0, result.stderr
    assert str(output) in result.stdout and " s" in result.stdout
    rgba = read_script_png(output)
    assert rgba.shape == (200, 300, 4) and (rgba[..., 3] == 255).all()
    # The article's image, up to Blender's pixel centres ((i + 0.5) / W instead of the
    # article's linspace): the same picture, edges shifted by under a pixel.
    reference = np.load(ARTICLE_REFERENCE)
    difference = np.abs(rgba[..., :3] / 255.0 - reference)
    assert difference.mean() < 0.005
    assert (difference.max(axis=2) > 0.1).mean() < 0.01
    black = (rgba[..., :3] == 0).all(axis=2).sum()
    assert abs(black - 29019) < 0.005 * 29019


@pytest.mark.slow
def test_arguments_may_follow_a_double_dash_as_under_blender(tmp_path):
    output = tmp_path / "small.png"
    result = run_script("--", "--output", output, "--width", 30, "--height", 20)
    assert result.returncode == 0, result.stderr
    assert read_script_png(output).shape == (20, 30, 4)


@pytest.mark.slow
def test_a_blend_with_options_renders_what_the_render_button_renders(tmp_path):
    scene = simple_scene()
    scene.glint.semantics = 'ARTICLE'
    blend = save_blend(tmp_path / "scene.blend")
    output = tmp_path / "out.png"

    result = run_script(blend, "--output", output, "--width", 50, "--height", 40,
                        "--percentage", 80, "--samples", 4, "--max-depth", 2,
                        "--semantics", "default", "--precision", "float64")

    assert result.returncode == 0, result.stderr
    scene.render.resolution_x, scene.render.resolution_y = 50, 40
    scene.render.resolution_percentage = 80
    scene.glint.samples, scene.glint.anti_aliasing = 4, 'FIXED'
    scene.glint.max_depth, scene.glint.semantics, scene.glint.precision = 2, 'DEFAULT', 'FLOAT64'
    np.testing.assert_array_equal(read_script_png(output), button_render())
    assert read_script_png(output).shape == (32, 40, 4)


@pytest.mark.slow
def test_frame_option_renders_that_frame(tmp_path):
    scene = simple_scene()
    animate_small_sphere(10)
    scene.frame_set(1)
    blend = save_blend(tmp_path / "animated.blend")

    result = run_script(blend, "--output", tmp_path / "f10.png", "--frame", 10)

    assert result.returncode == 0, result.stderr
    at_frame_1 = button_render()
    scene.frame_set(10)
    at_frame_10 = button_render()
    rendered = read_script_png(tmp_path / "f10.png")
    np.testing.assert_array_equal(rendered, at_frame_10)
    assert not np.array_equal(rendered, at_frame_1)


@pytest.mark.slow
def test_transparent_film_gives_coverage_alpha_and_a_transparent_background(tmp_path):
    scene = simple_scene()
    add_world("sky", (0.3, 0.5, 0.9))
    scene.render.film_transparent = True
    blend = save_blend(tmp_path / "transparent.blend")

    result = run_script(blend, "--output", tmp_path / "t.png")

    assert result.returncode == 0, result.stderr
    rgba = read_script_png(tmp_path / "t.png")
    background, covered = rgba[..., 3] == 0, rgba[..., 3] == 255
    partial = ~background & ~covered
    assert background.any() and covered.any() and partial.any()
    # Coverage: partial only on the silhouettes, which the pixel filter (Blackman-Harris,
    # 1.5 px: samples up to 1.5 px from the centre) spreads over 2 pixels at most.
    assert (_grown(background, 2) & _grown(covered, 2))[partial].all()
    assert (rgba[background] == 0).all()
    np.testing.assert_array_equal(rgba, button_render())


def _grown(mask, pixels: int):
    """mask, grown by ``pixels`` in every direction (a square)."""
    height, width = mask.shape
    padded = np.pad(mask, pixels)
    grown = np.zeros_like(mask)
    for dy in range(2 * pixels + 1):
        for dx in range(2 * pixels + 1):
            grown |= padded[dy:dy + height, dx:dx + width]
    return grown


@pytest.mark.slow
@pytest.mark.parametrize("view_transform", ["Standard", "AgX"])
def test_render_py_writes_the_pixels_f12_and_the_button_give(tmp_path, view_transform):
    scene = simple_scene()
    bpy.data.objects["light"].location = (-4.0, -6.0, 3.0)
    bpy.data.lights["light"].energy = 3000.0
    scene.view_settings.view_transform = view_transform
    blend = save_blend(tmp_path / "lit.blend")

    result = run_script(blend, "--output", tmp_path / "script.png")

    assert result.returncode == 0, result.stderr
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "f12.png")
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    bpy.ops.render.render(write_still=True)
    script = read_script_png(tmp_path / "script.png")
    np.testing.assert_array_equal(script, read_png(str(tmp_path / "f12.png")))
    np.testing.assert_array_equal(script, button_render(tmp_path))


@pytest.mark.slow
def test_an_unreadable_blend_fails_with_one_line_and_leaves_the_output_alone(tmp_path):
    corrupt = tmp_path / "corrupt.blend"
    corrupt.write_bytes(b"BLENDER-v500 this is not a blend file")
    output = tmp_path / "out.png"
    output.write_bytes(b"previous render")

    result = run_script(corrupt, "--output", output)

    assert result.returncode != 0
    (line,) = error_lines(result)
    assert "cannot open" in line and "corrupt.blend" in line
    assert "Error:" not in result.stdout     # not said again by Blender's report
    assert output.read_bytes() == b"previous render"
    assert sorted(os.listdir(tmp_path)) == ["corrupt.blend", "out.png"]


@pytest.mark.slow
def test_blenders_warnings_still_reach_stdout(tmp_path):
    scene = simple_scene()
    scene.render.use_motion_blur = True
    blend = save_blend(tmp_path / "blurred.blend")

    result = run_script(blend, "--output", tmp_path / "out.png")

    assert result.returncode == 0, result.stderr
    assert "Warning: Glint ignores these settings, which change what Cycles renders: motion " \
           "blur" in result.stdout


@pytest.mark.slow
def test_a_blend_without_camera_fails_with_one_line(tmp_path):
    empty_file()
    add_sphere()
    add_point_light()
    blend = save_blend(tmp_path / "nocamera.blend")

    result = run_script(blend, "--output", tmp_path / "out.png")

    assert result.returncode != 0
    (line,) = error_lines(result)
    assert "has no camera" in line
    assert sorted(os.listdir(tmp_path)) == ["nocamera.blend"]


BAD_ARGUMENTS = {
    "missing blend": (["{tmp}/missing.blend", "--output", "{tmp}/o.png"], "no such .blend"),
    "no output for the article's scene": ([], "--output is needed for the article's scene"),
    "format without output": (["--format", "png"], "--format png needs --output"),
    "output folder missing": (["--output", "{tmp}/nowhere/o.png"], "folder does not exist"),
    "output is a directory": (["--output", "{tmp}/folder.png"], "is a directory"),
    "output not png": (["--output", "{tmp}/o.jpg"], "must name a .png"),
    "zero width": (["--output", "{tmp}/o.png", "--width", "0"], "--width: must be at least 4"),
    "zero percentage": (["--output", "{tmp}/o.png", "--percentage", "0"],
                        "--percentage: must be at least 1"),
    "width below Blender's minimum": (["--output", "{tmp}/o.png", "--width", "3"],
                                      "--width: must be at least 4"),
    "height past Blender's maximum": (["--output", "{tmp}/o.png", "--height", "100000"],
                                      "--height: must be at most 65536"),
    "width not a number": (["--output", "{tmp}/o.png", "--width", "wide"], "--width"),
    "unknown semantics": (["--output", "{tmp}/o.png", "--semantics", "exact"], "--semantics"),
    "unknown precision": (["--output", "{tmp}/o.png", "--precision", "half"], "--precision"),
    "zero depth": (["--output", "{tmp}/o.png", "--max-depth", "0"], "--max-depth"),
    "huge percentage": (["--output", "{tmp}/o.png", "--percentage", "20000"], "--percentage"),
    "unknown option": (["--output", "{tmp}/o.png", "--turbo"], "--turbo"),
}


@pytest.mark.parametrize("case", BAD_ARGUMENTS, ids=list(BAD_ARGUMENTS))
def test_bad_arguments_fail_with_one_line_and_write_nothing(tmp_path, case):
    (tmp_path / "folder.png").mkdir()
    arguments, mentioned = BAD_ARGUMENTS[case]

    result = run_script(*[argument.format(tmp=tmp_path) for argument in arguments])

    assert result.returncode == 2
    assert result.stdout == ""
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("render.py: error:") and mentioned in line
    assert os.listdir(tmp_path) == ["folder.png"]


def test_the_arguments_are_checked_before_blender_is_loaded():
    """Importing the add-on and render.py's arguments loads no Blender module, so a mistake
    costs no Blender start-up."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import render; render.import_glint(); "
            "import glint.addon.cli.arguments; "
            "print(sorted(m for m in ('bpy', 'addon_utils', 'bmesh') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code, REPOSITORY], capture_output=True,
                            text=True, timeout=120, cwd=REPOSITORY)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_a_write_protected_output_is_refused_with_one_line(tmp_path):
    output = tmp_path / "kept.png"
    output.write_bytes(b"previous render")
    output.chmod(0o444)  # no write bit for anyone (root included, by Glint's rule)

    result = run_script("--output", output, "--width", 30, "--height", 20)

    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("render.py: error:") and "write-protected" in line
    assert output.read_bytes() == b"previous render"
    assert os.listdir(tmp_path) == ["kept.png"]


@pytest.mark.slow
def test_a_symlinked_output_is_written_through_and_stays_a_link(tmp_path):
    renders = tmp_path / "renders"
    renders.mkdir()
    target = renders / "real.png"
    target.write_bytes(b"previous render")
    target.chmod(0o640)
    link = tmp_path / "latest.png"
    link.symlink_to(target)

    result = run_script("--output", link, "--width", 30, "--height", 20)

    assert result.returncode == 0, result.stderr
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert read_script_png(target).shape == (20, 30, 4)
    assert (target.stat().st_mode & 0o777) == 0o640  # the file keeps its permissions
    assert sorted(os.listdir(renders)) == ["real.png"]


@pytest.mark.slow
@pytest.mark.parametrize("frame", [2_000_000, -2_000_000])
def test_a_frame_outside_blenders_range_fails_with_one_line(tmp_path, frame):
    result = run_script("--output", tmp_path / "o.png", "--frame", frame)

    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("render.py: error:") and f"--frame {frame}" in line
    assert "1048574" in line
    assert os.listdir(tmp_path) == []


def f12_png(scene, path) -> np.ndarray:
    """The frame F12 (and ``blender -b FILE -f N``) saves as an 8-bit RGBA PNG at ``path``."""
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(path)
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.render.image_settings.color_depth = '8'
    bpy.ops.render.render(write_still=True)
    return read_png(str(path))


def two_layer_scene(first_layer_shows_small=False):
    """simple_scene() whose small sphere is in a collection of its own, which the first view
    layer ('ViewLayer') excludes unless asked not to; a second layer, 'All', shows both."""
    scene = simple_scene()
    collection = bpy.data.collections.new("small things")
    scene.collection.children.link(collection)
    small = bpy.data.objects["small"]
    scene.collection.objects.unlink(small)
    collection.objects.link(small)
    scene.view_layers.new("All")
    first = scene.view_layers["ViewLayer"]
    first.layer_collection.children["small things"].exclude = not first_layer_shows_small
    return scene


def test_a_blend_with_a_compositor_gives_f12s_pixels(tmp_path):
    """The compositor runs, as with F12 and ``blender -b FILE -f N``: the file holds the
    inverted 'All' layer, not a layer as rendered."""
    scene = two_layer_scene()
    invert_compositor(scene, "All")
    blend = save_blend(tmp_path / "composited.blend")

    result = run_script(blend, "--output", tmp_path / "script.png")

    assert result.returncode == 0, result.stderr
    script = read_script_png(tmp_path / "script.png")
    np.testing.assert_array_equal(script, f12_png(scene, tmp_path / "f12.png"))
    scene.render.use_compositing = False
    assert not np.array_equal(script, f12_png(scene, tmp_path / "plain.png"))


def test_ctrl_c_during_a_composited_render_keeps_the_previous_file(tmp_path):
    """A cancel while Blender renders and composites: exit 130, one line, the previous file
    as it was and nothing else written."""
    import signal
    import time

    from process_support import sigint_disposition

    scene = simple_scene()
    invert_compositor(scene)
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    blend = save_blend(tmp_path / "slow.blend")
    output = tmp_path / "out.png"
    output.write_bytes(b"previous render")
    process = subprocess.Popen([sys.executable, RENDER_SCRIPT, str(blend), "--output",
                                str(output), "--samples", "64"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=REPOSITORY, preexec_fn=sigint_disposition())
    time.sleep(5.0)   # bpy's import and the file's, then rendering (about a minute in all)
    assert process.poll() is None, "the render ended before the signal: make it bigger"
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)

    assert process.returncode == 130, err
    (line,) = err.strip().splitlines()
    assert "cancelled by SIGINT" in line and "nothing written" in line
    assert output.read_bytes() == b"previous render"
    assert sorted(os.listdir(tmp_path)) == ["out.png", "slow.blend"]


def test_the_file_of_a_blend_with_several_view_layers_is_f12s(tmp_path):
    """Without a compositor, Blender's file of a frame shows the first view layer (here the
    one without the small sphere), whatever layers come after it."""
    scene = two_layer_scene()
    blend = save_blend(tmp_path / "layers.blend")

    result = run_script(blend, "--output", tmp_path / "script.png")

    assert result.returncode == 0, result.stderr
    np.testing.assert_array_equal(read_script_png(tmp_path / "script.png"),
                                  f12_png(scene, tmp_path / "f12.png"))


def test_only_the_view_layers_the_file_shows_are_rendered(tmp_path):
    from glint.addon.cli.arguments import parse_args
    from glint.addon.cli.interruption import Interruption
    from glint.addon.cli.output import OutputPlan
    from glint.addon.cli.run import render_scene

    def plan(*arguments):
        return OutputPlan.choose(bpy.context.scene, parse_args(list(map(str, arguments))))

    scene = two_layer_scene()
    for name in ("Third", "Fourth", "Fifth"):
        scene.view_layers.new(name)
    png, exr = tmp_path / "o.png", tmp_path / "o.exr"
    assert plan("--output", png).view_layers == ("ViewLayer",)
    assert plan("--output", exr).view_layers == ("ViewLayer",)
    assert plan("--output", exr, "--format", "multilayer-exr").view_layers is None  # all 5
    scene.view_layers["ViewLayer"].use = False          # not rendered by F12 either
    assert plan("--output", png).view_layers == ("All",)
    scene.view_layers["ViewLayer"].use = True
    invert_compositor(scene, "Fourth")
    scene.view_layers["Fourth"].use = False   # it reads no layer that renders: all render
    assert plan("--output", png).view_layers is None
    scene.view_layers["Fourth"].use = True
    composited = plan("--output", png)
    assert composited.view_layers == ("Fourth",) and composited.from_render_result

    scene.render.engine = 'GLINT'
    composited.select_view_layers(scene)
    frames = render_scene(scene, Interruption(), fill_render_result=True)

    assert len(frames) == 1     # the engine rendered one view layer of 5
    assert [layer.name for layer in scene.view_layers if layer.use] == ["Fourth"]


def test_a_blend_with_sequencer_strips_gives_f12s_pixels(tmp_path):
    scene = simple_scene()
    strip = new_effect_strip(scene, "red", 'COLOR', channel=1, frame_start=1, length=10)
    strip.color = (1.0, 0.2, 0.1)
    blend = save_blend(tmp_path / "edit.blend")

    result = run_script(blend, "--output", tmp_path / "script.png")

    assert result.returncode == 0, result.stderr
    script = read_script_png(tmp_path / "script.png")
    np.testing.assert_array_equal(script, f12_png(scene, tmp_path / "f12.png"))
    assert (script[..., :3] == (255, 51, 26)).all()     # the strip's colour, not the spheres


def test_without_output_the_scene_output_path_format_and_frame_are_used(tmp_path):
    """As ``blender -b FILE -f N``: the .blend's output path (relative to the .blend, its
    folder made), file format, frame numbering, and its Overwrite and Placeholders."""
    scene = simple_scene()
    animate_small_sphere(10)
    scene.frame_set(3)
    scene.render.filepath = "//shots/frame_###"
    scene.render.image_settings.file_format = 'JPEG'
    scene.render.use_overwrite, scene.render.use_placeholder = False, True
    blend = save_blend(tmp_path / "shot.blend")

    result = run_script(blend)

    assert result.returncode == 0, result.stderr
    written = tmp_path / "shots" / "frame_003.jpg"
    assert f"wrote {written} (frame 3," in result.stdout
    # What 'blender -b FILE -f 3' does: an animation of frame 3.
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "f12_###")
    scene.frame_start = scene.frame_end = 3
    bpy.ops.render.render(animation=True)
    np.testing.assert_array_equal(read_png(str(written)),
                                  read_png(str(tmp_path / "f12_003.jpg")))
    # Another frame and the scene's frames: Overwrite off keeps what exists.
    (tmp_path / "shots" / "frame_005.jpg").write_bytes(b"previous render")
    result = run_script(blend, "--frames", "4-5")
    assert result.returncode == 0, result.stderr
    assert "skipped frame 5" in result.stdout and "wrote 1 of 2 frames, skipped 1" in result.stdout
    assert (tmp_path / "shots" / "frame_005.jpg").read_bytes() == b"previous render"
    assert sorted(os.listdir(tmp_path / "shots")) == ["frame_003.jpg", "frame_004.jpg",
                                                      "frame_005.jpg"]


def test_without_output_a_video_format_is_refused_with_one_line(tmp_path):
    scene = simple_scene()
    scene.render.filepath = str(tmp_path / "movie_")
    set_file_format(scene.render.image_settings, 'FFMPEG')
    blend = save_blend(tmp_path / "movie.blend")

    result = run_script(blend)

    assert result.returncode == 1
    (line,) = result.stderr.strip().splitlines()
    assert "writes a video (FFMPEG)" in line and "--output" in line
    assert os.listdir(tmp_path) == ["movie.blend"]
