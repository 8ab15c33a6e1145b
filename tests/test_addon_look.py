"""Export in the default semantics: shader nodes -> SurfaceMaterial lobes, every light type
-> Cycles-unit lights, the world's Background -> scene-linear radiance; the engine lets the
Shader Editor in."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon_support import (add_camera, add_sphere, add_world, camera_and_light_file, core,
                           depsgraph, empty_file, export_scene, link)
from glint.addon.compat import new_material  # noqa: E402
from cycles_support import node_material
from glint.addon.engine.base import GlintRenderEngine


@pytest.fixture
def scene():
    return camera_and_light_file()


def material_with(kind, **inputs):
    """(material, its one shader node): ``node_material`` named after the node's kind."""
    material = node_material(kind, kind, **inputs)
    surface = material.node_tree.nodes["Material Output"].inputs["Surface"]
    return material, surface.links[0].from_node


def exported_material(material):
    add_sphere("ball", material=material)
    exported, warnings = export_scene(depsgraph())
    return exported.spheres[0].material, warnings


def test_the_shader_editor_works_with_glint():
    assert GlintRenderEngine.bl_use_shading_nodes_custom is False


def test_a_diffuse_bsdf_is_its_colour_in_scene_linear(scene):
    material, _ = material_with("ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.05))
    surface, warnings = exported_material(material)
    assert isinstance(surface, core.SurfaceMaterial)
    np.testing.assert_allclose(surface.diffuse, (0.8, 0.1, 0.05), rtol=1e-6)
    assert surface.specular_f0 == (0.0, 0.0, 0.0) and not any("ball" in w for w in warnings)


def test_blenders_default_material_is_a_default_principled_bsdf(scene):
    add_sphere("plain")
    surface = export_scene(depsgraph())[0].spheres[0].material
    expected = core.SurfaceMaterial.principled()
    assert surface == expected
    assert surface.roughness == 0.5 and surface.specular_f0[0] == pytest.approx(
        ((1.5 - 1) / 2.5) ** 2)


def test_principled_inputs_map_to_lobes(scene):
    material = new_material("glassy metal")
    node = material.node_tree.nodes["Principled BSDF"]
    node.inputs["Base Color"].default_value = (0.5, 0.2, 0.1, 1.0)
    node.inputs["Metallic"].default_value = 0.25
    node.inputs["Roughness"].default_value = 0.1
    node.inputs["IOR"].default_value = 1.45
    node.inputs["Transmission Weight"].default_value = 0.5
    node.inputs["Alpha"].default_value = 0.8
    node.inputs["Emission Color"].default_value = (1.0, 0.5, 0.0, 1.0)
    node.inputs["Emission Strength"].default_value = 2.0
    surface, _ = exported_material(material)
    expected = core.SurfaceMaterial.principled(
        base_color=(0.5, 0.2, 0.1), metallic=0.25, roughness=0.1, ior=1.45, transmission=0.5,
        emission=(2.0, 1.0, 0.0), alpha=0.8)
    for field in ("diffuse", "specular_f0", "specular_f90", "transmission", "emission",
                  "transparency"):
        np.testing.assert_allclose(getattr(surface, field), getattr(expected, field),
                                   rtol=1e-6, atol=1e-7, err_msg=field)
    assert surface.roughness == pytest.approx(0.1) and surface.ior == pytest.approx(1.45)
    np.testing.assert_allclose(surface.transparency, (0.2,) * 3, rtol=1e-6)


def test_glass_refraction_and_glossy_nodes(scene):
    glass, _ = material_with("ShaderNodeBsdfGlass", Color=(0.9, 0.8, 0.7), IOR=1.5,
                             Roughness=0.0)
    surface, _ = exported_material(glass)
    np.testing.assert_allclose(surface.transmission, (0.9, 0.8, 0.7), rtol=1e-6)
    np.testing.assert_allclose(surface.specular_f0, np.array((0.9, 0.8, 0.7)) * 0.04, rtol=1e-6)
    assert surface.transmission_fresnel == 1.0 and surface.ior == pytest.approx(1.5)

    empty_file()
    add_camera()
    refraction, _ = material_with("ShaderNodeBsdfRefraction", Color=(1.0, 1.0, 1.0), IOR=1.33)
    surface, _ = exported_material(refraction)
    assert surface.transmission_fresnel == 0.0 and surface.specular_f90 == (0.0, 0.0, 0.0)

    empty_file()
    add_camera()
    glossy, _ = material_with("ShaderNodeBsdfGlossy", Color=(0.2, 0.4, 0.6), Roughness=0.3)
    surface, _ = exported_material(glossy)
    np.testing.assert_allclose(surface.specular_f0, (0.2, 0.4, 0.6), rtol=1e-6)
    np.testing.assert_allclose(surface.specular_f90, (0.2, 0.4, 0.6), rtol=1e-6)
    assert surface.roughness == pytest.approx(0.3) and surface.diffuse == (0.0, 0.0, 0.0)


def test_mix_shader_factor_from_fresnel_is_evaluated_per_hit(scene):
    material = new_material("coated")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    red = tree.nodes.new("ShaderNodeBsdfDiffuse")
    red.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    blue = tree.nodes.new("ShaderNodeBsdfDiffuse")
    blue.inputs["Color"].default_value = (0.0, 0.0, 1.0, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    fresnel = tree.nodes.new("ShaderNodeFresnel")
    fresnel.inputs["IOR"].default_value = 1.5
    tree.links.new(fresnel.outputs[0], mix.inputs[0])
    tree.links.new(red.outputs[0], mix.inputs[1])
    tree.links.new(blue.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    surface, _ = exported_material(material)
    # A program the path integrator runs per hit; its constants are its value seen along
    # the normal, where Fresnel of IOR 1.5 is the normal reflectance, 0.04.
    assert surface.program is not None
    np.testing.assert_allclose(surface.diffuse, (0.96, 0.0, 0.04), rtol=1e-6)


def test_emission_holdout_transparent_and_add_shader(scene):
    material = new_material("sum")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    emission.inputs["Strength"].default_value = 4.0
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(emission.outputs[0], add.inputs[0])
    tree.links.new(transparent.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    surface, _ = exported_material(material)
    np.testing.assert_allclose(surface.emission, (4.0, 2.0, 1.0))
    np.testing.assert_allclose(surface.transparency, (1.0, 1.0, 1.0))

    empty_file()
    add_camera()
    holdout, _ = material_with("ShaderNodeHoldout")
    surface, _ = exported_material(holdout)
    assert surface.holdout == 1.0 and surface.diffuse == (0.0, 0.0, 0.0)


def test_an_unsupported_node_feeds_the_sockets_own_value_and_is_named(scene):
    material, node = material_with("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    wireframe = material.node_tree.nodes.new("ShaderNodeWireframe")
    material.node_tree.links.new(wireframe.outputs["Fac"], node.inputs["Color"])
    surface, warnings = exported_material(material)
    np.testing.assert_allclose(surface.diffuse, (0.2, 0.4, 0.6), rtol=1e-6)
    (note,) = [w for w in warnings if "material 'ShaderNodeBsdfDiffuse'" in w]
    assert wireframe.name in note and "not supported" in note


def test_an_unsupported_shader_renders_grey_and_is_named(scene):
    material, node = material_with("ShaderNodeBsdfHairPrincipled")
    surface, warnings = exported_material(material)
    assert surface.diffuse == (0.8, 0.8, 0.8)
    assert any(node.name in w and "not supported" in w for w in warnings)


@pytest.mark.parametrize("kind", ["ShaderNodeSubsurfaceScattering", "ShaderNodeBsdfSheen",
                                  "ShaderNodeBsdfToon"])
def test_approximated_shaders_are_a_diffuse_of_their_colour_with_one_note(scene, kind):
    material, node = material_with(kind, Color=(0.2, 0.4, 0.6))
    surface, warnings = exported_material(material)
    np.testing.assert_allclose(surface.diffuse, (0.2, 0.4, 0.6), rtol=1e-6)
    assert len([w for w in warnings if node.name in w and "approximated" in w]) == 1


@pytest.mark.parametrize("kind, output, socket", [
    ("ShaderNodeAmbientOcclusion", "Color", "Base Color"),
    ("ShaderNodeBevel", "Normal", "Normal")])
def test_ambient_occlusion_and_bevel_are_stand_ins_named_once(scene, kind, output, socket):
    """Glint traces no rays from shaders: Ambient Occlusion passes its Color through (AO 1)
    and Bevel leaves the normal unbevelled, each named in one warning."""
    material = new_material(kind)
    tree = material.node_tree
    node = tree.nodes.new(kind)
    if kind == "ShaderNodeAmbientOcclusion":
        node.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    tree.links.new(node.outputs[output], tree.nodes["Principled BSDF"].inputs[socket])
    surface, warnings = exported_material(material)
    assert len([w for w in warnings if node.name in w and "stand-in" in w]) == 1
    if kind == "ShaderNodeAmbientOcclusion":
        # The shader gets the AO's Color, as it would that colour unlinked.
        plain = new_material("plain")
        plain.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
            0.2, 0.4, 0.6, 1.0)
        bpy.data.objects.remove(bpy.data.objects["ball"])
        reference, _ = exported_material(plain)
        assert surface == reference
    else:
        # The normal comes out as it went in.
        from glint.core.shader.registry import NODES
        normal = np.array([[0.0], [0.6], [0.8]])
        points = type("Points", (), {"position": np.zeros((3, 1)), "dtype": np.float64})()
        (out,) = NODES[kind].function(points, 0.1, normal)
        np.testing.assert_array_equal(out, normal)


def test_without_a_linked_surface_the_material_is_black_as_in_cycles(scene):
    material = new_material("unplugged")
    tree = material.node_tree
    tree.links.remove(tree.nodes["Material Output"].inputs["Surface"].links[0])
    material.diffuse_color = (0.1, 0.6, 0.2, 1.0)
    surface, warnings = exported_material(material)
    assert surface == core.SurfaceMaterial(diffuse=(0, 0, 0), roughness=0.5)
    assert any("'unplugged'" in w and "black" in w for w in warnings)


def test_every_light_type_exports_in_cycles_units():
    empty_file()
    add_camera()
    lights = {}
    for kind in ('POINT', 'SPOT', 'SUN', 'AREA'):
        data = bpy.data.lights.new(kind, kind)
        data.energy = 100.0
        data.color = (1.0, 0.5, 0.25)
        obj = link(bpy.data.objects.new(kind, data))
        obj.location = (1.0, 2.0, 3.0)
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # -Z -> +Y
        lights[kind] = obj
    lights['POINT'].data.shadow_soft_size = 0.3
    lights['SPOT'].data.spot_size, lights['SPOT'].data.spot_blend = 0.8, 0.25
    lights['SUN'].data.angle = 0.1
    area = lights['AREA']
    area.data.shape, area.data.size, area.data.size_y = 'ELLIPSE', 2.0, 0.5
    area.scale = (1.5, 1.0, 1.0)

    exported, warnings = export_scene(depsgraph())

    by_name = {light.name: light for light in exported.lights}
    point, spot, sun, disc = (by_name[k] for k in ('POINT', 'SPOT', 'SUN', 'AREA'))
    assert isinstance(point, core.SphereLight) and point.power == 100.0
    assert point.radius == pytest.approx(0.3) and point.colour == (1.0, 0.5, 0.25)
    np.testing.assert_allclose(point.position, (1, 2, 3), atol=1e-6)
    assert isinstance(spot, core.SpotLight)
    np.testing.assert_allclose(spot.direction, (0, 1, 0), atol=1e-6)
    assert spot.spot_size == pytest.approx(0.8) and spot.spot_blend == pytest.approx(0.25)
    assert isinstance(sun, core.SunLight) and sun.strength == 100.0
    np.testing.assert_allclose(sun.direction, (0, 1, 0), atol=1e-6)
    assert sun.angle == pytest.approx(0.1)
    assert isinstance(disc, core.AreaLight) and disc.shape == 'ELLIPSE'
    assert (disc.size_x, disc.size_y) == pytest.approx((3.0, 0.5))
    np.testing.assert_allclose(disc.direction, (0, 1, 0), atol=1e-6)
    assert not any("skipped" in w for w in warnings)


def test_the_world_is_its_background_colour_times_strength_in_scene_linear(scene):
    add_world("sky", (0.2, 0.1, 0.05), 3.0)
    exported, _ = export_scene(depsgraph())
    np.testing.assert_allclose(exported.background, (0.6, 0.3, 0.15), rtol=1e-6)
    np.testing.assert_allclose(exported.ambient, (0.6, 0.3, 0.15), rtol=1e-6)


def test_group_inputs_take_the_group_nodes_values_and_simple_math_is_evaluated(scene):
    """As in CLEVR's rubber material: a group's Diffuse and Glossy read the group node's
    unlinked Color and a Math node of its Roughness."""
    group = bpy.data.node_groups.new("rubber", "ShaderNodeTree")
    group.interface.new_socket("Color", in_out='INPUT', socket_type='NodeSocketColor')
    group.interface.new_socket("Roughness", in_out='INPUT', socket_type='NodeSocketFloat')
    group.interface.new_socket("Shader", in_out='OUTPUT', socket_type='NodeSocketShader')
    inputs, outputs = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    diffuse = group.nodes.new("ShaderNodeBsdfDiffuse")
    glossy = group.nodes.new("ShaderNodeBsdfGlossy")
    power = group.nodes.new("ShaderNodeMath")
    power.operation = 'POWER'
    power.inputs[1].default_value = 0.5
    add = group.nodes.new("ShaderNodeAddShader")
    group.links.new(inputs.outputs["Color"], diffuse.inputs["Color"])
    group.links.new(inputs.outputs["Roughness"], power.inputs[0])
    group.links.new(power.outputs[0], glossy.inputs["Roughness"])
    group.links.new(diffuse.outputs[0], add.inputs[0])
    group.links.new(glossy.outputs[0], add.inputs[1])
    group.links.new(add.outputs[0], outputs.inputs["Shader"])
    material = new_material("rubber")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.inputs["Color"].default_value = (0.04, 0.27, 0.007, 1.0)
    node.inputs["Roughness"].default_value = 0.25
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    surface, warnings = exported_material(material)

    np.testing.assert_allclose(surface.diffuse, (0.04, 0.27, 0.007), rtol=1e-6)
    assert surface.roughness == pytest.approx(0.5)
    assert not [w for w in warnings if "rubber" in w]
