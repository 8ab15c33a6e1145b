"""Render passes (Depth, Position, Normal, Object Index, Material Index) through
update_render_passes, written by F12 into a multilayer EXR for every view layer, checked
against the scene's geometry and against Cycles' own passes of the same scene."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from addon_support import add_camera, add_point_light, add_sphere, empty_file
from glint.addon.compat import new_material, set_file_format  # noqa: E402
from exr import read_exr
from glint.addon.engine.passes import pass_warning
from glint.core.passes import MISSED_DEPTH

PASSES = ("use_pass_z", "use_pass_position", "use_pass_normal", "use_pass_object_index",
          "use_pass_material_index")
BIG, SMALL = ((0.0, 0.0, 0.0), 1.0), ((1.2, -0.8, 0.6), 0.3)
EYE = np.array([0.0, -6.0, 0.0])   # add_camera's default: looking along +Y


def passes_scene(layers=("ViewLayer",)):
    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = 96, 72
    for name, (centre, radius), index in (("big", BIG, 3), ("small", SMALL, 7)):
        material = new_material(f"{name} material")
        material.pass_index = index + 10
        material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
            0.1 * index, 0.5, 0.2, 1.0)
        add_sphere(name, centre, radius, material=material, segments=128, rings=64)
        bpy.data.objects[name].pass_index = index
    add_point_light()
    add_camera()
    for name in layers[1:]:
        scene.view_layers.new(name)
    for layer in scene.view_layers:
        for flag in PASSES:
            setattr(layer, flag, True)
    settings = scene.render.image_settings
    set_file_format(settings, 'OPEN_EXR_MULTILAYER')
    settings.exr_codec = 'NONE'
    settings.color_depth = '32'
    return scene


def render_exr(scene, tmp_path, engine, name):
    scene.render.engine = engine
    scene.render.filepath = str(tmp_path / name)
    bpy.ops.render.render(write_still=True)
    return read_exr(tmp_path / name)


def layer_passes(channels, layer):
    def stack(name, ids):
        return np.stack([channels[f"{layer}.{name}.{c}"] for c in ids], axis=-1)

    return dict(depth=channels[f"{layer}.Depth.Z"], position=stack("Position", "XYZ"),
                normal=stack("Normal", "XYZ"), object=channels[f"{layer}.Object Index.X"],
                material=channels[f"{layer}.Material Index.X"], alpha=channels[f"{layer}.Combined.A"])


@pytest.mark.slow
def test_f12_writes_the_passes_of_every_view_layer_with_the_geometrys_values(tmp_path):
    scene = passes_scene(layers=("ViewLayer", "Second"))
    scene.render.film_transparent = True

    channels = render_exr(scene, tmp_path, 'GLINT', "glint.exr")

    for layer in ("ViewLayer", "Second"):
        p = layer_passes(channels, layer)
        for name, (centre, radius), index in (("big", BIG, 3), ("small", SMALL, 7)):
            on = p["object"] == index
            assert on.sum() > 20, name
            offset = p["position"][on] - centre
            # Hit points lie on the analytic sphere; normals are its radial directions and
            # face the camera; depth is the distance along the view axis (+Y).
            np.testing.assert_allclose(np.linalg.norm(offset, axis=1), radius, rtol=1e-5)
            np.testing.assert_allclose(p["normal"][on], offset / radius, atol=1e-5)
            assert ((p["position"][on] - EYE) @ [0, 1, 0] > 0).all()
            np.testing.assert_allclose(p["depth"][on], p["position"][on][:, 1] - EYE[1],
                                       rtol=1e-5)
            assert (p["material"][on] == index + 10).all()
        missed = p["object"] == 0
        assert missed.any()
        assert (p["depth"][missed] == np.float32(MISSED_DEPTH)).all()
        assert (p["normal"][missed] == 0).all()
        # Combined's alpha is the coverage: 1 inside each sphere, 0 where nothing was hit.
        assert (p["alpha"][missed] < 1).all() and (p["alpha"][p["object"] > 0] > 0).all()


@pytest.mark.slow
@pytest.mark.cycles
def test_the_passes_agree_with_cycles(tmp_path):
    scene = passes_scene()
    # Both engines' passes hold what each pixel's first sample hit: a narrow box filter
    # puts it at the pixel's centre in both.
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 0.01
    glint = layer_passes(render_exr(scene, tmp_path, 'GLINT', "glint.exr"), "ViewLayer")
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    cycles = layer_passes(render_exr(scene, tmp_path, 'CYCLES', "cycles.exr"), "ViewLayer")

    # Compare where both see the same object and so do the 4 neighbours (silhouettes move by
    # up to a pixel between a tessellated and an analytic sphere).
    same = (glint["object"] == cycles["object"])
    interior = same.copy()
    interior[1:-1, 1:-1] &= same[:-2, 1:-1] & same[2:, 1:-1] & same[1:-1, :-2] & same[1:-1, 2:]
    interior[[0, -1], :] = interior[:, [0, -1]] = False
    assert (glint["object"] != cycles["object"]).mean() < 0.02
    hit = interior & (glint["object"] > 0)
    assert hit.sum() > 500
    # A 128 x 64 UV sphere sags by r (1 - cos(pi / 64)) = 1.2e-3 r between vertices, and a
    # jittered sample moves the hit by up to half a pixel (2 r / 30 px across here) times the
    # surface's slope: 0.02 r allows both except at grazing angles, which the normal test
    # below excludes too.
    facing = glint["normal"][..., 1] < -0.5
    for name, tolerance in (("depth", 0.02), ("position", 0.02), ("normal", 0.03)):
        difference = np.abs(glint[name] - cycles[name])
        if difference.ndim == 3:
            difference = difference.max(axis=-1)
        assert difference[hit & facing].max() < tolerance, name
    np.testing.assert_array_equal(glint["object"][interior], cycles["object"][interior])
    np.testing.assert_array_equal(glint["material"][interior], cycles["material"][interior])
    assert (cycles["depth"][interior & (glint["object"] == 0)] >= 1e9).all()


def test_material_ids_follow_the_cores_material_table():
    from glint.addon.engine.job import prepare_job
    from glint.core.arrays import scene_arrays
    from glint.core.passes import material_entries

    passes_scene()
    scene = prepare_job(bpy.context.evaluated_depsgraph_get()).scene
    entries = material_entries(scene)
    table = scene_arrays(scene).materials
    np.testing.assert_array_equal([m.diffuse for m in entries], table.diffuse)
    assert len(entries) == len(table.diffuse) == 2


def test_enabled_passes_glint_cannot_produce_are_named_in_one_warning():
    scene = passes_scene()
    layer = scene.view_layers[0]
    assert pass_warning(layer) is None
    layer.use_pass_mist = layer.use_pass_ambient_occlusion = True
    layer.aovs.add().name = "dirt"

    warning = pass_warning(layer)

    assert warning.startswith("view layer 'ViewLayer'")
    for label in ("Mist", "Ambient Occlusion", "AOV 'dirt'"):
        assert label in warning
    assert "Depth" not in warning and "Normal" not in warning


def test_enabling_passes_leaves_the_combined_image_as_it_is(tmp_path, monkeypatch):
    """The passes go to Blender with each tile, beside Combined: Combined must get the same
    hand-over (the default semantics' radiance unchanged, not the article's inverse sRGB).
    A path-traced frame hands every tile over once per progressive pass (and the denoised
    frame once more): whole frames, never a part of one twice."""
    import glint.addon.engine.final as final

    scene = passes_scene()
    converted = []
    convert = final.blender_pixels
    monkeypatch.setattr(final, "blender_pixels",
                        lambda rows, semantics: converted.append(rows.shape[:2])
                        or convert(rows, semantics))
    with_passes = render_exr(scene, tmp_path, 'GLINT', "with.exr")
    handed = sum(h * w for h, w in converted)
    assert handed >= 96 * 72 and handed % (96 * 72) == 0
    for flag in PASSES:
        setattr(scene.view_layers[0], flag, False)
    without = render_exr(scene, tmp_path, 'GLINT', "without.exr")

    for channel in "RGBA":
        key = f"ViewLayer.Combined.{channel}"
        np.testing.assert_array_equal(with_passes[key], without[key])
    assert without["ViewLayer.Combined.R"].max() > 0.05   # a lit picture, not a black one


@pytest.mark.slow
@pytest.mark.cycles
def test_the_emission_pass_holds_what_the_camera_path_meets_as_in_cycles(tmp_path,
                                                                        monkeypatch):
    """Cycles' Emission pass: emission seen by the camera, and through a Transparent BSDF
    (weighted by what passes); not what a mirror shows (glossy light) nor the world, and
    nothing of a holdout object.  Values are exact in both renderers on pixels well inside one
    surface (emission has no sampling noise there; Cycles' filter is near zero): 1e-4."""
    import cycles_support
    from cycles_support import add_ball, cycles_scene, node_material, set_world, sphere_mask

    scene = cycles_scene(bounces=2, samples=16)
    # Twice cycles_support's size, so that each ball keeps pixels 2 in from its outline.
    scene.render.resolution_x, scene.render.resolution_y = 96, 72
    monkeypatch.setattr(cycles_support, "WIDTH", 96)
    monkeypatch.setattr(cycles_support, "HEIGHT", 72)
    scene.cycles.transparent_max_bounces = 8
    scene.glint.max_depth = 4
    set_world((0.3, 0.5, 0.9), 0.5)
    glow = node_material("glow", "ShaderNodeEmission", Color=(1.0, 0.5, 0.2), Strength=3.0)
    lamp = add_ball("lamp", (-1.2, 0.0, 0.0), 0.8, glow)
    veil = add_ball("veil", (-0.75, -3.0, 0.0), 0.3, node_material(   # before the lamp
        "veil", "ShaderNodeBsdfTransparent", Color=(0.5, 0.5, 0.5)))
    mirror = add_ball("mirror", (1.2, 0.0, 0.0), 0.8, node_material(
        "mirror", "ShaderNodeBsdfGlossy", Color=(0.9, 0.9, 0.9), Roughness=0.0))
    held = add_ball("held", (0.0, 0.0, 1.4), 0.5, glow)
    held.is_holdout = True
    layer = scene.view_layers[0]
    layer.use_pass_emit = True
    settings = scene.render.image_settings
    settings.media_type, settings.exr_codec, settings.color_depth = \
        'MULTI_LAYER_IMAGE', 'NONE', '32'

    def emission(engine):
        channels = render_exr(scene, tmp_path, engine, f"{engine}.exr")
        return np.stack([channels[f"ViewLayer.Emission.{c}"] for c in "RGB"], axis=-1)

    glint, cycles = emission('GLINT'), emission('CYCLES')
    inside = sphere_mask(lamp) & ~sphere_mask(veil, erode=-2)
    np.testing.assert_allclose(cycles[inside], np.broadcast_to((3.0, 1.5, 0.6),
                                                               (inside.sum(), 3)), rtol=1e-4)
    through = sphere_mask(veil)          # 0.5 x 0.5 of the lamp behind it
    np.testing.assert_allclose(cycles[through], np.broadcast_to((0.75, 0.375, 0.15),
                                                                (through.sum(), 3)), rtol=1e-4)
    for mask in (inside, through, sphere_mask(mirror), sphere_mask(held)):
        assert mask.sum() >= 20
        np.testing.assert_allclose(glint[mask], cycles[mask], rtol=1e-4, atol=1e-6)
    assert cycles[sphere_mask(mirror)].max() == 0 and cycles[0:3, 0:3].max() == 0
    np.testing.assert_array_equal(glint[0:3, 0:3], 0.0)


@pytest.mark.slow
def test_a_render_region_holds_that_part_of_the_full_frames_passes(tmp_path):
    """The passes go to Blender tile by tile, each cut to the render region as Combined is:
    a cropped region's multilayer EXR holds the full frame's pixels there, in every pass."""
    scene = passes_scene()
    scene.render.resolution_x, scene.render.resolution_y = 300, 160   # several tiles
    full = render_exr(scene, tmp_path, 'GLINT', "full.exr")
    render = scene.render
    render.use_border, render.use_crop_to_border = True, True
    render.border_min_x, render.border_max_x = 0.3, 0.8
    render.border_min_y, render.border_max_y = 0.25, 0.9
    region = render_exr(scene, tmp_path, 'GLINT', "region.exr")

    # Blender's pixels: x in [int(0.3 * 300), int(0.8 * 300)), rows from the bottom likewise.
    x0, x1, y0, y1 = 90, 240, 40, 144
    top, bottom = 160 - y1, 160 - y0
    for name in ("Combined.R", "Combined.A", "Depth.Z", "Normal.X", "Object Index.X"):
        key = f"ViewLayer.{name}"
        assert region[key].shape == (y1 - y0, x1 - x0), name
        np.testing.assert_array_equal(region[key], full[key][top:bottom, x0:x1], err_msg=name)
    assert (region["ViewLayer.Object Index.X"] > 0).sum() > 1000


@pytest.mark.cycles
def test_denoising_data_gives_the_albedo_and_normal_passes_cycles_gives(tmp_path):
    """View Layer > Passes > Data > Denoising Data (Cycles' own setting) makes F12 write
    Denoising Albedo and Denoising Normal, as Cycles does, so the compositor's Denoise node
    can read them: the albedo is the surfaces' (Base Color, 0.1 index, 0.5, 0.2 here), the
    normal the shading normal; both agree with Cycles' inside the spheres."""
    scene = passes_scene()
    scene.view_layers[0].cycles.denoising_store_passes = True
    scene.glint.use_denoising = False
    glint = render_exr(scene, tmp_path, 'GLINT', "glint.exr")
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    cycles = render_exr(scene, tmp_path, 'CYCLES', "cycles.exr")

    def stack(channels, name, ids):
        return np.stack([channels[f"ViewLayer.{name}.{c}"] for c in ids], axis=-1)

    objects = glint["ViewLayer.Object Index.X"]
    inside = objects == 3
    inside[1:-1, 1:-1] &= inside[:-2, 1:-1] & inside[2:, 1:-1] & inside[1:-1, :-2] & inside[1:-1, 2:]
    for name, ids, tolerance in (("Denoising Albedo", "RGB", 0.03),
                                 ("Denoising Normal", "XYZ", 0.05)):
        ours, theirs = stack(glint, name, ids), stack(cycles, name, ids)
        assert ours[inside].std() > 0 or name == "Denoising Albedo"
        np.testing.assert_allclose(np.median(ours[inside], axis=0),
                                   np.median(theirs[inside], axis=0), atol=tolerance,
                                   err_msg=name)


def test_a_textured_material_keeps_its_pass_index(tmp_path):
    """A material whose Base Color comes from a texture is a shader program (arrays), not a
    set of constants: its Material Index still reaches the pass."""
    scene = passes_scene()
    material = bpy.data.materials["small material"]
    tree = material.node_tree
    checker = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(checker.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    p = layer_passes(render_exr(scene, tmp_path, 'GLINT', "glint.exr"), "ViewLayer")
    for index in (3, 7):
        on = p["object"] == index
        assert on.sum() > 20 and (p["material"][on] == index + 10).all(), index
