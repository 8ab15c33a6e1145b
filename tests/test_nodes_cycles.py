"""Node materials and textured worlds against Cycles, in whole scenes rendered by both: a
procedural material ball (Noise, ColorRamp, Voronoi, Bump), a UV-textured cube on a
checkered floor, a normal-mapped floor, and a product shot lit by one of Blender's own
studio-light HDRIs (CC0, shipped in the bpy wheel).

Direct light only (bounces 0), as the node tests of each family are kernel by kernel
(``test_shader_*``); here the whole pipeline is checked: export, compiled programs, per-hit
coordinates, the path integrator.  Tolerances: under a sun (a light of 0.5 degrees) both
renderers' pixels are nearly noise-free at these samples, so per pixel the 90th percentile
of |Glint - Cycles| must stay under 2 % of the image's brightest value (what is left: pixel
filters on edges, Glint's analytic sampling against Cycles' 256 samples); under the HDRI,
Glint's 256 samples and Cycles' 1024 leave noise, so means over the ball and the floor are
held to 2 %.
"""

from __future__ import annotations

import math
import os

import bpy
import numpy as np
import pytest

import cycles_support as cs
from glint.addon.compat import new_material  # noqa: E402
from addon_support import core_image, link

pytestmark = pytest.mark.cycles  # every test here renders with Cycles

PIXEL_TOLERANCE = 0.02
MEAN_TOLERANCE = 0.02


@pytest.fixture
def lit_scene():
    scene = cs.cycles_scene(bounces=0, samples=256)
    scene.glint.samples = 64
    cs.add_light('SUN', (0, -5, 5), (math.radians(50), 0, math.radians(30)), energy=3.0)
    return scene


def _per_pixel(glint, cycles):
    error = np.abs(glint[..., :3] - cycles[..., :3]).max(axis=2)
    return np.percentile(error, 90) / max(cycles[..., :3].max(), 1e-6)


def _smooth_ball(material, rotation=(0.0, 0.0, 0.0)):
    """A smooth UV sphere of radius 1.2 at the origin wearing ``material``."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.2,
                                         rotation=rotation)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material)


def _material(name):
    material = new_material(name)
    return material, material.node_tree, material.node_tree.nodes["Principled BSDF"]


def test_a_procedural_material_ball_matches_cycles(lit_scene):
    material, tree, principled = _material("procedural")
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 4.0
    noise.inputs["Detail"].default_value = 6.0
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.interpolation = 'CONSTANT'
    ramp.color_ramp.elements[0].color = (0.8, 0.1, 0.05, 1.0)
    ramp.color_ramp.elements[1].position = 0.5
    ramp.color_ramp.elements[1].color = (0.1, 0.3, 0.9, 1.0)
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], principled.inputs["Base Color"])
    voronoi = tree.nodes.new("ShaderNodeTexVoronoi")
    voronoi.inputs["Scale"].default_value = 6.0
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.6
    tree.links.new(voronoi.outputs["Distance"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], principled.inputs["Normal"])
    _smooth_ball(material)
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE
    # The pattern is there: both colours of the ramp show on the ball.
    ball = cycles[..., 3] > 0.99
    assert (glint[ball, 0] > 2 * glint[ball, 2]).any() and (glint[ball, 2] > 2 * glint[ball, 0]).any()


def _checker_image(name, size=64, squares=8):
    image = bpy.data.images.new(name, size, size)
    y, x = np.mgrid[0:size, 0:size] * squares // size
    odd = (x + y) % 2 == 1
    pixels = np.ones((size, size, 4), np.float32)
    pixels[..., :3] = np.where(odd[..., None], (0.9, 0.6, 0.1), (0.1, 0.2, 0.7))
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    return image


def test_a_uv_textured_cube_on_a_checkered_floor_matches_cycles(lit_scene):
    image = _checker_image("checker")
    material, tree, principled = _material("textured")
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = 'Closest'
    tree.links.new(texture.outputs["Color"], principled.inputs["Base Color"])
    bpy.ops.mesh.primitive_cube_add(size=1.6, rotation=(0.3, 0.2, 0.6))
    bpy.context.object.data.materials.append(material)
    floor_material, floor_tree, floor_principled = _material("floor")
    checker = floor_tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 6.0
    floor_tree.links.new(checker.outputs["Color"], floor_principled.inputs["Base Color"])
    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, -1.2))
    bpy.context.object.data.materials.append(floor_material)
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE


def test_a_normal_mapped_floor_matches_cycles(lit_scene):
    size = 64
    image = bpy.data.images.new("bumps", size, size)
    image.colorspace_settings.name = 'Non-Color'
    y, x = np.mgrid[0:size, 0:size] / size
    slope = 0.35 * np.sin(2 * np.pi * 4 * x)
    normal = np.stack([slope, np.zeros_like(slope), np.ones_like(slope)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    pixels = np.ones((size, size, 4), np.float32)
    pixels[..., :3] = normal * 0.5 + 0.5
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    material, tree, principled = _material("mapped")
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    mapping = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(texture.outputs["Color"], mapping.inputs["Color"])
    tree.links.new(mapping.outputs["Normal"], principled.inputs["Normal"])
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, -1.0), rotation=(0.6, 0, 0))
    bpy.context.object.data.materials.append(material)
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE
    # The map shows: the floor is striped, not flat.
    floor = cycles[..., 3] > 0.99
    assert glint[floor, 0].std() > 0.1 * glint[floor, 0].mean()


def _studio_light(name: str) -> str:
    """The path of one of Blender's studio-light HDRIs (its datafiles, CC0)."""
    path = os.path.join(bpy.utils.system_resource('DATAFILES', path="studiolights/world"),
                        f"{name}.exr")
    assert os.path.exists(path), f"Blender's studio light {path} not found"
    return path


def test_a_product_shot_lit_by_an_hdri_matches_cycles():
    scene = cs.cycles_scene(bounces=0, samples=1024)
    scene.glint.samples = 256
    world = scene.world.node_tree
    environment = world.nodes.new("ShaderNodeTexEnvironment")
    environment.image = bpy.data.images.load(_studio_light("sunrise"))
    background = world.nodes["Background"]
    background.inputs["Strength"].default_value = 1.0
    world.links.new(environment.outputs["Color"], background.inputs["Color"])
    image = _checker_image("label", squares=4)
    material, tree, principled = _material("product")
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    tree.links.new(texture.outputs["Color"], principled.inputs["Base Color"])
    principled.inputs["Roughness"].default_value = 0.4
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    bpy.ops.object.shade_smooth()
    ball = bpy.context.object
    ball.data.materials.append(material)
    bpy.ops.mesh.primitive_plane_add(size=10, location=(0, 0, -1.0))
    bpy.context.object.data.materials.append(cs.diffuse("floor", (0.5, 0.5, 0.5)))
    glint, cycles = core_image(), cs.render_cycles()
    on_ball = cs.sphere_mask(ball)
    floor = (cycles[..., 3] > 0.99) & ~on_ball
    floor[: cs.HEIGHT // 2] = False
    for region in (on_ball, floor):
        np.testing.assert_allclose(glint[region, :3].mean(axis=0),
                                   cycles[region, :3].mean(axis=0), rtol=MEAN_TOLERANCE)
    # The world seen straight on (the sky above the horizon) is the image itself (but on
    # the ball's silhouette, where the two balls' pixels mix differently).
    sky = np.zeros_like(on_ball)
    sky[: cs.HEIGHT // 3] = True
    relative = (np.abs(glint[sky, :3] - cycles[sky, :3]) / np.maximum(cycles[sky, :3], 1e-3))
    assert np.percentile(relative.max(axis=1), 90) < 0.01


def test_light_path_rays_see_the_world_and_shadows_as_in_cycles():
    # Two tricks Blender users build with the Light Path node: a world lighting the scene
    # warm while the camera sees it blue (Is Camera Ray), and a ball that casts no shadow
    # (Is Shadow Ray turns it Transparent for shadow rays).  With one bounce, light that
    # bounced off the floor sees the world as light, not as the camera does.
    scene = cs.cycles_scene(bounces=1, samples=1024)
    scene.glint.samples = 256
    world = scene.world.node_tree
    light_path = world.nodes.new("ShaderNodeLightPath")
    lighting, backdrop = world.nodes["Background"], world.nodes.new("ShaderNodeBackground")
    lighting.inputs["Color"].default_value = (1.0, 0.7, 0.4, 1.0)
    lighting.inputs["Strength"].default_value = 1.0
    backdrop.inputs["Color"].default_value = (0.1, 0.2, 0.8, 1.0)
    mix = world.nodes.new("ShaderNodeMixShader")
    world.links.new(light_path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    world.links.new(lighting.outputs["Background"], mix.inputs[1])
    world.links.new(backdrop.outputs["Background"], mix.inputs[2])
    world.links.new(mix.outputs["Shader"], world.nodes["World Output"].inputs["Surface"])
    material = bpy.data.materials.new("no shadow")
    tree = material.node_tree
    shadow = tree.nodes.new("ShaderNodeLightPath")
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    solid = tree.nodes["Principled BSDF"]
    solid.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    pick = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(shadow.outputs["Is Shadow Ray"], pick.inputs["Fac"])
    tree.links.new(solid.outputs["BSDF"], pick.inputs[1])
    tree.links.new(transparent.outputs["BSDF"], pick.inputs[2])
    tree.links.new(pick.outputs["Shader"], tree.nodes["Material Output"].inputs["Surface"])
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    bpy.ops.object.shade_smooth()
    ball = bpy.context.object
    ball.data.materials.append(material)
    bpy.ops.mesh.primitive_plane_add(size=10, location=(0, 0, -1.0))
    bpy.context.object.data.materials.append(cs.diffuse("floor", (0.5, 0.5, 0.5)))
    cs.add_light('SUN', (0, -5, 5), (math.radians(30), 0, math.radians(20)), energy=3.0)
    glint, cycles = core_image(), cs.render_cycles()
    on_ball = cs.sphere_mask(ball)
    floor = (cycles[..., 3] > 0.99) & ~on_ball
    floor[: cs.HEIGHT // 2] = False
    sky = np.zeros_like(on_ball)
    sky[: cs.HEIGHT // 4] = True
    sky &= ~on_ball
    for name, region in (("ball", on_ball), ("floor", floor), ("sky", sky)):
        np.testing.assert_allclose(glint[region, :3].mean(axis=0),
                                   cycles[region, :3].mean(axis=0), rtol=MEAN_TOLERANCE,
                                   err_msg=name)
    # The camera sees the blue backdrop; the ball and the floor are lit warm.
    assert glint[sky, 2].mean() > 3 * glint[sky, 0].mean()
    assert glint[on_ball, 0].mean() > glint[on_ball, 2].mean()


def test_mesh_attributes_and_uv_map_nodes_match_cycles(lit_scene):
    """A subdivided plane's render colour attribute (corner bytes: scene-linear in Cycles),
    a point float and a face integer through Vertex Color, Attribute and UV Map nodes: the
    exporter hands each to the integrator, which interpolates it at the hit as Cycles does
    (a missing attribute reads black, a missing vertex colour black with alpha 0)."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=4, size=4.0,
                                    rotation=(math.pi / 2, 0.0, 0.0))   # facing the camera
    plane = bpy.context.object
    mesh = plane.data
    mesh.color_attributes.new("paint", 'BYTE_COLOR', 'CORNER')
    mesh.attributes.new("height", 'FLOAT', 'POINT')
    mesh.attributes.new("group", 'INT', 'FACE')
    mesh.color_attributes.render_color_index = 0
    rng = np.random.default_rng(5)
    paint = mesh.attributes["paint"]
    colours = rng.uniform(0.05, 1.0, (len(paint.data), 4))
    paint.data.foreach_set("color", colours.astype(np.float32).ravel())
    height = mesh.attributes["height"]
    height.data.foreach_set("value", rng.uniform(0, 1, len(height.data)).astype(np.float32))
    group = mesh.attributes["group"]
    group.data.foreach_set("value", np.arange(len(group.data), dtype=np.int32) % 3)
    material, tree, principled = _material("attributes")
    vertex = tree.nodes.new("ShaderNodeVertexColor")          # the render colour
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "height"
    faces = tree.nodes.new("ShaderNodeAttribute")
    faces.attribute_name = "group"
    uv = tree.nodes.new("ShaderNodeUVMap")
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = 'RGBA'
    tree.links.new(attribute.outputs["Fac"], mix.inputs["Factor"])
    tree.links.new(vertex.outputs["Color"], mix.inputs[6])
    tree.links.new(uv.outputs["UV"], mix.inputs[7])
    tree.links.new(mix.outputs[2], principled.inputs["Base Color"])
    scale = tree.nodes.new("ShaderNodeMath")
    scale.operation = 'MULTIPLY'
    scale.inputs[1].default_value = 0.3
    tree.links.new(faces.outputs["Fac"], scale.inputs[0])
    tree.links.new(scale.outputs[0], principled.inputs["Roughness"])
    mesh.materials.append(material)
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE
    # The attributes are there: the plane is not one colour.
    plane = cycles[..., :3].max(axis=2) > 0
    assert plane.mean() > 0.3 and glint[plane, :3].std(axis=0).min() > 0.02


def test_a_displaced_ball_is_bumped_as_cycles_bumps_it(lit_scene):
    """A material output's Displacement (a Displacement node fed by a Noise texture) under
    Cycles' default Bump Only method: the height is the displacement along the normal and
    every shader with an unlinked Normal takes the bumped normal, as Cycles' graph does
    (measured 0.8 % per pixel at the 90th percentile)."""
    material, tree, principled = _material("displaced")
    principled.inputs["Base Color"].default_value = (0.7, 0.6, 0.5, 1.0)
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 4.0
    noise.inputs["Detail"].default_value = 2.0
    displacement = tree.nodes.new("ShaderNodeDisplacement")
    displacement.inputs["Scale"].default_value = 0.3
    tree.links.new(noise.outputs["Fac"], displacement.inputs["Height"])
    output = tree.get_output_node('ALL') or tree.get_output_node('CYCLES')
    tree.links.new(displacement.outputs["Displacement"], output.inputs["Displacement"])
    _smooth_ball(material)
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE
    # The bumps show: without the displacement the ball's shading is smooth.
    tree.links.remove(output.inputs["Displacement"].links[0])
    smooth = core_image()
    ball = cycles[..., 3] > 0.99
    assert np.abs(smooth[ball, :3] - glint[ball, :3]).max() > 0.05


@pytest.mark.parametrize("direction_type, axis", [("RADIAL", "Z"), ("RADIAL", "X"),
                                                  ("UV_MAP", "Z")])
def test_the_tangent_node_matches_cycles(lit_scene, direction_type, axis):
    """The Tangent node's direction (radial about an axis through the Generated coordinate's
    centre, or the UV map's tangent), shown as an emission colour 0.5 + 0.5 T on a turned,
    smooth ball: per pixel as Cycles computes it."""
    material = new_material("tangent")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeTangent")
    node.direction_type, node.axis = direction_type, axis
    shown = tree.nodes.new("ShaderNodeVectorMath")
    shown.operation = 'MULTIPLY_ADD'
    shown.inputs[1].default_value = (0.5, 0.5, 0.5)
    shown.inputs[2].default_value = (0.5, 0.5, 0.5)
    emission = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(node.outputs["Tangent"], shown.inputs[0])
    tree.links.new(shown.outputs["Vector"], emission.inputs["Color"])
    output = tree.get_output_node('ALL') or tree.get_output_node('CYCLES')
    tree.links.new(emission.outputs["Emission"], output.inputs["Surface"])
    _smooth_ball(material, rotation=(0.4, 0.3, 0.2))
    glint, cycles = core_image(), cs.render_cycles()
    assert _per_pixel(glint, cycles) < PIXEL_TOLERANCE
    ball = cycles[..., 3] > 0.99
    assert glint[ball, :3].std(axis=0).max() > 0.1      # the direction varies over the ball


@pytest.mark.parametrize("metallic", [1.0, 0.0])
def test_a_normal_tilted_away_from_the_view_keeps_its_glossy_reflection_as_in_cycles(metallic):
    """A floor seen at a grazing angle whose mapped normal leans away from the camera would
    mirror the view into the floor: Cycles raises the glossy lobes' normal until their
    reflection stays above the surface (maybe_ensure_valid_specular_reflection) and layers
    the diffuse lobe under that lobe, while the diffuse lobe keeps the mapped normal.  Under
    a blue world, the floor's mean within MEAN_TOLERANCE of Cycles' (a metal that lost
    those reflections instead lost a fifth of its light; a dielectric 1.5 %)."""
    scene = cs.cycles_scene(bounces=0, samples=256)
    scene.glint.samples = 128
    cs.set_world((0.6, 0.7, 0.9), 1.0)
    material, tree, principled = _material("leaning")
    principled.inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    principled.inputs["Roughness"].default_value = 0.1
    principled.inputs["Metallic"].default_value = metallic
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    normal_map.space = 'OBJECT'
    # Object-space normal (0, 0.5, 0.866): leaning 30 degrees away from the camera (+Y).
    normal_map.inputs["Color"].default_value = (0.5, 0.75, 0.933, 1.0)
    tree.links.new(normal_map.outputs["Normal"], principled.inputs["Normal"])
    mesh = bpy.data.meshes.new("floor")
    mesh.from_pydata([(-6, -6, -1), (6, -6, -1), (6, 6, -1), (-6, 6, -1)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    link(bpy.data.objects.new("floor", mesh))
    glint, cycles = cs.render_both()
    rows = slice(cs.HEIGHT // 2 + 2, cs.HEIGHT)
    np.testing.assert_allclose(glint[rows, :, :3].reshape(-1, 3).mean(axis=0),
                               cycles[rows, :, :3].reshape(-1, 3).mean(axis=0),
                               rtol=MEAN_TOLERANCE)
