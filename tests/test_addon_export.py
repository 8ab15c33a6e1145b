"""Export: Blender's evaluated scene -> core Scene (spheres, lights, materials, world, camera).

Meshes, point clouds and instances in detail: ``test_addon_export_geometry.py``."""

from __future__ import annotations

import math

import bpy
import bmesh  # after bpy: the pip module makes bmesh importable
import numpy as np
import pytest
from mathutils import Matrix, Vector

from addon_support import (ExportError, add_camera, add_point_light, add_sphere, add_world,
                           camera_and_light_file, core, cube_mesh, depsgraph, empty_file,
                           export_scene, ico_sphere_mesh, link, uv_sphere_mesh)
from glint.addon.compat import LIGHT_EXPOSURE, new_material  # noqa: E402
from glint.addon.export.geometry import (ANALYTIC_SPHERE_PROPERTY, FLOAT32_SLACK,
                                         MAX_FACE_SAGITTA, MAX_RADIUS_SCATTER, fit_sphere,
                                         uniform_scales)
from glint.addon.export.materials import SurfaceValues, blinn_exponent, material_from_surface
from glint.addon.utils.colour import linear_to_srgb, srgb_to_linear
from glint.core.camera import blender_view_plane, camera_rays


def export():
    return export_scene(depsgraph())


def article_semantics():
    """The article semantics exports the article's Material and PointLight (the default
    semantics' Blender look is tested in test_addon_look.py)."""
    bpy.context.scene.glint.semantics = 'ARTICLE'


def spheres_by_name(scene):
    return {sphere.name: sphere for sphere in scene.spheres}


@pytest.fixture
def scene():
    return camera_and_light_file()


# --- spheres ----------------------------------------------------------------------------------

@pytest.mark.parametrize("segments, rings", [(64, 32), (128, 64)])
def test_fine_uv_spheres_become_their_analytic_sphere(scene, segments, rings):
    obj = add_sphere("ball", (0.5, -1.0, 2.0), 0.75, segments=segments, rings=rings)
    obj.rotation_euler = (0.3, 1.1, -0.4)
    obj.scale = (2.0, 2.0, 2.0)

    exported, warnings = export()

    (sphere,) = exported.spheres
    assert sphere.name == "ball" and not exported.meshes
    # bmesh builds the vertices in float32 trigonometry: a few 1e-7 of the radius.
    np.testing.assert_allclose(sphere.center, (0.5, -1.0, 2.0), atol=1e-5 * 1.5)
    assert sphere.radius == pytest.approx(1.5, rel=1e-5)
    assert not [w for w in warnings if "skipped" in w]


@pytest.mark.parametrize("subdivisions", [3, 5])
def test_fine_ico_spheres_become_their_analytic_sphere(scene, subdivisions):
    obj = link(bpy.data.objects.new("ico", ico_sphere_mesh("ico", 0.4, subdivisions)))
    obj.location = (3.0, 1.0, -2.0)

    exported, _ = export()

    (sphere,) = exported.spheres
    np.testing.assert_allclose(sphere.center, (3.0, 1.0, -2.0), atol=1e-5)
    assert sphere.radius == pytest.approx(0.4, rel=1e-5)


def test_the_article_floor_sphere_keeps_its_radius_when_asked_to_stay_a_sphere(scene):
    # The camera at (0, -6, 0) is inside this sphere: by the pixel rule its facets show.
    floor = add_sphere("floor", (0.0, -9000.0, 0.0), 9000.0 - 0.7, segments=64, rings=32)
    assert not export()[0].spheres
    floor[ANALYTIC_SPHERE_PROPERTY] = True

    (sphere,) = export()[0].spheres

    assert sphere.radius == pytest.approx(8999.3, rel=1e-6)
    np.testing.assert_allclose(sphere.center, (0.0, -9000.0, 0.0), atol=1e-3)


def test_sphere_fit_tolerates_float32_rounding_and_records_the_scatter():
    rng = np.random.default_rng(1)
    directions = rng.normal(size=(500, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    center, radius = np.array([1000.0, -20.0, 5.0]), 0.1
    on_sphere = (center + radius * directions).astype(np.float32).astype(np.float64)
    fit = fit_sphere(on_sphere)
    assert fit is not None and fit.radius == pytest.approx(radius, rel=1e-5)
    # float32 rounding at 1000 is not a bump (the scatter is the rounding, as Blender draws it)
    assert fit.deviation <= FLOAT32_SLACK * 1000.0

    bumped = center + radius * directions
    bumped[0] = center + radius * 1.01 * directions[0]  # one vertex 1 % out
    assert fit_sphere(bumped).deviation == pytest.approx(0.01 * radius, rel=0.05)
    bumped[0] = center + radius * (1 + 2 * MAX_RADIUS_SCATTER) * directions[0]
    assert fit_sphere(bumped) is None
    assert FLOAT32_SLACK * 1000.0 < 0.01 * radius


def test_meshes_that_are_not_spheres_become_triangle_meshes(scene):
    add_sphere("ball")
    link(bpy.data.objects.new("box", cube_mesh("box")))  # vertices on a sphere, faces not
    hemisphere = uv_sphere_mesh("dome")  # vertices on a sphere, but open
    builder = bmesh.new()
    builder.from_mesh(hemisphere)
    bmesh.ops.delete(builder, geom=[v for v in builder.verts if v.co.z < -1e-6], context='VERTS')
    builder.to_mesh(hemisphere)
    builder.free()
    link(bpy.data.objects.new("dome", hemisphere))
    plane = bpy.data.meshes.new("flat")
    plane.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
    link(bpy.data.objects.new("flat", plane))

    exported, warnings = export()

    assert [s.name for s in exported.spheres] == ["ball"]
    assert sorted(m.name for m in exported.meshes) == ["box", "dome", "flat"]
    assert not [w for w in warnings if "skipped" in w]


def test_the_face_check_tells_a_coarse_ico_sphere_from_a_box():
    # An icosahedron's faces sag 20.5 % of the radius, a cube's or octahedron's 42 %.
    icosahedron_sag = 1 - math.sqrt((5 + 2 * math.sqrt(5)) / 15)
    cube_sag = 1 - 1 / math.sqrt(3)
    assert icosahedron_sag < MAX_FACE_SAGITTA < cube_sag


def test_a_non_uniformly_scaled_sphere_is_drawn_as_its_triangles(scene):
    add_sphere("ball")
    egg = add_sphere("egg", (3.0, 0.0, 0.0))
    egg.scale = (1.0, 1.0, 1.5)
    sheared = add_sphere("sheared", (-3.0, 0.0, 0.0))
    sheared.matrix_world = Matrix.Translation((-3, 0, 0)) @ Matrix.Shear('XY', 4, (0.3, 0.0))

    exported, warnings = export()

    assert [s.name for s in exported.spheres] == ["ball"]
    meshes = {m.name: m for m in exported.meshes}
    assert sorted(meshes) == ["egg", "sheared"]
    for name in meshes:
        np.testing.assert_allclose(meshes[name].transforms[0],
                                   np.array(bpy.data.objects[name].matrix_world), atol=1e-6)
    assert not [w for w in warnings if "skipped" in w]


def test_zero_scale_objects_are_skipped_as_degenerate_not_as_non_uniform(scene):
    add_sphere("ball")
    add_sphere("vanished", (3.0, 0.0, 0.0)).scale = (0.0, 0.0, 0.0)
    link(bpy.data.objects.new("flattened box", cube_mesh("flattened box"))).scale = (1, 0, 1)

    exported, warnings = export()

    assert [s.name for s in exported.spheres] == ["ball"] and not exported.meshes
    (skipped,) = [w for w in warnings if "skipped" in w]
    assert "vanished (zero scale: draws nothing)" in skipped
    assert "flattened box (zero scale: draws nothing)" in skipped
    assert "non-uniform" not in skipped


def test_mirrored_spheres_are_spheres():
    matrices = np.array([Matrix.Diagonal(d) for d in ((-2.0, 2.0, 2.0, 1.0), (2.0, 2.0, 2.1, 1.0),
                                                      (0.0, 0.0, 0.0, 1.0))])
    scales, uniform = uniform_scales(matrices)
    assert scales[0] == pytest.approx(2.0)
    assert uniform.tolist() == [True, False, False]


def test_parented_spheres_are_exported_in_world_space(scene):
    parent = link(bpy.data.objects.new("parent", None))
    parent.location = (10.0, 0.0, 0.0)
    parent.rotation_euler = (0.0, 0.0, math.pi / 2)
    parent.scale = (3.0, 3.0, 3.0)
    child = add_sphere("child", (1.0, 0.0, 0.0), 0.5, segments=64, rings=32)
    child.parent = parent

    (sphere,) = export()[0].spheres

    expected = parent.matrix_world @ Vector((1.0, 0.0, 0.0))
    np.testing.assert_allclose(sphere.center, expected, atol=1e-5)
    np.testing.assert_allclose(sphere.center, (10.0, 3.0, 0.0), atol=1e-5)
    assert sphere.radius == pytest.approx(1.5, rel=1e-6)


def test_collection_instances_of_a_sphere_become_one_sphere_set(scene):
    source = bpy.data.collections.new("source")
    ball = bpy.data.objects.new("ball", uv_sphere_mesh("ball", 0.5, 64, 32))
    ball.location = (0.0, 0.0, 1.0)
    source.objects.link(ball)  # not in the scene itself: only its instances render
    for index, x in enumerate((-2.0, 2.0)):
        instancer = link(bpy.data.objects.new(f"instancer{index}", None))
        instancer.instance_type = 'COLLECTION'
        instancer.instance_collection = source
        instancer.location = (x, 0.0, 0.0)
        instancer.scale = (2.0, 2.0, 2.0)

    exported, _ = export()

    assert not exported.spheres
    (spheres,) = exported.sphere_sets
    centers = sorted(tuple(np.round(c, 6)) for c in spheres.centers)
    assert centers == [(-2.0, 0.0, 2.0), (2.0, 0.0, 2.0)]
    np.testing.assert_allclose(spheres.radii, 1.0, rtol=1e-6)
    assert spheres.name.startswith("ball (instanced by instancer")


def test_modifiers_are_applied_before_fitting(scene):
    obj = add_sphere("grown", (0.0, 0.0, 0.0), 1.0, segments=64, rings=32)
    displace = obj.modifiers.new("grow", 'DISPLACE')
    displace.direction = 'NORMAL'
    displace.mid_level = 0.0
    displace.strength = 0.5  # no texture: every vertex moves 0.5 along its normal
    squash = add_sphere("squashed", (4.0, 0.0, 0.0), 1.0)
    warp = squash.modifiers.new("squash", 'SIMPLE_DEFORM')
    warp.deform_method = 'STRETCH'
    warp.factor = 0.5

    exported, warnings = export()

    (sphere,) = exported.spheres
    assert sphere.name == "grown"
    assert sphere.radius == pytest.approx(1.5, rel=1e-5)
    (mesh,) = exported.meshes
    assert mesh.name == "squashed"
    # The deformed mesh, not the original sphere: stretching changes its proportions.
    extent = np.ptp(mesh.vertices, axis=0)
    assert not np.allclose(extent, 2.0, rtol=0.1)


def test_objects_and_collections_hidden_for_render_are_not_exported(scene):
    add_sphere("shown")
    add_sphere("hidden", (2.0, 0.0, 0.0)).hide_render = True
    parent = bpy.data.collections.new("parent")
    child = bpy.data.collections.new("child")
    bpy.context.scene.collection.children.link(parent)
    parent.children.link(child)
    in_child = bpy.data.objects.new("in hidden collection", uv_sphere_mesh("c"))
    child.objects.link(in_child)
    parent.hide_render = True
    also_shown = bpy.data.objects.new("also in the scene collection", uv_sphere_mesh("d"))
    child.objects.link(also_shown)
    bpy.context.scene.collection.objects.link(also_shown)

    exported, warnings = export()

    assert sorted(s.name for s in exported.spheres) == ["also in the scene collection",
                                                        "shown"]
    assert not any("hidden" in w for w in warnings)


def test_collection_visibility_is_read_once_not_per_object(scene, monkeypatch):
    # Object.users_collection walks every collection in Python: once per object it made the
    # viewport's export quadratic in the objects (30,000 objects: 67 s).
    parent = bpy.data.collections.new("hidden parent")
    bpy.context.scene.collection.children.link(parent)
    parent.hide_render = True
    for index in range(3):
        parent.objects.link(bpy.data.objects.new(f"hidden {index}", uv_sphere_mesh("h")))
        add_sphere(f"shown {index}", (2.0 * index, 0.0, 0.0))

    def refuse(self):
        raise AssertionError(f"users_collection read for {self.name}")

    monkeypatch.setattr(bpy.types.Object, "users_collection", property(refuse))
    exported, _ = export()

    assert sorted(s.name for s in exported.spheres) == ["shown 0", "shown 1", "shown 2"]


def test_other_object_types_are_named_in_the_warning(scene):
    curve = bpy.data.curves.new("text", 'FONT')
    link(bpy.data.objects.new("label", curve))  # text evaluates to a mesh
    link(bpy.data.objects.new("fog", bpy.data.volumes.new("fog")))
    link(bpy.data.objects.new("empty", None))

    exported, warnings = export()

    assert [m.name for m in exported.meshes] == ["label"]
    (skipped,) = [w for w in warnings if "skipped" in w]
    assert "fog (volume object)" in skipped
    assert "label" not in skipped
    assert "empty" not in skipped  # draws nothing in a render either


# --- lights -----------------------------------------------------------------------------------

def test_a_1000_watt_white_point_light_is_the_articles_light(scene):
    article_semantics()
    (light,) = export()[0].lights
    assert light.position == (5.0, 5.0, 5.0)
    assert light.ambient == light.diffuse == light.specular == (1.0, 1.0, 1.0)
    assert light.radius == 0.0


def test_point_light_power_colour_exposure_and_radius_map_linearly():
    empty_file()
    article_semantics()
    add_camera()
    parent = link(bpy.data.objects.new("rig", None))
    parent.location = (0.0, 0.0, 10.0)
    lamp = add_point_light("lamp", (1.0, 2.0, 3.0), energy=250.0, radius=0.4,
                           colour=(1.0, 0.5, 0.25))
    lamp.parent = parent
    if LIGHT_EXPOSURE:
        lamp.data.exposure = 1.0  # twice the power
    else:
        lamp.data.energy *= 2.0   # Blender 4.2 has no light Exposure

    (light,) = export()[0].lights

    expected = (0.5, 0.25, 0.125)  # colour * 250 W * 2 / 1000 W
    np.testing.assert_allclose(light.diffuse, expected)
    np.testing.assert_allclose(light.ambient, expected)
    np.testing.assert_allclose(light.specular, expected)
    np.testing.assert_allclose(light.position, (1.0, 2.0, 13.0))
    assert light.radius == pytest.approx(0.4)
    assert light.name == "lamp"


def test_non_point_lights_are_named_in_one_warning(scene):
    article_semantics()
    for kind in ('SUN', 'SPOT', 'AREA'):
        link(bpy.data.objects.new(f"{kind.lower()} lamp", bpy.data.lights.new(kind, kind)))

    exported, warnings = export()

    assert len(exported.lights) == 1
    (skipped,) = [w for w in warnings if "point lights only" in w]
    for text in ("sun lamp (sun light)", "spot lamp (spot light)", "area lamp (area light)"):
        assert text in skipped


def test_a_scene_without_light_or_objects_exports_with_warnings():
    empty_file()
    add_camera()

    exported, warnings = export()

    assert exported.spheres == () and exported.lights == () and exported.meshes == ()
    assert any("no light" in w for w in warnings)
    assert any("nothing to render" in w for w in warnings)


# --- materials and world ----------------------------------------------------------------------

def test_blenders_default_surface_maps_close_to_the_article_look(scene):
    article_semantics()
    add_sphere("plain")  # no material: Blender's default surface
    add_sphere("default", (3, 0, 0), material=new_material("fresh"))

    exported, _ = export()

    for sphere in exported.spheres:
        material = sphere.material
        grey = float(linear_to_srgb(0.8))
        np.testing.assert_allclose(material.diffuse, (grey,) * 3)
        np.testing.assert_allclose(material.ambient, (0.1,) * 3)
        np.testing.assert_allclose(material.specular, (1.0,) * 3)
        assert material.shininess == pytest.approx(120.0)
        assert material.reflection == pytest.approx(0.5)


def test_principled_values_map_as_documented(scene):
    article_semantics()
    metal = new_material("metal")
    principled = metal.node_tree.nodes["Principled BSDF"]
    base = (0.5, 0.2, 0.05)
    principled.inputs["Base Color"].default_value = (*base, 1.0)
    principled.inputs["Metallic"].default_value = 1.0
    principled.inputs["Roughness"].default_value = 0.2
    principled.inputs["Specular IOR Level"].default_value = 0.25
    add_sphere("metal", material=metal)

    (sphere,) = export()[0].spheres
    material = sphere.material

    colour = linear_to_srgb(base)
    exponent = 2 / 0.04 ** 2 - 2
    assert material.diffuse == (0.0, 0.0, 0.0)
    assert material.ambient == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(material.specular, colour * 2 * 0.25 * 1.0)
    assert material.shininess == pytest.approx(4 * exponent)
    assert material.reflection == pytest.approx(0.8)


def test_article_colours_map_to_the_articles_ambient():
    for diffuse, ambient in [((0.7, 0, 0), (0.1, 0, 0)), ((0.7, 0, 0.7), (0.1, 0, 0.1)),
                             ((0, 0.6, 0), (0, 0.1, 0)), ((0.6, 0.6, 0.6), (0.1, 0.1, 0.1))]:
        linear = tuple(float(c) for c in srgb_to_linear(diffuse))
        material = material_from_surface(SurfaceValues(linear, 0.0, 0.5, 0.5))
        np.testing.assert_allclose(material.diffuse, diffuse, atol=1e-12)
        np.testing.assert_allclose(material.ambient, ambient, atol=1e-12)


def test_rougher_materials_get_wider_dimmer_highlights():
    exponents = [blinn_exponent(r) for r in (0.1, 0.5, 0.9)]
    assert exponents[0] > exponents[1] > exponents[2] > 0
    rough = material_from_surface(SurfaceValues((0.8,) * 3, 0.0, 0.9, 0.5))
    assert rough.specular[0] < 0.2 and rough.reflection == pytest.approx(0.1)


def test_custom_glint_values_are_used_as_typed(scene):
    article_semantics()
    material = new_material("typed")
    custom = material.glint
    custom.use_custom = True
    custom.ambient, custom.diffuse, custom.specular = (0.1, 0, 0), (0.7, 0, 0), (0.5, 0.5, 0.5)
    custom.shininess, custom.reflection = 42.0, 0.25
    add_sphere("typed", material=material)

    (sphere,) = export()[0].spheres

    np.testing.assert_allclose(sphere.material.ambient, (0.1, 0, 0), atol=1e-7)
    np.testing.assert_allclose(sphere.material.diffuse, (0.7, 0, 0), atol=1e-7)
    np.testing.assert_allclose(sphere.material.specular, (0.5, 0.5, 0.5), atol=1e-7)
    assert sphere.material.shininess == pytest.approx(42.0)
    assert sphere.material.reflection == pytest.approx(0.25)


def test_a_non_principled_surface_falls_back_to_viewport_display_with_a_note(scene):
    article_semantics()
    material = new_material("diffuse only")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(diffuse.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    material.diffuse_color = (0.2, 0.4, 0.6, 1.0)
    material.metallic, material.roughness = 0.0, 0.5
    add_sphere("ball", material=material)

    exported, warnings = export()

    (sphere,) = exported.spheres
    np.testing.assert_allclose(sphere.material.diffuse, linear_to_srgb((0.2, 0.4, 0.6)))
    assert any("'diffuse only'" in w and "Viewport Display" in w for w in warnings)


def test_the_world_colour_is_background_and_ambient(scene):
    article_semantics()
    add_world("sky", (0.2, 0.1, 0.05), 0.5)

    exported, _ = export()

    expected = linear_to_srgb((0.1, 0.05, 0.025))
    np.testing.assert_allclose(exported.background, expected)
    np.testing.assert_allclose(exported.ambient, expected)


def test_no_world_is_black(scene):
    bpy.context.scene.world = None
    exported, _ = export()
    assert exported.background == (0.0, 0.0, 0.0) and exported.ambient == (0.0, 0.0, 0.0)


# --- camera -----------------------------------------------------------------------------------

def test_no_camera_is_a_clear_error():
    empty_file()
    add_sphere()
    with pytest.raises(ExportError, match="has no camera"):
        export()


def test_a_panoramic_camera_is_a_clear_error(scene):
    bpy.context.scene.camera.data.type = 'PANO'
    with pytest.raises(ExportError, match="'camera' is panoramic"):
        export()


def test_a_non_camera_scene_camera_is_a_clear_error(scene):
    bpy.context.scene.camera = add_sphere("ball")
    with pytest.raises(ExportError, match="'ball' is a mesh object, not a camera"):
        export()


def as_rows(vectors) -> np.ndarray:
    """(n, 3) from the core's ray arrays, whichever of (n, 3) or (3, n) layout they use."""
    vectors = np.asarray(vectors, np.float64)
    return vectors if vectors.shape[-1] == 3 and vectors.shape[0] != 3 else vectors.T


CAMERA_CASES = {
    "auto wide": dict(resolution=(64, 48)),
    "auto tall": dict(resolution=(30, 64)),
    "horizontal tall": dict(resolution=(30, 64), fit='HORIZONTAL'),
    "vertical wide": dict(resolution=(64, 48), fit='VERTICAL', sensor=(36.0, 20.0)),
    "shift": dict(resolution=(64, 48), shift=(0.2, -0.15)),
    "pixel aspect": dict(resolution=(64, 48), aspect=(2.0, 1.0)),
    "pixel aspect tips auto fit": dict(resolution=(40, 48), aspect=(1.5, 1.0)),
    "percentage": dict(resolution=(128, 90), percentage=50),
    "percentage truncates": dict(resolution=(128, 90), percentage=37),
    "ortho": dict(resolution=(64, 48), ortho=3.5, shift=(0.1, 0.05)),
    "ortho vertical": dict(resolution=(48, 64), ortho=2.0, fit='VERTICAL', aspect=(1.0, 1.25)),
}


def camera_case(resolution, fit='AUTO', sensor=(36.0, 24.0), shift=(0.0, 0.0),
                aspect=(1.0, 1.0), percentage=100, ortho=None):
    scene = empty_file()
    camera = add_camera(location=(1.0, -7.0, 2.0), rotation=(1.3, 0.2, 0.4), lens=35.0)
    data = camera.data
    data.sensor_fit = fit
    data.sensor_width, data.sensor_height = sensor
    data.shift_x, data.shift_y = shift
    data.clip_start, data.clip_end = 0.5, 50.0
    if ortho is not None:
        data.type = 'ORTHO'
        data.ortho_scale = ortho
    render = scene.render
    render.resolution_x, render.resolution_y = resolution
    render.resolution_percentage = percentage
    render.pixel_aspect_x, render.pixel_aspect_y = aspect
    return scene, camera


# view_frame sizes the frame from the resolution before the percentage's truncation to whole
# pixels; renders (and calc_matrix_camera below) use the truncated size.
VIEW_FRAME_CASES = [name for name in CAMERA_CASES if name != "percentage truncates"]


@pytest.mark.parametrize("case", VIEW_FRAME_CASES)
def test_camera_view_plane_matches_blenders_view_frame(case):
    scene, camera = camera_case(**CAMERA_CASES[case])
    exported, _ = export()
    cam = exported.camera
    plane = blender_view_plane(cam)

    frame = np.array([tuple(v) for v in camera.data.view_frame(scene=scene)])
    if camera.data.type == 'ORTHO':
        xy = frame[:, :2]
    else:
        xy = frame[:, :2] / -frame[:, 2:3]
    assert xy[:, 0].min() == pytest.approx(plane.offset_x - plane.half_width, abs=1e-6)
    assert xy[:, 0].max() == pytest.approx(plane.offset_x + plane.half_width, abs=1e-6)
    assert xy[:, 1].min() == pytest.approx(plane.offset_y - plane.half_height, abs=1e-6)
    assert xy[:, 1].max() == pytest.approx(plane.offset_y + plane.half_height, abs=1e-6)
    assert (cam.width, cam.height) == (
        int(scene.render.resolution_x * scene.render.resolution_percentage / 100),
        int(scene.render.resolution_y * scene.render.resolution_percentage / 100))


@pytest.mark.parametrize("case", CAMERA_CASES, ids=list(CAMERA_CASES))
def test_camera_rays_project_to_pixel_centres_through_calc_matrix_camera(case):
    scene, camera = camera_case(**CAMERA_CASES[case])
    graph = depsgraph()
    exported, _ = export_scene(graph)
    cam = exported.camera
    render = scene.render
    projection = np.array(camera.calc_matrix_camera(
        graph, x=cam.width, y=cam.height,
        scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y))
    view = np.array(camera.matrix_world.normalized().inverted())

    cols, rows = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
    cols, rows = cols.ravel(), rows.ravel()
    rays = camera_rays(cam, cols + 0.5, rows + 0.5)
    directions = as_rows(rays.directions)
    origins = np.broadcast_to(as_rows(rays.origins), directions.shape)
    t_min = np.broadcast_to(np.asarray(rays.t_min, np.float64).reshape(-1, 1),
                            (len(directions), 1))
    # Points at depth between the clip planes, projected by Blender's own matrices.
    points = origins + directions * (t_min + 1.0)
    homogeneous = np.hstack([points, np.ones((len(points), 1))]) @ (projection @ view).T
    ndc = homogeneous[:, :2] / homogeneous[:, 3:4]

    expected_x = 2 * (cols + 0.5) / cam.width - 1
    expected_y = 2 * (cam.height - rows - 0.5) / cam.height - 1  # row 0 is the top
    # mathutils matrices are float32: 1e-5 in NDC is under a thousandth of a pixel here.
    np.testing.assert_allclose(ndc[:, 0], expected_x, atol=1e-5)
    np.testing.assert_allclose(ndc[:, 1], expected_y, atol=1e-5)
    # And the clip planes are Blender's depths: clip_start projects to NDC z = -1.
    near = origins + directions * t_min
    near_h = np.hstack([near, np.ones((len(near), 1))]) @ (projection @ view).T
    np.testing.assert_allclose(near_h[:, 2] / near_h[:, 3], -1.0, atol=1e-5)


def test_the_camera_matrix_is_exported_as_nested_tuples(scene):
    cam = export()[0].camera
    expected = tuple(tuple(row) for row in bpy.context.scene.camera.matrix_world)
    assert cam.matrix_world == expected
    assert isinstance(cam, core.BlenderCamera)


# --- invalid values in the article semantics (docs/invalid-data.md) ----------------------------

def test_article_semantics_leaves_out_a_negative_or_nan_light_with_one_warning(scene):
    """The article's lights neither subtract light nor go dark; the light is left out."""
    article_semantics()
    bpy.data.objects["light"].data.energy = -500.0
    add_point_light("nan", energy=float("nan"))
    exported, warnings = export()
    assert not exported.lights
    assert ("light 'light': negative power, which the article's lights cannot subtract: the "
            "article semantics leaves it out") in warnings
    assert ("light 'nan': power or colour not finite: the article semantics leaves it out"
            in warnings)


def test_article_semantics_counts_a_nan_input_as_0_with_one_warning(scene):
    article_semantics()
    paint = new_material("Paint")
    paint.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = float("nan")
    add_sphere("ball", material=paint)
    exported, warnings = export()
    expected = material_from_surface(SurfaceValues((0.8, 0.8, 0.8), 0.0, 0.5, 0.5))
    np.testing.assert_allclose(exported.spheres[0].material.diffuse, expected.diffuse,
                               rtol=1e-6)  # (Blender's 0.8 is float32)
    assert exported.spheres[0].material.specular == pytest.approx(expected.specular)
    assert "object 'ball', material 'Paint': metallic nan counts as 0.0" in warnings
