"""Scenes rendered three ways for the silhouette tests: by Workbench, by Cycles, and by Glint
through the add-on's exporter.

A UV sphere is a convex polyhedron: it contains the ball of its *inscribed* radius (the
smallest distance from its centre to a face plane) and lies inside the ball of its
*circumscribed* radius (its vertices').  Any point-sampled mask of the mesh therefore agrees
with the masks of both balls wherever those two agree; clip planes keep that true, since the
mesh's first and last crossings of a ray lie between the two balls' (``silhouette_check``).
So Glint's analytic mask may differ from Blender's only in the band where Glint's own renders
of the inscribed and the circumscribed spheres differ.  The band is computed from the very
exported scene under test, so an exporter or camera bug moves the band with the mask and
shows up as mismatches outside it.

Triangle meshes are drawn by both sides as the same triangles, so their masks must agree
except where a pixel centre lies within ``EDGE_TOLERANCE_PIXELS`` of a projected edge
(``near_edges``, computed from the exported triangles, clipped to the visible depths, and the
outlines the clip planes cut into them), where rounding may decide either way.

Blender's masks come from its own renderers at one sample per pixel centre (Workbench without
anti-aliasing, Cycles with 1 sample and a 0.01 px filter), written as RGBA PNGs and read back.
"""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass, field
from typing import Callable, Sequence

import bpy
import bmesh  # after bpy: the pip module makes bmesh importable
import numpy as np
from mathutils import Euler, Vector

from addon_support import core, depsgraph, empty_file, export_scene, link, uv_sphere_mesh
from glint.core.camera import blender_view_plane, camera_to_world

ENGINES = ("BLENDER_WORKBENCH", "CYCLES")

#: Glint's settings for masks: one path sample per pixel, through its centre (a box filter
#: 1e-4 px wide moves it by at most 5e-5 px, far inside EDGE_TOLERANCE_PIXELS), no bounces.
GLINT_SETTINGS = core.RenderSettings(semantics="default", precision="float64", samples=1,
                                     filter_type="BOX", filter_width=1e-4, max_bounces=0)


# --------------------------------------------------------------------------------------------
# Building scenes

@dataclass(frozen=True)
class CameraSetup:
    """The scene camera and the render settings that shape its view.

    location, target, roll: the camera sits at ``location`` and looks at ``target`` (local -Z
    towards it, local +Y up), then turns by ``roll`` radians about its view axis.
    ortho_scale: None for a perspective camera.
    """

    resolution: tuple[int, int] = (96, 64)
    percentage: int = 100
    pixel_aspect: tuple[float, float] = (1.0, 1.0)
    sensor_fit: str = "AUTO"
    sensor: tuple[float, float] = (36.0, 24.0)
    lens: float = 50.0
    ortho_scale: float | None = None
    shift: tuple[float, float] = (0.0, 0.0)
    clip: tuple[float, float] = (0.1, 100.0)
    location: tuple[float, float, float] = (1.0, -9.0, 1.5)
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    roll: float = 0.0


def look_at(location, target, roll=0.0) -> Euler:
    """Rotation of a camera at ``location`` looking at ``target``, +Y up, turned by ``roll``."""
    direction = Vector(target) - Vector(location)
    quaternion = direction.to_track_quat('-Z', 'Y')
    quaternion = quaternion @ Euler((0.0, 0.0, roll)).to_quaternion()
    return quaternion.to_euler()


def add_camera(setup: CameraSetup, scene):
    data = bpy.data.cameras.new("camera")
    data.lens = setup.lens
    data.sensor_width, data.sensor_height = setup.sensor
    data.sensor_fit = setup.sensor_fit
    data.shift_x, data.shift_y = setup.shift
    data.clip_start, data.clip_end = setup.clip
    if setup.ortho_scale is not None:
        data.type = 'ORTHO'
        data.ortho_scale = setup.ortho_scale
    camera = link(bpy.data.objects.new("camera", data), scene)
    camera.location = setup.location
    camera.rotation_euler = look_at(setup.location, setup.target, setup.roll)
    scene.camera = camera
    return camera


def configure_renderers(scene) -> None:
    """One sample at each pixel centre, transparent film, RGBA PNG output."""
    render = scene.render
    render.film_transparent = True
    render.image_settings.file_format = 'PNG'
    render.image_settings.color_mode = 'RGBA'
    render.image_settings.color_depth = '8'
    render.threads_mode = 'FIXED'
    render.threads = max(1, min(2, os.cpu_count() or 1))
    scene.display.render_aa = 'OFF'
    cycles = scene.cycles
    cycles.device = 'CPU'
    cycles.samples = 1
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.filter_width = 0.01
    cycles.max_bounces = 0


#: Builds a scene's objects, given the scene and its camera object (already placed).
ObjectsBuilder = Callable[[object, object], None]


def build_scene(setup: CameraSetup, *builders: ObjectsBuilder):
    """A fresh file whose scene has the camera of ``setup`` and the builders' objects."""
    scene = empty_file()
    render = scene.render
    render.resolution_x, render.resolution_y = setup.resolution
    render.resolution_percentage = setup.percentage
    render.pixel_aspect_x, render.pixel_aspect_y = setup.pixel_aspect
    configure_renderers(scene)
    camera = add_camera(setup, scene)
    bpy.context.view_layer.update()  # builders may read the camera's matrix_world
    for builder in builders:
        builder(scene, camera)
    return scene


def add_sphere(scene, name, location, radius=1.0, segments=32, rings=16, *,
               rotation=(0.0, 0.0, 0.0), scale=1.0, parent=None):
    obj = link(bpy.data.objects.new(name, uv_sphere_mesh(name, radius, segments, rings)), scene)
    obj.location = location
    obj.rotation_euler = rotation
    obj.scale = (scale, scale, scale)
    obj.parent = parent
    return obj


def in_camera_space(camera, local) -> tuple[float, float, float]:
    """World position of a point given in the camera's own coordinates (-Z ahead)."""
    return tuple(camera.matrix_world @ Vector(local))


# --------------------------------------------------------------------------------------------
# Object sets; each names its spheres after what they exercise.

def transformed_spheres(scene, camera) -> None:
    """Scaled, rotated and parented spheres of several tessellations, and one hidden for render
    in front of them all (Glint must leave it out, as Blender does)."""
    add_sphere(scene, "scaled", (-1.4, 0.0, 0.4), 0.5, 32, 16, scale=1.6)
    add_sphere(scene, "rotated", (0.9, 0.6, -0.5), 0.7, 24, 12, rotation=(0.4, 0.9, 0.3))
    add_sphere(scene, "fine", (0.1, 1.5, 0.9), 0.5, 128, 64)
    add_sphere(scene, "coarse", (2.4, -0.4, 0.8), 0.45, 12, 6, rotation=(1.1, 0.0, 0.7))
    parent = link(bpy.data.objects.new("parent", None), scene)
    parent.location = (0.3, -0.6, -0.9)
    parent.rotation_euler = (0.2, -0.5, 1.2)
    parent.scale = (0.5, 0.5, 0.5)
    add_sphere(scene, "child", (1.0, 0.4, 0.6), 1.0, 48, 24, rotation=(0.0, 0.7, 0.0),
               parent=parent)
    hidden = add_sphere(scene, "hidden", (-0.3, -2.5, 0.0), 0.8, 32, 16)
    hidden.hide_render = True


def instanced_spheres(scene, camera) -> None:
    """A collection of two spheres, not itself in the scene, instanced twice by empties."""
    collection = bpy.data.collections.new("cluster")
    for name, location, radius, segments in (("ball", (0.0, 0.0, 0.0), 0.6, 32),
                                             ("moon", (0.9, 0.2, 0.5), 0.3, 40)):
        obj = bpy.data.objects.new(name, uv_sphere_mesh(name, radius, segments, segments // 2))
        obj.location = location
        collection.objects.link(obj)
    for name, location, rotation, scale in (("cluster_a", (-1.2, 0.3, -0.2), (0, 0, 0), 1.0),
                                            ("cluster_b", (1.1, -0.5, 0.3), (0.5, 1.0, -0.8),
                                             0.7)):
        empty = link(bpy.data.objects.new(name, None), scene)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = collection
        empty.location = location
        empty.rotation_euler = rotation
        empty.scale = (scale, scale, scale)


def clipped_spheres(scene, camera) -> None:
    """Spheres cut by the camera's plane and by the clip planes (placed in camera coordinates,
    -Z ahead; x / -z and y / -z are the tangents of the directions they are seen in)."""
    near, far = camera.data.clip_start, camera.data.clip_end
    # Straddles the camera's plane at the right edge: its front part enters the view.
    add_sphere(scene, "behind_camera", in_camera_space(camera, (0.55, -0.1, -0.05)), 0.5,
               48, 24)
    # Wholly nearer than clip_start, or wholly beyond clip_end: never seen.
    add_sphere(scene, "before_clip_start",
               in_camera_space(camera, (-0.3 * near, 0.25 * near, -0.6 * near)), 0.2 * near,
               32, 16)
    add_sphere(scene, "beyond_clip_end",
               in_camera_space(camera, (-0.55 * (far + 1.0), -0.45 * (far + 1.0), -far - 1.0)),
               0.8, 32, 16)
    # The near plane keeps only this one's far cap, the far plane only the middle of that one.
    add_sphere(scene, "cut_by_clip_start",
               in_camera_space(camera, (0.12 * near, -0.18 * near, -0.8 * near)), 0.4 * near,
               40, 20)
    add_sphere(scene, "cut_by_clip_end",
               in_camera_space(camera, (-0.45 * far, 0.0, -far - 0.4)), 0.25 * far, 64, 32)
    add_sphere(scene, "ahead", in_camera_space(camera, (-0.1, -0.15, -0.5 * far)), 0.15 * far,
               32, 16)


def fine_spheres(scene, camera) -> None:
    """Three finely tessellated (128 x 64) spheres, one scaled and rotated."""
    add_sphere(scene, "fine_a", (-1.0, 0.0, 0.2), 0.9, 128, 64)
    add_sphere(scene, "fine_b", (1.2, 0.8, -0.3), 0.4, 128, 64, rotation=(0.3, 1.2, -0.4),
               scale=1.5)
    add_sphere(scene, "fine_c", (0.6, -1.2, 0.9), 0.35, 128, 64)


def _mesh_object(scene, name, mesh, location, rotation=(0.0, 0.0, 0.0), scale=(1, 1, 1)):
    obj = link(bpy.data.objects.new(name, mesh), scene)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    return obj


def _bmesh_mesh(name, build):
    mesh = bpy.data.meshes.new(name)
    builder = bmesh.new()
    build(builder)
    builder.to_mesh(mesh)
    builder.free()
    return mesh


def triangle_meshes(scene, camera) -> None:
    """A cube, a tilted plane, Suzanne, and a second Suzanne sharing her mesh, rotated and
    scaled non-uniformly (exported as one mesh with two transforms)."""
    cube = _bmesh_mesh("cube", lambda b: bmesh.ops.create_cube(b, size=1.2))
    _mesh_object(scene, "cube", cube, (-1.8, 0.5, 0.7), (0.3, 0.5, 0.2))
    plane = bpy.data.meshes.new("plane")
    plane.from_pydata([(-2, -1, 0), (2, -1, 0), (2, 1, 0), (-2, 1, 0)], [], [(0, 1, 2, 3)])
    _mesh_object(scene, "plane", plane, (0.0, 0.5, -1.4), (0.5, 0.0, 0.3))
    suzanne = _bmesh_mesh("suzanne", lambda b: bmesh.ops.create_monkey(b))
    _mesh_object(scene, "suzanne", suzanne, (0.6, 0.0, 0.3), (0.2, 0.0, 0.4))
    _mesh_object(scene, "squashed suzanne", suzanne, (2.4, 1.0, -0.3), (0.9, -0.4, 1.3),
                 (0.5, 0.9, 0.35))


def mesh_behind_camera(scene, camera) -> None:
    """A box straddling the camera's plane (its front part cut by clip_start enters the view)
    and a box in front, placed in camera coordinates (-Z ahead)."""
    box = _bmesh_mesh("box", lambda b: bmesh.ops.create_cube(b, size=1.0))
    _mesh_object(scene, "straddling", box, in_camera_space(camera, (0.6, -0.1, -0.2)),
                 tuple(a + b for a, b in zip(camera.rotation_euler, (0.2, 0.1, 0.3))),
                 (1.0, 0.8, 2.0))
    _mesh_object(scene, "ahead", box, in_camera_space(camera, (-0.6, 0.2, -4.0)),
                 (0.6, 0.4, 0.1))


# --------------------------------------------------------------------------------------------
# Blender's masks

def blender_mask(scene, engine: str, directory) -> np.ndarray:
    """(H, W) bool, row 0 = top: pixels whose alpha in ``engine``'s render exceeds 0.5."""
    scene.render.engine = engine
    path = os.path.join(str(directory), f"{engine.lower()}.png")
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path, check_existing=False)
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    # Blender's row 0 is the bottom; the core's is the top.
    return pixels.reshape(height, width, 4)[::-1, :, 3] > 0.5


# --------------------------------------------------------------------------------------------
# Glint's masks and the band

@dataclass(frozen=True)
class BandRadii:
    """A mesh sphere's inscribed and circumscribed radii as fractions of its vertex radius
    (the radius the exporter fits through the vertices)."""

    inscribed: float
    circumscribed: float


def band_radii(mesh) -> BandRadii:
    """From the mesh's own triangles: the smallest distance from the centre to a face plane,
    and the largest vertex distance, each over the mean vertex distance.  (The test scenes
    have no modifiers, so the original mesh is the one Blender renders.)"""
    vertices = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", vertices)
    vertices = vertices.reshape(-1, 3)
    mesh.calc_loop_triangles()
    triangles = np.empty(len(mesh.loop_triangles) * 3, np.int64)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    corners = vertices[triangles.reshape(-1, 3)]
    # A UV sphere is symmetric about its centre, so the box's middle is the centre.
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    plane_distances = np.abs(np.einsum("ij,ij->i", normals, corners[:, 0] - centre))
    vertex_distances = np.linalg.norm(vertices - centre, axis=1)
    mean = vertex_distances.mean()
    return BandRadii(plane_distances.min() / mean, vertex_distances.max() / mean)


_INSTANCED = re.compile(r"^(?P<object>.*?)( \(instanced by .*\))?( \(\d+ instances\))?$")


def source_object(sphere_name: str):
    """The object an exported sphere or sphere set came from: the exporter names a sphere
    after its object, and a set of instances 'object (instanced by parent) (N instances)'."""
    name = _INSTANCED.match(sphere_name).group("object")
    obj = bpy.data.objects.get(name)
    if obj is None or obj.type != 'MESH':
        raise LookupError(f"exported sphere {sphere_name!r}: no mesh object {name!r}")
    return obj


def with_radii(scene, sphere_factors: Sequence[float], set_factors: Sequence[float] = ()):
    """The core scene with sphere i's radius multiplied by sphere_factors[i] and sphere set
    j's radii by set_factors[j]."""
    spheres = tuple(dataclasses.replace(sphere, radius=sphere.radius * factor)
                    for sphere, factor in zip(scene.spheres, sphere_factors, strict=True))
    sets = tuple(dataclasses.replace(sphere_set, radii=sphere_set.radii * factor)
                 for sphere_set, factor in zip(scene.sphere_sets, set_factors, strict=True))
    return dataclasses.replace(scene, spheres=spheres, sphere_sets=sets)


def glint_mask(scene) -> np.ndarray:
    return core.render(scene, GLINT_SETTINGS).image[..., 3] > 0.5


#: Pixels whose centre lies this close to a projected triangle edge (in pixels) may go either
#: way: there Workbench's rasteriser (float32 vertex transform, its own tie rule) and Glint's
#: float64 ray test may round differently.  float32 rounding of positions of size ~10
#: projected at ~100 px per unit is ~1e-4 px; 1e-3 px is ten times that.
EDGE_TOLERANCE_PIXELS = 1e-3


def _clip_segments(a, b, plane_z, keep_below: bool):
    """Segments a -> b (n, 3) in camera space clipped to z <= plane_z (keep_below) or
    z >= plane_z; returns the clipped (a, b) and which survived."""
    za, zb = a[:, 2] - plane_z, b[:, 2] - plane_z
    if not keep_below:
        za, zb = -za, -zb
    inside_a, inside_b = za <= 0, zb <= 0
    alive = inside_a | inside_b
    crossing = inside_a != inside_b
    t = np.divide(za, za - zb, out=np.zeros_like(za), where=crossing)
    point = a + t[:, None] * (b - a)
    a = np.where((crossing & ~inside_a)[:, None], point, a)
    b = np.where((crossing & ~inside_b)[:, None], point, b)
    return a[alive], b[alive]


def _plane_cuts(corners, plane_z):
    """Where triangles (n, 3, 3) in camera space cross the plane z = plane_z: (m, 2, 3)
    segments (the outline a clip plane cuts into a mesh)."""
    side = corners[:, :, 2] - plane_z
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = corners[:, i], corners[:, j]
        crosses = (side[:, i] < 0) != (side[:, j] < 0)
        t = np.divide(side[:, i], side[:, i] - side[:, j], out=np.zeros(len(side)),
                      where=crosses)
        ends.append((crosses, a + t[:, None] * (b - a)))
    segments = []
    for (c0, p0), (c1, p1) in ((ends[0], ends[1]), (ends[1], ends[2]), (ends[2], ends[0])):
        both = c0 & c1
        segments.append(np.stack([p0[both], p1[both]], axis=1))
    return np.concatenate(segments)


def projected_edges(scene) -> np.ndarray:
    """(S, 2, 2) image positions (column, row from the top) of every triangle edge of the
    exported scene's meshes, and of the outlines the clip planes cut into them, clipped to
    the visible depth range."""
    camera = scene.camera
    plane = blender_view_plane(camera)
    rotation, translation = camera_to_world(camera)
    near, far = -camera.clip_start, -camera.clip_end
    segments = []
    for mesh in scene.meshes:
        for transform in mesh.transforms:
            world = mesh.vertices @ transform[:3, :3].T + transform[:3, 3]
            local = (world - translation) @ rotation  # camera space, -Z ahead
            corners = local[mesh.triangles]
            a = corners.reshape(-1, 3)
            b = corners[:, [1, 2, 0]].reshape(-1, 3)
            a, b = _clip_segments(a, b, near, keep_below=True)
            a, b = _clip_segments(a, b, far, keep_below=False)
            segments.append(np.stack([a, b], axis=1))
            for cut in (near, far):
                segments.append(_plane_cuts(corners, cut))
    if not segments:
        return np.zeros((0, 2, 2))
    points = np.concatenate(segments)  # (S, 2, 3)
    if camera.projection == "ORTHO":
        u, v = points[..., 0], points[..., 1]
    else:
        u, v = points[..., 0] / -points[..., 2], points[..., 1] / -points[..., 2]
    columns = ((u - plane.offset_x) / plane.half_width + 1.0) * camera.width / 2
    rows = camera.height - ((v - plane.offset_y) / plane.half_height + 1.0) * camera.height / 2
    return np.stack([columns, rows], axis=-1)


def near_edges(scene, tolerance: float = EDGE_TOLERANCE_PIXELS) -> np.ndarray:
    """(H, W) bool: pixels whose centre lies within ``tolerance`` pixels of a projected edge."""
    camera = scene.camera
    edges = projected_edges(scene)
    mask = np.zeros((camera.height, camera.width), bool)
    if not len(edges):
        return mask
    columns, rows = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    centres = np.stack([columns.ravel(), rows.ravel()], axis=1)
    start, along = edges[:, 0], edges[:, 1] - edges[:, 0]
    length_squared = np.maximum((along * along).sum(axis=1), 1e-300)
    for first in range(0, len(edges), 256):
        s, d = start[first:first + 256], along[first:first + 256]
        offset = centres[:, None, :] - s[None]
        t = np.clip((offset * d[None]).sum(axis=2) / length_squared[first:first + 256], 0, 1)
        gap = offset - t[..., None] * d[None]
        close = ((gap * gap).sum(axis=2) <= tolerance ** 2).any(axis=1)
        mask |= close.reshape(mask.shape)
    return mask


@dataclass
class GlintMasks:
    """Glint's mask of the exported scene, of the same scene with every sphere swapped for its
    mesh's inscribed and circumscribed spheres, and the pixels next to a triangle edge."""

    mask: np.ndarray
    inscribed: np.ndarray
    circumscribed: np.ndarray
    edges: np.ndarray

    @property
    def band(self) -> np.ndarray:
        return (self.inscribed != self.circumscribed) | self.edges


def glint_masks(scene) -> GlintMasks:
    sphere_radii = [band_radii(source_object(sphere.name).data) for sphere in scene.spheres]
    set_radii = [band_radii(source_object(s.name).data) for s in scene.sphere_sets]
    return GlintMasks(
        mask=glint_mask(scene),
        inscribed=glint_mask(with_radii(scene, [r.inscribed for r in sphere_radii],
                                        [r.inscribed for r in set_radii])),
        circumscribed=glint_mask(with_radii(scene, [r.circumscribed for r in sphere_radii],
                                            [r.circumscribed for r in set_radii])),
        edges=near_edges(scene))


def export_current_scene():
    """(core scene, warnings) of the current scene through the add-on's exporter."""
    return export_scene(depsgraph())


# --------------------------------------------------------------------------------------------
# Comparison

@dataclass
class SilhouetteCheck:
    """How Glint's mask compares with a reference mask of the meshes."""

    mismatches: int
    outside_band: int
    band_pixels: int
    iou: float
    outside_positions: list = field(default_factory=list)

    def describe(self) -> str:
        return (f"{self.mismatches} mismatched pixels, {self.outside_band} outside the "
                f"{self.band_pixels}-pixel band (first at (row, col) "
                f"{self.outside_positions[:8]}), IoU {self.iou:.5f}")


def silhouette_check(glint: GlintMasks, reference: np.ndarray) -> SilhouetteCheck:
    if glint.mask.shape != reference.shape:
        raise AssertionError(f"Glint's image is {glint.mask.shape[::-1]} (W, H), Blender's "
                             f"{reference.shape[::-1]}")
    mismatched = glint.mask != reference
    outside = mismatched & ~glint.band
    union = np.count_nonzero(glint.mask | reference)
    iou = np.count_nonzero(glint.mask & reference) / union if union else 1.0
    return SilhouetteCheck(int(mismatched.sum()), int(outside.sum()), int(glint.band.sum()),
                           iou, [tuple(map(int, p)) for p in np.argwhere(outside)])


def shifted_by_pixels(scene, dx: float = 0.0, dy: float = 0.0):
    """The core scene with its camera's lens shift moved by (dx, dy) pixels (dy up)."""
    camera = scene.camera
    plane = blender_view_plane(camera)
    # Shift is in units of the fitted view size; one unit of shift moves the plane by it.
    size = blender_view_plane(
        dataclasses.replace(camera, shift_x=camera.shift_x + 1.0)).offset_x - plane.offset_x
    pixel_w = 2 * plane.half_width / camera.width
    pixel_h = 2 * plane.half_height / camera.height
    moved = dataclasses.replace(camera, shift_x=camera.shift_x + dx * pixel_w / size,
                                shift_y=camera.shift_y + dy * pixel_h / size)
    return dataclasses.replace(scene, camera=moved)

