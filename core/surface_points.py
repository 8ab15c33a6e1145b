"""The shading points of hits: what a material's program reads of them
(``core.shader.points.ShadingPoints``), made lazily from the hits and the scene's tables.

A triangle hit knows its mesh, instance and triangle by its global id (meshes in order,
each instance by instance, triangle by triangle: ``core.arrays``), so no per-triangle table
is built: object coordinates come from the instance's inverse transform, Generated ones from
the mesh's bounding box in object space (Cycles' default for meshes), UVs from the mesh's
corner UVs and the hit's barycentrics.  A sphere's object space is its centre with world
axes (analytic spheres keep no rotation), its UVs those of Blender's UV sphere.  The world's
axes and location of each hit's object go to the nodes that read them
(``object_axis_x``..., ``object_location``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .shader.input_nodes import (ATTRIBUTE_ALPHA_PREFIX, ATTRIBUTE_PREFIX, RENDER_COLOR,
                                 RENDER_COLOR_ALPHA)
from .shader.points import ShadingPoints
from .shader.program import run
from .shader.world import light_path_sources
from .vectors import take


@dataclass(frozen=True)
class SurfaceTables:
    """Per mesh of the scene (canonical frame): the first global primitive id of its
    triangles, its triangles and instances, each instance's object-to-canonical (K, 3, 4)
    and inverse, its object-space bounding box (low, size), its UV maps ((name, (T, 3, 2))
    ...).  Spheres: the sphere count, and ``world_scale`` (scene units per canonical
    unit, for sphere object coordinates)."""

    sphere_count: int
    starts: np.ndarray
    triangle_counts: np.ndarray
    transforms: tuple
    inverses: tuple
    boxes: tuple
    uv_maps: tuple
    world_scale: float
    meshes: tuple = ()
    tangent_maps: tuple = ()
    attributes: tuple = ()
    world_centre: np.ndarray = field(default_factory=lambda: np.zeros(3))
    camera: object = None

    def to_world(self, points) -> np.ndarray:
        """Canonical points (3, k) in the scene's own units (``core.frame``)."""
        return points * self.world_scale + self.world_centre[:, None]

    @classmethod
    def of(cls, scene, frame=None) -> "SurfaceTables":
        """The tables of a canonical scene; frame: the ``core.frame.Frame`` that made it."""
        world_scale = 1.0 if frame is None else 1.0 / frame.scale
        centre = np.zeros(3) if frame is None else np.asarray(frame.centre, np.float64)
        counts = np.array([len(mesh.triangles) for mesh in scene.meshes], np.int64)
        instances = np.array([len(mesh.transforms) for mesh in scene.meshes], np.int64)
        starts = scene.sphere_count + np.concatenate([[0], np.cumsum(counts * instances)[:-1]])
        transforms, inverses, boxes = [], [], []
        for mesh in scene.meshes:
            transforms.append(mesh.transforms[:, :3, :])
            inverses.append(np.linalg.inv(mesh.transforms)[:, :3, :])
            low = mesh.vertices.min(axis=0) if len(mesh.vertices) else np.zeros(3)
            high = mesh.vertices.max(axis=0) if len(mesh.vertices) else np.ones(3)
            # Blender's automatic texture space: the bounds, a flat side widened to 2 about
            # its centre (so a plane's Generated z is 0.5, as in Cycles).
            centre, half = (low + high) / 2, (high - low) / 2
            half = np.where(half > 0, half, 1.0)
            boxes.append((centre - half, 2 * half))
        return cls(scene.sphere_count, starts.astype(np.int64), counts, tuple(transforms),
                   tuple(inverses), tuple(boxes), tuple(mesh.uv_maps for mesh in scene.meshes),
                   float(world_scale), tuple(scene.meshes),
                   tuple(mesh.tangent_maps for mesh in scene.meshes),
                   tuple(mesh.attributes for mesh in scene.meshes), centre, scene.camera)


def _triangle_hits(tables: SurfaceTables, primitive):
    """For hits on primitives (k,): (mesh (k,) or -1 for spheres, instance (k,), local
    triangle (k,))."""
    mesh = np.searchsorted(tables.starts, primitive, side="right") - 1
    mesh = np.where(primitive >= tables.sphere_count, mesh, -1)
    local = primitive - tables.starts[np.maximum(mesh, 0)]
    count = tables.triangle_counts[np.maximum(mesh, 0)]
    count = np.where(count > 0, count, 1)
    return mesh, local // count, local % count


class _HitSources:
    """The lazily made coordinates of k hits (module docstring)."""

    def __init__(self, tables: SurfaceTables, geometry, primitive, points, barycentrics):
        self.tables = tables
        self.geometry = geometry
        self.primitive = primitive
        self.points = points
        self.barycentrics = barycentrics
        self.mesh, self.instance, self.local = _triangle_hits(tables, primitive)
        self._object = None

    def _groups(self):
        """(mesh index, rows of the hits on it) for every mesh hit."""
        for m in np.unique(self.mesh[self.mesh >= 0]):
            yield int(m), np.flatnonzero(self.mesh == m)

    def _spheres(self):
        return np.flatnonzero(self.mesh < 0)

    def object(self) -> np.ndarray:
        if self._object is None:
            dtype = self.points.dtype
            result = np.zeros_like(self.points)
            rows = self._spheres()
            if len(rows):
                spheres = self.geometry.spheres
                centre = spheres.centers[self.primitive[rows]].T.astype(dtype)
                result[:, rows] = (take(self.points, rows) - centre) * self.tables.world_scale
            for m, rows in self._groups():
                inverse = self.tables.inverses[m][self.instance[rows]]        # (k, 3, 4)
                p = take(self.points, rows).astype(np.float64)
                local = np.einsum("kij,jk->ik", inverse[:, :, :3], p) + inverse[:, :, 3].T
                result[:, rows] = local
            self._object = result
        return self._object

    def generated(self) -> np.ndarray:
        local = self.object()
        result = np.zeros_like(local)
        rows = self._spheres()
        if len(rows):
            radius = self.geometry.spheres.radii[self.primitive[rows]] * self.tables.world_scale
            result[:, rows] = take(local, rows) / (2 * radius) + 0.5
        for m, rows in self._groups():
            low, size = self.tables.boxes[m]
            result[:, rows] = (take(local, rows) - low[:, None]) / size[:, None]
        return result

    def uv(self, name: str | None = None) -> np.ndarray:
        local = self.object()
        result = np.zeros_like(local)
        rows = self._spheres()
        if len(rows):
            p = take(local, rows)
            radius = np.sqrt((p * p).sum(axis=0))
            result[0, rows] = np.arctan2(p[1], p[0]) / (2 * np.pi) + 0.5
            result[1, rows] = np.arcsin(np.clip(p[2] / np.where(radius > 0, radius, 1), -1,
                                                1)) / np.pi + 0.5
        for m, rows in self._groups():
            maps = dict(self.tables.uv_maps[m])
            if not maps:
                continue
            corners = maps.get(name) if name is not None else self.tables.uv_maps[m][0][1]
            if corners is None:
                continue
            triangle = corners[self.local[rows]]                               # (k, 3, 2)
            weights = np.stack([b[rows] for b in self.barycentrics], axis=1)   # (k, 3)
            result[:2, rows] = np.einsum("kc,kcu->uk", weights, triangle)
        return result

    def object_jacobian(self) -> np.ndarray:
        """(3, 3, k) d(object coordinates) / d(position) of each hit."""
        result = np.zeros((3, 3, len(self.primitive)), self.points.dtype)
        rows = self._spheres()
        if len(rows):
            result[:, :, rows] = np.eye(3)[:, :, None] * self.tables.world_scale
        for m, rows in self._groups():
            inverse = self.tables.inverses[m][self.instance[rows]][:, :, :3]   # (k, 3, 3)
            result[:, :, rows] = inverse.transpose(1, 2, 0)
        return result

    def generated_jacobian(self) -> np.ndarray:
        jacobian = self.object_jacobian().copy()
        rows = self._spheres()
        if len(rows):
            radius = self.geometry.spheres.radii[self.primitive[rows]] * self.tables.world_scale
            jacobian[:, :, rows] /= 2 * radius
        for m, rows in self._groups():
            _, size = self.tables.boxes[m]
            jacobian[:, :, rows] /= size[:, None, None]
        return jacobian

    def uv_jacobian(self, name: str | None = None) -> np.ndarray:
        """(3, 3, k) d(u, v, 0) / d(position): the UV map's gradients in each hit
        triangle's plane (object space, then to the world by the object's inverse)."""
        result = np.zeros((3, 3, len(self.primitive)), self.points.dtype)
        object_jacobian = self.object_jacobian()
        for m, rows in self._groups():
            maps = self.tables.uv_maps[m]
            if not maps:
                continue
            corners = dict(maps).get(name) if name is not None else maps[0][1]
            if corners is None:
                continue
            mesh = self.tables.meshes[m]
            triangle = mesh.triangles[self.local[rows]]                       # (k, 3)
            p = mesh.vertices[triangle]                                        # (k, 3, 3)
            e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
            uv = corners[self.local[rows]].astype(np.float64)                 # (k, 3, 2)
            d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
            a11, a12, a22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
            det = a11 * a22 - a12 * a12
            det = np.where(np.abs(det) > 0, det, 1)
            for axis in range(2):
                a = (d1[:, axis] * a22 - d2[:, axis] * a12) / det
                b = (d2[:, axis] * a11 - d1[:, axis] * a12) / det
                gradient = a[:, None] * e1 + b[:, None] * e2                  # (k, 3) object
                result[axis, :, rows] = np.einsum("kj,jik->ki", gradient,
                                                  object_jacobian[:, :, rows])
        return result

    def tangent(self, name: str | None, sign: bool) -> np.ndarray:
        """(3, k) the UV map's interpolated MikkTSpace tangent in world space (sign: its
        bitangent sign in the first row); zero where a hit's mesh has none."""
        result = np.zeros_like(self.points)
        for m, rows in self._groups():
            maps = self.tables.tangent_maps[m] if self.tables.tangent_maps else ()
            if not maps:
                continue
            corners = dict(maps).get(name) if name is not None else maps[0][1]
            if corners is None:
                continue
            weights = np.stack([b[rows] for b in self.barycentrics], axis=1)   # (k, 3)
            values = np.einsum("kc,kcj->jk", weights, corners[self.local[rows]])  # (4, k)
            if sign:
                result[0, rows] = np.where(values[3] < 0, -1.0, 1.0)
                continue
            linear = self.tables.transforms[m][self.instance[rows]][:, :, :3]   # (k, 3, 3)
            world = np.einsum("kij,jk->ik", linear, values[:3])
            # Unit length: the canonical frame scales every object (Cycles works on the
            # object-space tangent, which the mesh's own unit keeps near unit length).
            length = np.sqrt((world * world).sum(axis=0))
            result[:, rows] = world / np.where(length > 0, length, 1)
        return result

    def attribute(self, name: str, alpha: bool) -> np.ndarray:
        """(3, k) a mesh attribute interpolated at each hit (alpha: its alpha in the first
        row); zero (alpha 1) where a hit's mesh has none of that name, as in Cycles."""
        result = np.zeros_like(self.points)
        if alpha:
            result[0] = 1.0
        for m, rows in self._groups():
            corners = dict(self.tables.attributes[m]).get(name)
            if corners is None:
                continue
            weights = np.stack([b[rows] for b in self.barycentrics], axis=1)   # (k, 3)
            values = np.einsum("kc,kcj->jk", weights, corners[self.local[rows]])  # (4, k)
            if alpha:
                result[0, rows] = values[3]
            else:
                result[:, rows] = values[:3]
        return result

    def object_axis(self, axis: int) -> np.ndarray:
        """(3, k) the world-space image of each hit's object's local axis (scene units)."""
        result = np.zeros_like(self.points)
        rows = self._spheres()
        if len(rows):
            result[axis, rows] = 1.0
        for m, rows in self._groups():
            result[:, rows] = (self.tables.transforms[m][self.instance[rows]][:, :, axis].T
                               * self.tables.world_scale)
        return result

    def object_location(self) -> np.ndarray:
        """(3, k) each hit's object's location in the scene's own units."""
        result = np.zeros_like(self.points)
        rows = self._spheres()
        if len(rows):
            result[:, rows] = self.geometry.spheres.centers[self.primitive[rows]].T
        for m, rows in self._groups():
            result[:, rows] = self.tables.transforms[m][self.instance[rows]][:, :, 3].T
        return self.tables.to_world(result)


def surface_points(tables: SurfaceTables, geometry, points, normal, true_normal, incoming,
                   backfacing, primitive, barycentrics, footprint=None,
                   ray=None) -> ShadingPoints:
    """The ShadingPoints of k hits: points, shading and true normals (facing the ray) and
    incoming (towards the viewer) (3, k), backfacing (k,), primitive (k,) global ids,
    barycentrics (b0, b1, b2) (k,) each or None (no triangle hit); ray: the Light Path
    node's coordinates of the rays that found them (``core.shader.world.light_path_sources``)
    or None (camera rays)."""
    if barycentrics is None:
        zero = np.zeros(points.shape[1], points.dtype)
        barycentrics = (zero, zero, zero)
    hits = _HitSources(tables, geometry, primitive, points, barycentrics)
    sources = {"object": hits.object, "generated": hits.generated, "uv": hits.uv,
               "object_location": hits.object_location,
               "object_axis_x": lambda: hits.object_axis(0),
               "object_axis_y": lambda: hits.object_axis(1),
               "object_axis_z": lambda: hits.object_axis(2)}
    # Programs see the scene in its own units (Cycles' world): positions, footprints and
    # the coordinates' derivatives by them are taken out of the canonical frame.
    per_unit = 1.0 / tables.world_scale

    def by_world(jacobian):
        return lambda: jacobian() * per_unit

    jacobians = {"object": by_world(hits.object_jacobian),
                 "generated": by_world(hits.generated_jacobian),
                 "uv": by_world(hits.uv_jacobian)}
    sources["camera"] = lambda: camera_coordinates(tables, points)[0]
    sources["window"] = lambda: camera_coordinates(tables, points)[1]
    names = {name for maps in tables.uv_maps for name, _ in maps}
    for name in names:
        sources[f"uv:{name}"] = (lambda name=name: hits.uv(name))
        jacobians[f"uv:{name}"] = by_world(lambda name=name: hits.uv_jacobian(name))
    sources["tangent"] = lambda: hits.tangent(None, False)
    sources["tangent_sign"] = lambda: hits.tangent(None, True)
    for name in {name for maps in tables.tangent_maps for name, _ in maps}:
        sources[f"tangent:{name}"] = (lambda name=name: hits.tangent(name, False))
        sources[f"tangent:{name}_sign"] = (lambda name=name: hits.tangent(name, True))
    for name in {name for maps in tables.attributes for name, _ in maps}:
        value, alpha = ((RENDER_COLOR, RENDER_COLOR_ALPHA) if name == "" else
                        (ATTRIBUTE_PREFIX + name, ATTRIBUTE_ALPHA_PREFIX + name))
        sources[value] = (lambda name=name: hits.attribute(name, False))
        sources[alpha] = (lambda name=name: hits.attribute(name, True))
    sources.update(light_path_sources(ray))
    if footprint is not None:
        footprint = footprint * tables.world_scale
    return ShadingPoints(tables.to_world(points).astype(points.dtype), normal, true_normal,
                         incoming, backfacing, sources, jacobians, footprint)


def program_emission(program, tables: SurfaceTables, geometry, points, normal, incoming,
                     primitive, barycentrics, ray=None) -> np.ndarray:
    """(3, k) the emission of a material's ``program`` at k points (3, k) on triangles
    ``primitive`` (k,) at ``barycentrics`` (b0, b1, b2), of unit (geometric) normal (3, k),
    seen from unit ``incoming`` (3, k); ray: as for ``surface_points``.  Emitters shine on
    both sides, as in Cycles: the back side sees its normal turned towards it."""
    backfacing = (normal * incoming).sum(axis=0) < 0
    facing_normal = np.where(backfacing, -normal, normal)
    found = surface_points(tables, geometry, points, facing_normal, facing_normal, incoming,
                           backfacing, primitive, barycentrics, None, ray)
    return run(program, found).closures(points.shape[1], points.dtype,
                                        facing_normal).emission


def camera_coordinates(tables: SurfaceTables, points):
    """((3, k) Cycles' Camera coordinates (camera space: x right, y up, z along the view,
    scene units), (3, k) its Window coordinates ([0, 1] over the frame, z 0)) of canonical
    points."""
    from .camera import BlenderCamera, blender_view_plane, camera_to_world
    camera = tables.camera
    result = np.zeros_like(points)
    window = np.zeros_like(points)
    if not isinstance(camera, BlenderCamera):
        return result, window
    rotation, translation = camera_to_world(camera)
    local = rotation.T @ (points - translation[:, None])
    result[0], result[1], result[2] = local[0], local[1], -local[2]
    result *= tables.world_scale
    plane = blender_view_plane(camera)
    if camera.projection == "ORTHO":
        u, v = local[0], local[1]
    else:
        depth = np.where(np.abs(local[2]) > 0, -local[2], 1e-30)
        u, v = local[0] / depth, local[1] / depth
    window[0] = (u - plane.offset_x) / (2 * plane.half_width) + 0.5
    window[1] = (v - plane.offset_y) / (2 * plane.half_height) + 0.5
    return result, window
