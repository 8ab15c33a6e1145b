"""Holdouts and Film > Transparent against Cycles (``cycles_support``): the same small scenes
rendered by both, compared on each ball's pixels (2 pixels in from its silhouette).

What Cycles does (bpy 5.0.1, checked headless on these scenes) and Glint now does
(``core.trace``):
* a Holdout shader seen by the camera is black with alpha 0, with Film > Transparent on or
  off; a Mix Shader of Holdout at factor f gives alpha 1 - f and (1 - f) x the other shader;
* seen in a mirror or through refraction it is black and opaque (only camera rays, and rays
  straight through Transparent BSDFs, cut holes);
* a holdout object (Object > Visibility > Holdout, or a holdout collection of the view
  layer) is black with alpha 0 to the camera, yet casts its shadow and shows its own material
  in mirrors;
* through a Transparent BSDF of colour c (both sides of a ball: c^2 passes) a holdout or,
  with Film > Transparent, the world leaves alpha 1 - mean(c^2), and the world seen so adds
  no colour.

Tolerances: alpha has no sampling noise in either renderer on pixels well inside one
surface (Cycles' pixel filter is near zero, so its samples fall within the pixel's centre
area, on the same surface as Glint's centre ray): 1e-3, the EXR's float32 and Cycles'
accumulation.  Colours: ``test_look_cycles``' 2 % on the mean and 5 % per pixel at the 90th
percentile (a faceted UV sphere against an analytic one, and 32-sample noise).  A wrong
model fails by far more: a holdout rendered opaque is off by 1 in alpha, a missing shadow
by the whole shadowed area, a holdout object black in the mirror by all of its reflection.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from cycles_support import (add_ball, add_light, add_plane, cycles_scene, diffuse,
                            node_material, pixel_errors, render_both, set_world, sphere_mask,
                            surface_ratios)
from glint.addon.compat import new_material  # noqa: E402

ALPHA_TOLERANCE = 1e-3
LIGHT_TOLERANCE = 0.02
PIXEL_TOLERANCE = 0.05


def holdout_mix(name: str, factor: float, colour):
    """Mix Shader: (1 - factor) Diffuse(colour) + factor Holdout."""
    material = new_material(name)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = factor
    shader = tree.nodes.new("ShaderNodeBsdfDiffuse")
    shader.inputs["Color"].default_value = (*colour, 1.0)
    holdout = tree.nodes.new("ShaderNodeHoldout")
    tree.links.new(shader.outputs[0], mix.inputs[1])
    tree.links.new(holdout.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def assert_alpha(glint, cycles, mask, expected=None):
    assert mask.sum() >= 10, mask.sum()
    np.testing.assert_allclose(glint[mask, 3], cycles[mask, 3], atol=ALPHA_TOLERANCE)
    if expected is not None:
        np.testing.assert_allclose(cycles[mask, 3], expected, atol=ALPHA_TOLERANCE)


def assert_colours(glint, cycles, ball, floor=0.05, beside=None):
    """Colours on ``ball``'s pixels, those within 2 pixels of ``beside`` left out."""
    mask = sphere_mask(ball)
    if beside is not None:
        mask &= ~sphere_mask(beside, erode=-2)
    ratios = surface_ratios(glint, cycles, mask, floor)
    np.testing.assert_allclose(ratios, 1.0, atol=LIGHT_TOLERANCE, err_msg=f"{ball.name}")
    assert np.percentile(pixel_errors(glint, cycles, mask, floor), 90) < PIXEL_TOLERANCE


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("transparent", [False, True], ids=["opaque film", "transparent film"])
def test_holdout_shader_cuts_camera_holes_and_is_black_in_mirrors_and_through_glass(
        transparent):
    scene = cycles_scene(bounces=2)
    set_world((0.3, 0.5, 0.9), 0.02)   # dim: the balls are lit by the light alone
    scene.render.film_transparent = transparent
    hold = node_material("hold", "ShaderNodeHoldout")
    held = add_ball("held", (-1.3, 0.0, 0.9), 0.6, hold)
    behind = add_ball("behind", (-2.2, 3.0, 0.6), 1.6, diffuse("red", (0.8, 0.2, 0.1)))
    mix = add_ball("mix", (0.2, 0.0, 0.9), 0.55, holdout_mix("mix", 0.3, (0.2, 0.8, 0.2)))
    mirror = add_ball("mirror", (1.7, 0.0, 0.6), 0.9, node_material(
        "mirror", "ShaderNodeBsdfGlossy", Color=(0.9, 0.9, 0.9), Roughness=0.0))
    add_ball("in the mirror", (3.8, -1.2, 0.6), 1.0, hold)   # right of the frame
    lens = add_ball("lens", (0.0, -1.0, -1.2), 0.5, node_material(
        "lens", "ShaderNodeBsdfRefraction", Color=(1.0, 1.0, 1.0), IOR=1.0))
    add_ball("behind the lens", (0.0, 1.0, -1.2), 0.9, hold)
    add_light('POINT', (3.0, -5.0, 5.0), energy=2000.0, shadow_soft_size=0)
    glint, cycles = render_both()

    # Seen by the camera: black, alpha 0, film transparent or not.
    assert_alpha(glint, cycles, sphere_mask(held), 0.0)
    assert np.abs(glint[sphere_mask(held), :3]).max() == 0
    # Mixed at 0.3: alpha 0.7 and 0.7 of the diffuse ball's light.
    assert_alpha(glint, cycles, sphere_mask(mix), 0.7)
    assert_colours(glint, cycles, mix)
    # The red ball around the held one (its silhouette's pixels left out: Cycles' faceted
    # outline and Glint's analytic one part there).
    assert_alpha(glint, cycles, sphere_mask(behind) & ~sphere_mask(held, erode=-2), 1.0)
    assert_colours(glint, cycles, behind, beside=held)
    # Through the lens and in the mirror: black and opaque.
    through = sphere_mask(lens)
    assert_alpha(glint, cycles, through, 1.0)
    assert np.abs(glint[through, :3]).max() < 1e-6
    mirrored = sphere_mask(mirror)
    assert_alpha(glint, cycles, mirrored, 1.0)
    dark = mirrored & (cycles[..., :3].max(axis=2) < 1e-4)
    assert dark.sum() >= 5, "the held ball should show black in the mirror"
    assert glint[dark, :3].max() < 1e-4
    # The world: seen where the film is opaque, transparent black where it is not.
    sky = cycles[..., 3] == (0.0 if transparent else 1.0)
    sky &= ~np.any([sphere_mask(ball, erode=-2) for ball in bpy.data.objects
                    if ball.type == 'MESH'], axis=0)
    assert sky.sum() > 100
    np.testing.assert_allclose(glint[sky], cycles[sky], atol=1e-5)


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("transparent", [False, True], ids=["opaque film", "transparent film"])
@pytest.mark.parametrize("how", ["object", "collection"])
def test_holdout_objects_cut_holes_yet_cast_shadows_and_show_in_mirrors(how, transparent):
    scene = cycles_scene(bounces=1)
    scene.cycles.diffuse_bounces = 0   # the mirror's reflection: direct light only
    scene.render.film_transparent = transparent
    held = add_ball("held", (1.0, 1.5, 0.0), 0.6, diffuse("green", (0.2, 0.8, 0.2)))
    floor = add_ball("floor", (1.9, 3.2, -1.6), 1.1, diffuse("grey", (0.8, 0.8, 0.8)))
    # At 45 degrees on the left: camera rays reflect towards +X, onto the held ball's left.
    add_plane("mirror", (-1.5, 1.5, 0.0), 2.0, node_material(
        "mirror", "ShaderNodeBsdfGlossy", Color=(0.9, 0.9, 0.9), Roughness=0.0), math.pi / 4)
    if how == "object":
        held.is_holdout = True
    else:
        collection = bpy.data.collections.new("held out")
        scene.collection.children.link(collection)
        scene.collection.objects.unlink(held)
        collection.objects.link(held)
        bpy.context.view_layer.layer_collection.children["held out"].holdout = True
    add_light('POINT', (-1.0, -2.0, 3.0), energy=1500.0, shadow_soft_size=0)
    glint, cycles = render_both()

    assert_alpha(glint, cycles, sphere_mask(held), 0.0)
    assert np.abs(glint[sphere_mask(held), :3]).max() == 0
    # Its shadow on the floor: Cycles' floor has a shadowed part, and Glint matches it.
    lit = sphere_mask(floor)
    assert (cycles[lit, :3].max(axis=1) < 0.2 * cycles[lit, :3].max()).sum() >= 5
    assert_colours(glint, cycles, floor, floor=0.0)
    # In the mirror, its green material (the only green in the mirror).
    reflection = (cycles[..., 1] > 2 * cycles[..., 0]) & (cycles[..., 1] > 0.02) & \
        ~sphere_mask(held, erode=-2)
    assert reflection.sum() >= 20, "the held ball should show in the mirror"
    errors = np.abs(glint[reflection, :3].sum(axis=1) / cycles[reflection, :3].sum(axis=1) - 1)
    assert np.percentile(errors, 90) < PIXEL_TOLERANCE, np.percentile(errors, 90)
    np.testing.assert_allclose(glint[reflection, 3], 1.0)


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("transparent", [False, True], ids=["opaque film", "transparent film"])
def test_holdouts_and_the_world_through_a_transparent_bsdf(transparent):
    scene = cycles_scene(bounces=2)
    # Cycles' Russian roulette on transparent bounces biases its holdout alpha (0.742
    # instead of 0.633 here): with it off, Cycles' alpha is exactly 1 - mean(c^2).
    scene.cycles.transparent_max_bounces = 8
    scene.cycles.min_transparent_bounces = 8
    scene.glint.max_depth = 4
    set_world((0.3, 0.5, 0.9), 0.5)
    scene.render.film_transparent = transparent
    colour = np.array([0.5, 0.6, 0.7])
    glass = node_material("clear", "ShaderNodeBsdfTransparent", Color=tuple(colour))
    over_holdout = add_ball("over holdout", (-1.2, -1.0, 0.0), 0.5, glass)
    add_ball("held", (-1.2, 2.0, 0.0), 1.5, node_material("hold", "ShaderNodeHoldout"))
    over_world = add_ball("over world", (1.2, -1.0, 0.0), 0.5, glass)
    glint, cycles = render_both()

    passed = colour ** 2
    assert_alpha(glint, cycles, sphere_mask(over_holdout), 1 - passed.mean())
    assert np.abs(glint[sphere_mask(over_holdout), :3]).max() == 0
    world = sphere_mask(over_world)
    assert_alpha(glint, cycles, world, 1 - passed.mean() if transparent else 1.0)
    seen = 0.0 if transparent else passed * np.array([0.3, 0.5, 0.9]) * 0.5
    np.testing.assert_allclose(cycles[world, :3], np.broadcast_to(seen, (world.sum(), 3)),
                               atol=1e-4)
    np.testing.assert_allclose(glint[world, :3], cycles[world, :3], atol=1e-4)


@pytest.mark.slow
def test_f12_saves_the_holdout_hole_with_an_opaque_film(tmp_path):
    """What the engine hands Blender (and Blender saves) keeps the hole: alpha 0 on the held
    ball in the PNG, 1 on the world around it, Film > Transparent off."""
    from addon_support import read_png

    scene = cycles_scene()
    set_world((0.3, 0.5, 0.9), 0.5)
    held = add_ball("held", (0.0, 0.0, 0.0), 1.0, node_material("hold", "ShaderNodeHoldout"))
    scene.render.engine = 'GLINT'
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.render.filepath = str(tmp_path / "held.png")
    bpy.ops.render.render(write_still=True)
    alpha = read_png(str(tmp_path / "held.png"))[..., 3]
    inside = sphere_mask(held)
    assert inside.sum() > 50 and (alpha[inside] == 0).all()
    assert (alpha[~sphere_mask(held, erode=-2)] == 255).all()


@pytest.mark.slow
@pytest.mark.cycles
def test_a_holdout_object_keeps_its_transparency():
    """Cycles holds out all of a holdout object but its transparency: a Principled BSDF of
    Alpha 0.5 passes half at each of its two sides, so a quarter of the ball behind shows
    (alpha 0.25) and three quarters are held out."""
    scene = cycles_scene(bounces=2)
    scene.cycles.transparent_max_bounces = 8
    scene.cycles.min_transparent_bounces = 8    # no Russian roulette bias (see above)
    scene.glint.max_depth = 4
    set_world((0.3, 0.5, 0.9), 0.02)   # dim: the ball behind is lit by the light alone
    half = new_material("half")
    principled = half.node_tree.nodes["Principled BSDF"]
    principled.inputs["Alpha"].default_value = 0.5
    principled.inputs["Base Color"].default_value = (0.2, 0.8, 0.2, 1.0)
    held = add_ball("held", (0.0, -1.0, 0.0), 0.6, half)
    held.is_holdout = True
    add_ball("behind", (0.0, 2.0, 0.0), 1.5, diffuse("red", (0.8, 0.2, 0.1)))
    add_light('POINT', (2.0, -4.0, 3.0), energy=1000.0, shadow_soft_size=0)
    glint, cycles = render_both()

    mask = sphere_mask(held)
    assert_alpha(glint, cycles, mask, 0.25)
    ratios = glint[mask, :3].mean(axis=0) / cycles[mask, :3].mean(axis=0)
    np.testing.assert_allclose(ratios, 1.0, atol=LIGHT_TOLERANCE, err_msg=str(ratios))
