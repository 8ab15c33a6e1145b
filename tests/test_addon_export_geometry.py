"""Export of geometry: meshes as triangles, the sphere-or-triangles rule, point clouds and
instances (``addon/export/meshes.py``, ``geometry.py``, ``pointclouds.py``, ``instances.py``).

Expected values come from Blender itself (the mesh's own data read back one element at a
time, the depsgraph's own instance matrices) or from geometry worked out in the comments.
"""

from __future__ import annotations

import math
import warnings

import bpy
import bmesh  # after bpy: the pip module makes bmesh importable
import numpy as np
import pytest
from mathutils import Matrix

from addon_support import (add_camera, add_sphere, camera_and_light_file, core, cube_mesh,
                           depsgraph, empty_file, export_scene, ico_sphere_mesh, link,
                           uv_sphere_mesh)
from glint.addon.compat import new_material  # noqa: E402
from glint.addon.export import instances as instances_module
from glint.addon.export.context import CameraFootprint
from glint.addon.export.geometry import MAX_DEVIATION_PIXELS, mesh_sphere
from glint.core.camera import camera_rays


def export():
    return export_scene(depsgraph())


@pytest.fixture
def scene():
    return camera_and_light_file()


def add_mesh(name, mesh, location=(0.0, 0.0, 0.0)):
    obj = link(bpy.data.objects.new(name, mesh))
    obj.location = location
    return obj


def coloured(name, rgb):
    material = new_material(name)
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*rgb, 1)
    return material


def corner_normals_one_by_one(mesh) -> np.ndarray:
    """(T, 3, 3) Blender's corner normals gathered triangle by triangle (the slow, obvious
    way), as the reference for the exporter's foreach_get gather."""
    return np.array([[tuple(mesh.corner_normals[loop].vector) for loop in triangle.loops]
                     for triangle in mesh.loop_triangles])


# --- meshes -----------------------------------------------------------------------------------

def test_a_cube_is_twelve_flat_triangles_in_object_space_with_its_world_matrix(scene):
    cube = add_mesh("cube", cube_mesh("cube", 2.0), (1.0, 2.0, 0.5))
    cube.rotation_euler = (0.3, 0.2, 0.1)

    exported, warnings = export()

    (mesh,) = exported.meshes
    assert mesh.name == "cube" and not exported.spheres
    assert mesh.triangles.shape == (12, 3) and mesh.vertices.shape == (8, 3)
    assert mesh.corner_normals is None  # all faces flat: the geometric normal is Blender's
    np.testing.assert_array_equal(mesh.vertices, [tuple(v.co) for v in cube.data.vertices])
    np.testing.assert_array_equal(mesh.triangles,
                                  [tuple(t.vertices) for t in cube.data.loop_triangles])
    np.testing.assert_allclose(mesh.transforms, [np.array(cube.matrix_world)], atol=1e-7)
    assert not [w for w in warnings if "skipped" in w]


def test_smooth_normals_are_blenders_corner_normals(scene):
    mesh = cube_mesh("smooth cube")
    mesh.shade_smooth()
    add_mesh("smooth cube", mesh)

    (exported,) = export()[0].meshes

    reference = corner_normals_one_by_one(mesh)
    np.testing.assert_allclose(exported.corner_normals, reference, atol=1e-6)
    # Smooth shading of a cube: every corner's normal points along its vertex (x, y, z)/sqrt 3.
    corners = exported.vertices[exported.triangles]
    np.testing.assert_allclose(exported.corner_normals, corners / np.sqrt(3.0), atol=1e-6)


def test_sharp_edges_split_the_normals(scene):
    mesh = bpy.data.meshes.new("can")
    builder = bmesh.new()
    bmesh.ops.create_cone(builder, cap_ends=True, segments=16, radius1=1.0, radius2=1.0,
                          depth=2.0)
    builder.to_mesh(mesh)
    builder.free()
    mesh.shade_smooth()
    mesh.set_sharp_from_angle(angle=math.radians(30))  # Blender 4.1+'s auto smooth
    add_mesh("can", mesh)

    (exported,) = export()[0].meshes

    np.testing.assert_allclose(exported.corner_normals, corner_normals_one_by_one(mesh),
                               atol=1e-6)
    # Side faces meet at 22.5 degrees (smooth: horizontal normals along the radius), the caps
    # at 90 (sharp: the caps' own normals, straight up or down).
    normals = exported.corner_normals.reshape(-1, 3)
    corners = exported.vertices[exported.triangles].reshape(-1, 3)
    cap = np.abs(normals[:, 2]) > 0.5
    assert cap.any() and (~cap).any()
    np.testing.assert_allclose(np.abs(normals[cap, 2]), 1.0, atol=1e-6)
    np.testing.assert_allclose(normals[~cap, :2], corners[~cap, :2], atol=1e-5)
    np.testing.assert_allclose(normals[~cap, 2], 0.0, atol=1e-6)


def test_custom_split_normals_are_kept(scene):
    mesh = cube_mesh("custom")
    mesh.shade_smooth()
    tilted = np.array([0.0, 0.6, 0.8])
    mesh.normals_split_custom_set_from_vertices([tuple(tilted)] * len(mesh.vertices))
    add_mesh("custom", mesh)

    (exported,) = export()[0].meshes

    np.testing.assert_allclose(exported.corner_normals.reshape(-1, 3),
                               np.tile(tilted, (36, 1)), atol=1e-4)


def test_each_triangle_keeps_its_faces_material_slot(scene):
    mesh = cube_mesh("two colours")
    mesh.materials.append(coloured("red", (0.8, 0.0, 0.0)))
    mesh.materials.append(coloured("blue", (0.0, 0.0, 0.8)))
    slots = np.array([0, 1, 1, 0, 1, 0])
    mesh.polygons.foreach_set("material_index", slots)
    add_mesh("two colours", mesh)

    (exported,) = export()[0].meshes

    faces = np.array([t.polygon_index for t in mesh.loop_triangles])
    np.testing.assert_array_equal(exported.material_indices, slots[faces])
    red, blue = exported.materials
    assert red.diffuse[0] > 0.5 > red.diffuse[2] and blue.diffuse[2] > 0.5 > blue.diffuse[0]


def test_a_material_index_past_the_last_slot_uses_the_last_slot(scene):
    mesh = cube_mesh("overflow")
    mesh.materials.append(coloured("only", (0.1, 0.7, 0.1)))
    mesh.polygons.foreach_set("material_index", [0, 0, 0, 3, 3, 3])
    add_mesh("overflow", mesh)

    (exported,) = export()[0].meshes

    assert len(exported.materials) == 1
    np.testing.assert_array_equal(exported.material_indices, 0)


def test_a_shared_mesh_is_exported_once_with_one_transform_per_object(scene):
    mesh = cube_mesh("shared")
    objects = [add_mesh(f"copy{i}", mesh, (3.0 * i, 0.0, 0.0)) for i in range(3)]
    objects[1].scale = (1.0, 2.0, 0.5)  # non-uniform is fine for triangles

    (exported,) = export()[0].meshes

    assert exported.transforms.shape == (3, 4, 4)
    assert exported.name == "copy0 (3 instances)"
    expected = sorted(np.array(obj.matrix_world).ravel().tolist() for obj in objects)
    got = sorted(t.ravel().tolist() for t in exported.transforms)
    np.testing.assert_allclose(got, expected, atol=1e-7)


def test_object_linked_materials_split_a_shared_mesh(scene):
    mesh = cube_mesh("shared")
    mesh.materials.append(coloured("data", (0.5, 0.5, 0.5)))
    plain = add_mesh("plain", mesh)
    special = add_mesh("special", mesh, (3.0, 0.0, 0.0))
    special.material_slots[0].link = 'OBJECT'
    special.material_slots[0].material = coloured("object", (0.9, 0.1, 0.1))

    exported = {m.name: m for m in export()[0].meshes}

    assert sorted(exported) == ["plain", "special"]
    assert exported["special"].materials[0].diffuse[0] > exported["plain"].materials[0].diffuse[1]
    assert plain.data is special.data


def test_curves_text_and_surfaces_are_exported_as_their_evaluated_meshes(scene):
    bevelled = bpy.data.curves.new("tube", 'CURVE')
    spline = bevelled.splines.new('POLY')
    spline.points.add(1)
    spline.points[1].co = (2.0, 0.0, 0.0, 1.0)
    bevelled.bevel_depth = 0.2
    add_mesh("tube", bevelled)
    thin = bevelled.copy()
    thin.bevel_depth = 0.0  # a bare curve: no faces, nothing rendered in Blender either
    add_mesh("wire", thin, (0.0, 0.0, 2.0))
    text = bpy.data.curves.new("text", 'FONT')
    text.body = "Glint"
    add_mesh("label", text, (0.0, 0.0, -2.0))

    exported, warnings = export()

    meshes = {m.name: m for m in exported.meshes}
    assert sorted(meshes) == ["label", "tube"]
    graph = depsgraph()
    for name, mesh in meshes.items():
        evaluated = bpy.data.objects[name].evaluated_get(graph)
        triangles = evaluated.to_mesh().loop_triangles
        # Zero-area triangles (a font's outline has a few) are left out: nothing hits them.
        drawn = [tuple(t.vertices) for t in triangles if t.area > 0]
        evaluated.to_mesh_clear()
        assert len(drawn) > 0
        np.testing.assert_array_equal(mesh.triangles, drawn)
    assert not [w for w in warnings if "skipped" in w]


def test_modifiers_give_the_evaluated_triangles(scene):
    cube = add_mesh("rounded", cube_mesh("rounded"))
    cube.modifiers.new("subdivide", 'SUBSURF').levels = 2

    (exported,) = export()[0].meshes

    # Two Catmull-Clark levels split each of the 6 quads into 16: 96 quads, 192 triangles.
    assert len(exported.triangles) == 192
    assert len(cube.data.polygons) == 6  # the original is untouched


# --- sphere or triangles ----------------------------------------------------------------------

def sphere_in_frame(name, mesh, fraction):
    """The mesh placed straight ahead of the default camera (at y = -6, 50 mm lens, 36 mm
    sensor) at the distance where its diameter covers ``fraction`` of the image width."""
    obj = add_mesh(name, mesh)
    radius = max(v.co.length for v in mesh.vertices)
    # The view is 36 / 50 units wide at unit distance.
    distance = 2.0 * radius / (fraction * 36.0 / 50.0)
    obj.location = (0.0, distance - 6.0, 0.0)
    return obj


@pytest.mark.parametrize("name, mesh, width", [
    ("icosahedron", lambda: ico_sphere_mesh("icosahedron", 1.0, 1), 64),  # 12 vertices
    ("8-segment UV sphere", lambda: uv_sphere_mesh("uv8", 1.0, 8, 4), 64),
    # 0.0024 r off its sphere: 0.06 px at 51 px across, 2 px at 1536 px across.
    ("64x32 UV sphere filling a 1920 px frame", lambda: uv_sphere_mesh("uv64", 1.0, 64, 32),
     1920),
])
def test_coarse_spheres_large_in_frame_are_drawn_as_triangles(scene, name, mesh, width):
    scene.render.resolution_x = width
    sphere_in_frame(name, mesh(), 0.8)

    exported, _ = export()

    assert not exported.spheres and [m.name for m in exported.meshes] == [name]


@pytest.mark.parametrize("name, mesh, fraction", [
    ("64x32 UV sphere", lambda: uv_sphere_mesh("uv64", 1.0, 64, 32), 0.3),
    ("icosahedron far away", lambda: ico_sphere_mesh("far", 1.0, 1), 0.01),
])
def test_spheres_whose_facets_are_under_a_pixel_fraction_stay_analytic(scene, name, mesh,
                                                                       fraction):
    sphere_in_frame(name, mesh(), fraction)

    exported, _ = export()

    assert [s.name for s in exported.spheres] == [name] and not exported.meshes


def test_a_subdivided_uv_sphere_is_a_sphere_small_and_triangles_large(scene):
    mesh = uv_sphere_mesh("subdivided", 1.0, 16, 8)
    obj = sphere_in_frame("subdivided", mesh, 0.1)
    obj.modifiers.new("subdivide", 'SUBSURF').levels = 2
    fit = mesh_sphere(obj.evaluated_get(depsgraph()).data)
    # Catmull-Clark pulls the vertices inwards unevenly: about 2 % of the radius here.
    assert 0.005 < fit.deviation / fit.radius < 0.05

    # 6.4 px across: deviation 0.02 * 3.2 px = 0.07 px.
    assert [s.name for s in export()[0].spheres] == ["subdivided"]
    # Filling 90 % of the frame it deviates by 0.02 * 29 px = 0.6 px: the triangles show it.
    obj.location.y = 2.0 * fit.radius / (0.9 * 36.0 / 50.0) - 6.0
    exported, _ = export()
    assert not exported.spheres and [m.name for m in exported.meshes] == ["subdivided"]


def test_flat_facets_larger_than_the_pixel_fraction_make_triangles(scene):
    smooth = sphere_in_frame("smooth", uv_sphere_mesh("smooth", 1.0, 64, 32), 0.3)
    flat = sphere_in_frame("flat", uv_sphere_mesh("flat", 1.0, 64, 32, smooth=False), 0.3)
    flat.location.x = 2.0

    exported, _ = export()

    # 19 px across: the silhouette strays 0.0024 r = 0.02 px, but a flat facet's edge is
    # 2 pi r / 64 = 0.1 r = 0.9 px.
    assert [s.name for s in exported.spheres] == ["smooth"]
    assert [m.name for m in exported.meshes] == ["flat"]
    assert smooth.data.polygons[0].use_smooth and not flat.data.polygons[0].use_smooth


def test_the_threshold_is_a_fraction_of_a_pixel():
    assert 0.0 < MAX_DEVIATION_PIXELS < 1.0


@pytest.mark.parametrize("ortho", [False, True])
def test_pixel_size_is_the_spacing_of_neighbouring_camera_rays(ortho):
    empty_file()
    camera = add_camera(location=(1.0, -7.0, 2.0), rotation=(1.3, 0.2, 0.4), lens=35.0)
    if ortho:
        camera.data.type = 'ORTHO'
        camera.data.ortho_scale = 4.0
    cam = export()[0].camera
    footprint = CameraFootprint.of(cam)

    rays = camera_rays(cam, np.array([20.5, 21.5]), np.array([30.5, 30.5]))
    origins = np.broadcast_to(rays.origins, rays.directions.shape)
    view_axis = -np.array(camera.matrix_world)[:3, 2]
    depth = 9.0
    # Points at depth 9 along both rays, one pixel apart.
    along = depth / (rays.directions.T @ view_axis)
    points = origins.T + rays.directions.T * along[:, None] if not ortho else \
        origins.T + rays.directions.T * depth
    spacing = np.linalg.norm(points[1] - points[0])
    center = points.mean(axis=0)
    assert footprint.pixel_size(center[None], np.array([0.0]))[0] == pytest.approx(spacing,
                                                                                   rel=1e-6)
    # A sphere's nearest visible depth counts: radius 3 at depth 9 is seen from depth 6.
    if not ortho:
        size = footprint.pixel_size(center[None], np.array([3.0]))[0]
        assert size == pytest.approx(spacing * 6.0 / 9.0, rel=1e-6)


# --- point clouds -----------------------------------------------------------------------------

def geometry_nodes(obj, build):
    """Give obj a Geometry Nodes modifier whose tree ``build(tree, input, output)`` wires."""
    tree = bpy.data.node_groups.new(f"{obj.name} nodes", 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    group_in = tree.nodes.new("NodeGroupInput")
    group_out = tree.nodes.new("NodeGroupOutput")
    build(tree, group_in.outputs[0], group_out.inputs[0])
    obj.modifiers.new("nodes", 'NODES').node_group = tree
    return tree


def points_object(name, positions, radius, location=(0.0, 0.0, 0.0), material=None):
    """A mesh of loose vertices turned into a point cloud by Mesh to Points (which, as in
    Blender, carries no material unless a Set Material node gives it one)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in positions], [], [])
    obj = add_mesh(name, mesh, location)

    def build(tree, geometry_in, geometry_out):
        to_points = tree.nodes.new("GeometryNodeMeshToPoints")
        to_points.inputs["Radius"].default_value = radius
        tree.links.new(geometry_in, to_points.inputs["Mesh"])
        output = to_points.outputs[0]
        if material is not None:
            paint = tree.nodes.new("GeometryNodeSetMaterial")
            paint.inputs["Material"].default_value = material
            tree.links.new(output, paint.inputs["Geometry"])
            output = paint.outputs[0]
        tree.links.new(output, geometry_out)

    geometry_nodes(obj, build)
    return obj


def test_geometry_nodes_points_become_one_sphere_set_in_world_space(scene):
    positions = np.array([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.5)])
    obj = points_object("dust", positions, 0.25, (2.0, 1.0, 0.0),
                        material=coloured("dust", (0.1, 0.2, 0.7)))
    obj.rotation_euler = (0.0, 0.0, math.pi / 2)
    obj.scale = (2.0, 2.0, 2.0)

    exported, warnings = export()

    (cloud,) = exported.sphere_sets
    assert cloud.name == "dust" and not exported.meshes and not exported.spheres
    world = np.array(obj.matrix_world)
    expected = positions @ world[:3, :3].T + world[:3, 3]
    np.testing.assert_allclose(cloud.centers, expected, atol=1e-6)
    np.testing.assert_allclose(cloud.radii, 0.5, rtol=1e-6)
    assert cloud.materials[0].diffuse[2] > cloud.materials[0].diffuse[0]
    assert not [w for w in warnings if "skipped" in w]


def test_a_non_uniformly_scaled_point_cloud_is_skipped_with_its_reason(scene):
    points_object("squashed", [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], 0.1).scale = (1.0, 1.0, 3.0)

    exported, warnings = export()

    assert not exported.sphere_sets
    (skipped,) = [w for w in warnings if "skipped" in w]
    assert "squashed (non-uniformly scaled point cloud" in skipped


@pytest.mark.parametrize("positions, radius, left_out, words", [
    ([(0.0, 0.0, 0.0), (float("nan"), 0.0, 0.0), (1.0, 0.0, 0.0)], 0.1, 1,
     "sphere set 'dust': 1 of 3 spheres draw nothing, as in Cycles (centers[1] is [nan"),
    ([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], -0.2, 2,
     "sphere set 'dust': 2 of 2 spheres draw nothing, as in Cycles (radii[0] is 0.0)"),
])
def test_points_that_draw_nothing_in_cycles_are_left_out_with_one_warning(scene, positions,
                                                                          radius, left_out,
                                                                          words):
    """Measured in Cycles: a NaN point is missing from the render, points of radius -0.2
    (which Mesh to Points stores as 0) draw nothing."""
    points_object("dust", positions, radius)

    with warnings.catch_warnings():
        warnings.simplefilter("error")   # no NumPy warning on the way
        exported, notes = export()

    (cloud,) = exported.sphere_sets
    assert len(cloud) == len(positions) - left_out and np.isfinite(cloud.centers).all()
    (line,) = [note for note in notes if "dust" in note]
    assert line.startswith(words)


def test_a_mesh_instance_whose_matrix_is_not_finite_is_skipped_with_its_reason(scene):
    add_mesh("lost", cube_mesh("lost")).location = (float("nan"), 0.0, 0.0)

    exported, notes = export()

    assert not exported.meshes and not exported.spheres
    (skipped,) = [note for note in notes if "skipped" in note]
    assert "lost (matrix not finite: draws nothing, as in Cycles)" in skipped


# --- instances --------------------------------------------------------------------------------

def instancer(name, positions, instance_mesh):
    """A mesh of loose vertices with Geometry Nodes instancing ``instance_mesh`` (through an
    Object Info node on an object holding it) on each vertex."""
    source = bpy.data.objects.new(f"{name} source", instance_mesh)  # not linked to the scene
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in positions], [], [])
    obj = add_mesh(name, mesh)

    def build(tree, geometry_in, geometry_out):
        info = tree.nodes.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = source
        place = tree.nodes.new("GeometryNodeInstanceOnPoints")
        rotate = tree.nodes.new("FunctionNodeRandomValue")
        rotate.data_type = 'FLOAT_VECTOR'
        rotate.inputs["Max"].default_value = (3.0, 3.0, 3.0)
        tree.links.new(geometry_in, place.inputs["Points"])
        tree.links.new(info.outputs["Geometry"], place.inputs["Instance"])
        tree.links.new(rotate.outputs["Value"], place.inputs["Rotation"])
        tree.links.new(place.outputs[0], geometry_out)

    geometry_nodes(obj, build)
    return obj


def grid_positions(count, spacing=0.6):
    side = int(math.ceil(count ** (1 / 3)))
    index = np.arange(count)
    return np.stack([index % side, (index // side) % side, index // side ** 2], axis=1) * \
        spacing - spacing * (side - 1) / 2


def export_per_instance(monkeypatch):
    """The export with the bulk path switched off: every instance through the walk."""
    with monkeypatch.context() as patch:
        patch.setattr(instances_module.InstanceExporter, "_read_source",
                      staticmethod(lambda parent: None))
        return export()


def test_geometry_nodes_sphere_instances_become_one_sphere_set_read_in_bulk(scene,
                                                                            monkeypatch):
    positions = grid_positions(27)
    instancer("crowd", positions, uv_sphere_mesh("ball", 0.1, 64, 32))

    exported, warnings = export()

    (spheres,) = exported.sphere_sets
    assert len(spheres) == 27 and not exported.meshes and not exported.spheres
    np.testing.assert_allclose(np.sort(spheres.centers, axis=0), np.sort(positions, axis=0),
                               atol=1e-6)
    np.testing.assert_allclose(spheres.radii, 0.1, rtol=1e-5)
    # The depsgraph's own instance matrices give the same spheres.
    (walked,) = export_per_instance(monkeypatch)[0].sphere_sets
    np.testing.assert_allclose(np.sort(walked.centers, axis=0),
                               np.sort(spheres.centers, axis=0), atol=1e-6)


def test_geometry_nodes_mesh_instances_share_one_triangle_mesh(scene, monkeypatch):
    instancer("boxes", grid_positions(8, 3.0), cube_mesh("box", 0.5))

    (boxes,) = export()[0].meshes
    (walked,) = export_per_instance(monkeypatch)[0].meshes

    assert boxes.transforms.shape == (8, 4, 4) and len(boxes.triangles) == 12
    key = lambda transforms: sorted(t.ravel().round(5).tolist() for t in transforms)  # noqa
    np.testing.assert_allclose(key(boxes.transforms), key(walked.transforms), atol=1e-5)


def two_mesh_instancer(name, positions):
    """Geometry Nodes instancing a fine UV sphere on even vertices and a cube on odd ones
    (Pick Instance of a Geometry to Instance of both)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in positions], [], [])
    obj = add_mesh(name, mesh)

    def build(tree, geometry_in, geometry_out):
        nodes, links = tree.nodes, tree.links
        sphere = nodes.new("GeometryNodeMeshUVSphere")
        sphere.inputs["Segments"].default_value, sphere.inputs["Rings"].default_value = 64, 32
        sphere.inputs["Radius"].default_value = 0.1
        smooth = nodes.new("GeometryNodeSetShadeSmooth")
        links.new(sphere.outputs[0], smooth.inputs[0])
        cube = nodes.new("GeometryNodeMeshCube")
        cube.inputs["Size"].default_value = (0.2, 0.2, 0.2)
        both = nodes.new("GeometryNodeGeometryToInstance")
        links.new(cube.outputs[0], both.inputs[0])  # a multi-input socket: last linked first
        links.new(smooth.outputs[0], both.inputs[0])
        parity = nodes.new("ShaderNodeMath")
        parity.operation = 'MODULO'
        parity.inputs[1].default_value = 2.0
        links.new(nodes.new("GeometryNodeInputIndex").outputs[0], parity.inputs[0])
        place = nodes.new("GeometryNodeInstanceOnPoints")
        place.inputs["Pick Instance"].default_value = True
        links.new(geometry_in, place.inputs["Points"])
        links.new(both.outputs[0], place.inputs["Instance"])
        links.new(parity.outputs[0], place.inputs["Instance Index"])
        links.new(place.outputs[0], geometry_out)

    geometry_nodes(obj, build)
    return obj


def test_walked_instances_equal_the_full_path_taken_for_every_instance(scene, monkeypatch):
    # InstanceWalk works out how to export each (instancer, object, mesh) once and reuses
    # it; the reference takes the full path (visibility, type, MeshUse) for every instance.
    # Two meshes instanced through one temporary object (Geometry Nodes), vertex instances.
    positions = grid_positions(12, 1.0)
    two_mesh_instancer("mixed", positions)
    placement = bpy.data.meshes.new("placement")
    placement.from_pydata([tuple(p + 5.0) for p in grid_positions(5)], [], [])
    parent = add_mesh("placement", placement)
    parent.instance_type = 'VERTS'
    add_mesh("ball", uv_sphere_mesh("ball", 0.1, 64, 32)).parent = parent

    walked, _ = export_per_instance(monkeypatch)
    with monkeypatch.context() as patch:
        patch.setattr(instances_module.InstanceWalk, "_plan",
                      lambda self, instance, obj: self.WHOLE)
        reference, _ = export_per_instance(monkeypatch)

    def shapes(exported):
        return (sorted((len(s), tuple(np.sort(s.centers, axis=0).ravel().round(5)))
                       for s in exported.sphere_sets),
                sorted((m.name, len(m.triangles), tuple(np.sort(
                    m.transforms.reshape(len(m.transforms), -1), axis=0).ravel().round(5)))
                       for m in exported.meshes),
                sorted(s.name for s in exported.spheres))

    assert shapes(walked) == shapes(reference)
    # Six spheres and six cubes from the instancer (not all of them the first mesh it
    # met), five vertex instances; the instanced original ball is not drawn.
    assert sorted(len(s) for s in walked.sphere_sets) == [5, 6]
    (cubes,) = walked.meshes
    assert len(cubes.transforms) == 6 and len(cubes.triangles) == 12
    assert not walked.spheres


def test_particles_instancing_a_sphere_become_a_sphere_set(scene):
    emitter = add_mesh("emitter", cube_mesh("emitter", 2.0))
    ball = bpy.data.objects.new("grain", uv_sphere_mesh("grain", 0.05, 64, 32))
    bpy.context.scene.collection.objects.link(ball)
    ball.location = (100.0, 0.0, 0.0)
    emitter.modifiers.new("particles", 'PARTICLE_SYSTEM')
    settings = emitter.particle_systems[0].settings
    settings.count = 40
    settings.frame_start = settings.frame_end = 1
    settings.render_type = 'OBJECT'
    settings.instance_object = ball
    settings.particle_size = 1.0
    settings.physics_type = 'NO'
    emitter.show_instancer_for_render = False

    exported, _ = export()

    (grains,) = exported.sphere_sets
    assert len(grains) == 40
    # Emitted from the cube's surface: every centre lies on the 2 x 2 x 2 cube.
    assert np.allclose(np.abs(grains.centers).max(axis=1), 1.0, atol=1e-4)
    np.testing.assert_allclose(grains.radii, 0.05, rtol=1e-4)
    assert [s.name for s in exported.spheres] == ["grain"]  # the object itself, far away
    assert not exported.meshes  # the emitter is not rendered (show_instancer_for_render)


def f12_scene():
    """The scene Glint's render engine exports on F12 (a render depsgraph, not the
    viewport's one ``export`` reads)."""
    from glint.addon.engine.final import FrameRequest, requesting_frames

    bpy.context.scene.render.engine = 'GLINT'
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = 32, 18
    with requesting_frames(FrameRequest(fill_render_result=False)) as request:
        bpy.ops.render.render()
    ((job, _),) = request.frames
    return job.scene


def test_f12_draws_the_instances_of_an_instancer_not_rendered_itself(scene):
    # A render depsgraph leaves a vertex instancer whose show_instancer_for_render is off out
    # of depsgraph.objects, but yields its instances: they must be walked, not missed.
    placement = bpy.data.meshes.new("placement")
    placement.from_pydata([tuple(p) for p in grid_positions(8)], [], [])
    parent = add_mesh("placement", placement)
    parent.instance_type = 'VERTS'
    parent.show_instancer_for_render = False
    add_mesh("ball", uv_sphere_mesh("ball", 0.1, 64, 32)).parent = parent

    (balls,) = f12_scene().sphere_sets
    button, _ = export()  # the viewport's depsgraph, as the Render button exports

    assert len(balls) == 8
    np.testing.assert_allclose(np.sort(balls.centers, axis=0),
                               np.sort(grid_positions(8), axis=0), atol=1e-6)
    # The viewport shows the instanced original too; renders (and the button) do not.
    assert [len(s) for s in button.sphere_sets] == [8] and not button.spheres


def test_many_objects_sharing_a_sphere_mesh_become_one_set_of_the_same_spheres(scene,
                                                                                monkeypatch):
    from glint.addon.export import meshes as meshes_module

    ball = uv_sphere_mesh("ball", 0.1, 64, 32)
    places = [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.2)]
    for index, place in enumerate(places):
        add_mesh(f"copy {index}", ball, place)

    named, _ = export()
    monkeypatch.setattr(meshes_module, "MAX_NAMED_SPHERES", 2)
    grouped, _ = export()

    assert sorted(s.name for s in named.spheres) == ["copy 0", "copy 1", "copy 2"]
    assert not named.sphere_sets
    (spheres,) = grouped.sphere_sets
    assert not grouped.spheres and spheres.name == "copy 0 (3 instances)"
    np.testing.assert_allclose(np.sort(spheres.centers, axis=0),
                               np.sort([s.center for s in named.spheres], axis=0), atol=1e-7)
    np.testing.assert_allclose(spheres.radii, [s.radius for s in named.spheres])


def test_instances_of_a_hidden_instancer_are_not_exported(scene):
    instancer("hidden crowd", grid_positions(8), uv_sphere_mesh("ball", 0.1, 64, 32)) \
        .hide_render = True

    exported, warnings = export()

    assert not exported.sphere_sets and not exported.meshes


def test_read_mesh_block_helpers_give_the_whole_array_values():
    """read_mesh works per block of BLOCK_ROWS triangles (its temporaries stay small):
    the area test, the normals' gather and the flat normals where Blender left a corner's zero
    give the same bits as the whole-array formulas."""
    from glint.addon.export import meshes as meshes_module
    from glint.core.validation import BLOCK_ROWS

    rng = np.random.default_rng(9)
    count = 2 * BLOCK_ROWS + 3
    vertices = rng.normal(size=(500, 3))
    triangles = rng.integers(0, 500, (count, 3))
    degenerate = [5, BLOCK_ROWS + 1, count - 1]
    triangles[degenerate, 2] = triangles[degenerate, 0]                  # zero area
    corners = vertices[triangles]
    area = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    keep = meshes_module._nonzero_area(vertices, triangles)
    assert np.array_equal(keep, area.any(axis=1)) and not keep[degenerate].any()

    stored = rng.normal(size=(3 * count, 3)).astype(np.float32)
    stored[[7, 40_000, 3 * count - 2]] = 0.0                              # left zero
    loops = rng.permutation(3 * count).reshape(count, 3)
    gathered = meshes_module._gathered(stored, loops, np.float64)
    assert gathered.dtype == np.float64 and np.array_equal(gathered, stored[loops])

    expected = stored[loops].astype(np.float64)
    zero = ~expected.any(axis=2)
    expected[zero] = np.repeat(area[:, None, :], 3, axis=1)[zero]
    flat = meshes_module._flat_where_zero(gathered, vertices, triangles)
    assert zero.sum() == 3 and np.array_equal(flat, expected)
