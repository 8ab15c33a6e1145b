"""Bad values in a .blend: one line naming the object, the material (or world, or light) and
the field, from every entry point (the engine, the Render button, render.py), and nothing
written; the core's own validation limits; long image names."""

from __future__ import annotations

import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

from addon_support import (RENDER_SCRIPT, REPOSITORY, core, read_image, render_script,
                           simple_scene)

NAN, INF = float("nan"), float("inf")


def principled(input_name, value):
    def setup(scene):
        material = bpy.data.materials.new("Paint")
        node = material.node_tree.nodes["Principled BSDF"]
        if input_name == "Base Color":
            value4 = (value, 0.5, 0.5, 1.0)
            node.inputs[input_name].default_value = value4
        else:
            node.inputs[input_name].default_value = value
        bpy.data.objects["big"].data.materials.append(material)
    return setup


def custom(field, value):
    def setup(scene):
        material = bpy.data.materials.new("Custom")
        material.glint.use_custom = True
        if field in ("ambient", "diffuse", "specular"):
            setattr(material.glint, field, (value, 0.0, 0.0))
        else:
            setattr(material.glint, field, value)
        bpy.data.objects["big"].data.materials.append(material)
    return setup


def world(input_name, value):
    def setup(scene):
        sky = bpy.data.worlds.new("Sky")
        node = sky.node_tree.nodes["Background"]
        node.inputs[input_name].default_value = ((value, 0.1, 0.1, 1.0) if input_name == "Color"
                                                 else value)
        scene.world = sky
    return setup


def light(field, value):
    def setup(scene):
        data = bpy.data.objects["light"].data
        if field == "color":
            data.color = (value, 1.0, 1.0)
        else:
            setattr(data, field, value)
    return setup


#: case: (setup, words the one line must contain)
CASES = {
    "NaN base colour": (principled("Base Color", NAN), ["'big'", "'Paint'", "base colour"]),
    "NaN roughness": (principled("Roughness", NAN), ["'big'", "'Paint'", "roughness"]),
    "infinite specular level": (principled("Specular IOR Level", INF),
                                ["'big'", "'Paint'", "specular"]),
    "huge base colour": (principled("Base Color", 1e38), ["'big'", "'Paint'", "diffuse"]),
    "NaN custom diffuse": (custom("diffuse", NAN), ["'big'", "'Custom'", "diffuse"]),
    "NaN custom shininess": (custom("shininess", NAN), ["'big'", "'Custom'", "shininess"]),
    "NaN world colour": (world("Color", NAN), ["world 'Sky'", "background"]),
    "huge world strength": (world("Strength", 1e38), ["world 'Sky'", "background", "1e+12"]),
    "NaN light power": (light("energy", NAN), ["light 'light'", "energy"]),
    "huge light power": (light("energy", 3e38), ["light 'light'", "energy"]),
    "infinite light colour": (light("color", INF), ["light 'light'", "color"]),
    "huge light radius": (light("shadow_soft_size", 3e38), ["sphere", "float64"]),
}


def make(case):
    scene = simple_scene()
    CASES[case][0](scene)
    return scene


def check_line(text, case):
    (line,) = text.strip().splitlines()
    for word in CASES[case][1]:
        assert word in line, f"{word!r} not in {line!r}"
    return line


@pytest.mark.parametrize("case", CASES)
def test_the_engine_names_the_culprit_in_one_line_and_writes_nothing(tmp_path, case):
    scene = make(case)
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "f.png")
    with pytest.raises(RuntimeError) as raised:
        bpy.ops.render.render(write_still=True)
    check_line(str(raised.value), case)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("case", CASES)
def test_the_render_button_names_the_culprit_in_one_line_and_keeps_the_image(case):
    scene = simple_scene()
    assert bpy.ops.glint.render() == {'FINISHED'}
    before = read_image(bpy.data.images["Glint Render"])
    CASES[case][0](scene)

    with pytest.raises(RuntimeError) as raised:
        bpy.ops.glint.render()

    check_line(str(raised.value), case)
    np.testing.assert_array_equal(read_image(bpy.data.images["Glint Render"]), before)


@pytest.mark.parametrize("case", ["NaN base colour", "NaN world colour", "huge light power",
                                  "huge light radius"])
def test_render_script_names_the_culprit_in_one_line(tmp_path, case):
    make(case)
    blend = tmp_path / "bad.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    result = subprocess.run([sys.executable, RENDER_SCRIPT, str(blend), "--output",
                             str(tmp_path / "o.png")], capture_output=True, text=True,
                            timeout=300, cwd=REPOSITORY)
    assert result.returncode == 1
    line = check_line(result.stderr, case)
    assert line.startswith("render.py: error:")
    assert sorted(os.listdir(tmp_path)) == ["bad.blend"]


@pytest.mark.parametrize("name", ["x" * 64, "é" * 32])  # 64 bytes each
def test_an_image_name_longer_than_blenders_limit_is_refused_and_creates_nothing(name):
    scene = simple_scene()
    scene.glint.image_name = name
    for _ in range(2):
        with pytest.raises(RuntimeError) as raised:
            bpy.ops.glint.render()
        (line,) = str(raised.value).strip().splitlines()
        assert "64 bytes" in line and "at most 63" in line
    assert len(bpy.data.images) == 0


def test_an_image_name_at_blenders_limit_is_reused_render_after_render():
    scene = simple_scene()
    scene.glint.image_name = "é" * 31 + "x"  # 63 bytes
    for _ in range(2):
        assert bpy.ops.glint.render() == {'FINISHED'}
    assert [image.name for image in bpy.data.images] == [scene.glint.image_name]


LIMITS = [
    (lambda: core.Material(diffuse=(1e13, 0, 0)), "material.diffuse[0] must be at most 1e+12"),
    (lambda: core.Material(shininess=1e8), "material.shininess must be at most 1e+07"),
    (lambda: core.Sphere((1e301, 0, 0), 1.0, name="far"), "sphere 'far'.center[0]"),
    (lambda: core.Sphere((0, 0, 0), 1e301, name="vast"), "sphere 'vast'.radius"),
    (lambda: core.PointLight((0, 0, 0), diffuse=(0, 2e12, 0), name="sun"),
     "light 'sun'.diffuse[1]"),
    (lambda: core.PointLight.from_power((0, 0, 0), (1, 1, 1), 2e15, name="sun"),
     "light 'sun'.energy must be at most 1e+15"),
    (lambda: core.RenderSettings(samples=100_000_000), "settings.samples must be at most 16384"),
    (lambda: core.RenderSettings(light_samples=5000), "settings.light_samples must be at most"),
    (lambda: core.RenderSettings(max_depth=10_000), "settings.max_depth must be at most 256"),
    (lambda: core.RenderSettings(tile_size=100_000), "settings.tile_size must be at most"),
]


@pytest.mark.parametrize("make_value, message", LIMITS, ids=[m for _, m in LIMITS])
def test_the_core_rejects_values_past_its_limits_naming_the_field(make_value, message):
    with pytest.raises(core.SceneError, match=message.replace("[", r"\[").replace("+", r"\+")):
        make_value()


def test_values_at_the_limits_render_without_nan():
    """The largest accepted colours, powers and exponents, together: a finite picture."""
    hot = core.Material(ambient=(1e12,) * 3, diffuse=(1e12,) * 3, specular=(1e12,) * 3,
                        shininess=1e7, reflection=1.0)
    scene = core.Scene(
        camera=core.ScreenCamera(32, 24),
        spheres=(core.Sphere((0, 0, -2), 0.5, hot, "hot"),
                 core.Sphere((0.8, 0, -2.5), 0.5, hot, "hot2")),
        lights=tuple(core.PointLight((x, 3, 1), (1e12,) * 3, (1e12,) * 3, (1e12,) * 3,
                                     radius=0.2) for x in (-2, 2)),
        background=(1e12,) * 3, ambient=(1e12,) * 3)
    for semantics in ("default", "article"):
        for precision in ("float32", "float64"):
            image = core.render(scene, core.RenderSettings(
                semantics=semantics, precision=precision, light_samples=4, max_depth=8)).image
            assert np.isfinite(image).all()


def test_the_settings_hard_maximums_are_the_cores_limits():
    from glint.core import scene as limits

    from glint.addon.properties import GlintMaterialSettings, GlintRenderSettings

    render = GlintRenderSettings.bl_rna.properties
    assert render["samples"].hard_max == limits.MAX_SAMPLES
    assert render["light_samples"].hard_max == limits.MAX_LIGHT_SAMPLES
    assert render["world_samples"].hard_max == limits.MAX_LIGHT_SAMPLES
    assert render["max_depth"].hard_max == limits.MAX_DEPTH
    material = GlintMaterialSettings.bl_rna.properties
    assert material["shininess"].hard_max == limits.MAX_SHININESS
    assert all(material[name].hard_max == pytest.approx(limits.MAX_COLOUR, rel=1e-6)
               for name in ("ambient", "diffuse", "specular"))  # stored as float32
    settings = simple_scene().glint
    settings.samples = 100_000_000  # Blender clamps to the hard maximum
    assert settings.samples == limits.MAX_SAMPLES
    # render.py checks its options before importing the package, with the same numbers.
    assert (render_script.MAX_SAMPLES, render_script.MAX_DEPTH) == (limits.MAX_SAMPLES,
                                                                    limits.MAX_DEPTH)
    resolution = bpy.types.RenderSettings.bl_rna.properties["resolution_x"]
    assert (render_script.MIN_RESOLUTION, render_script.MAX_RESOLUTION) == (
        resolution.hard_min, resolution.hard_max)


CORE_COMMAND_ERRORS = {
    "width not a number": (["--width", "abc"], "--width"),
    "negative width": (["--width", "-5"], "camera.width"),
    "zero samples": (["--samples", "0", "--anti-aliasing", "fixed"], "settings.samples"),
    "samples past the limit": (["--samples", "100000000"], "settings.samples must be at most"),
    "zero threads": (["--threads", "0"], "settings.threads"),
    "depth past the limit": (["--max-depth", "1000"], "settings.max_depth must be at most"),
    "unknown semantics": (["--semantics", "exact"], "--semantics"),
}


@pytest.mark.parametrize("case", CORE_COMMAND_ERRORS)
def test_python_m_core_gives_one_line_for_bad_options(tmp_path, case):
    arguments, mentioned = CORE_COMMAND_ERRORS[case]
    result = subprocess.run([sys.executable, "-m", "core", *arguments, "--output",
                             str(tmp_path / "o.png")], capture_output=True, text=True,
                            cwd=REPOSITORY, timeout=120)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert mentioned in line
    assert os.listdir(tmp_path) == []


def test_render_script_refuses_samples_past_the_limit_in_one_line(tmp_path):
    result = subprocess.run([sys.executable, RENDER_SCRIPT, "--output", str(tmp_path / "o.png"),
                             "--samples", "100000000"], capture_output=True, text=True,
                            cwd=REPOSITORY, timeout=120)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert "--samples" in line and "at most 16384" in line


def test_python_m_core_refuses_a_write_protected_output_and_writes_through_links(tmp_path):
    kept = tmp_path / "kept.png"
    kept.write_bytes(b"previous render")
    kept.chmod(0o444)
    command = [sys.executable, "-m", "core", "--width", "20", "--height", "10", "--output"]

    refused = subprocess.run(command + [str(kept)], capture_output=True, text=True,
                             cwd=REPOSITORY, timeout=120)
    assert refused.returncode == 2
    (line,) = refused.stderr.strip().splitlines()
    assert "write-protected" in line and kept.read_bytes() == b"previous render"

    target = tmp_path / "real.png"
    target.write_bytes(b"previous render")
    link = tmp_path / "link.png"
    link.symlink_to(target)
    written = subprocess.run(command + [str(link)], capture_output=True, text=True,
                             cwd=REPOSITORY, timeout=120)
    assert written.returncode == 0, written.stderr
    assert link.is_symlink() and target.read_bytes().startswith(b"\x89PNG")
    assert sorted(os.listdir(tmp_path)) == ["kept.png", "link.png", "real.png"]
