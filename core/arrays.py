"""The scene as structure-of-arrays, the form the tracer works on.

Built once per render from a validated ``Scene``, in whole-array operations (no Python loop
per primitive for sphere sets and meshes); every array is float64 (the render casts what it
needs to its precision).

Primitive ids are global: the N spheres first (``Scene.spheres`` in order, then each
``SphereSet`` in order), then the T triangles (each mesh's triangles, instance by instance).
Ties between equally near hits go to the lower id.  Materials form one table for the scene;
every primitive carries an index into it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .light_sources import PointLight
from .scene import Scene


@dataclass(frozen=True)
class SphereArrays:
    """centers (N, 3), radii (N,), material (N,) indices into the scene's material table."""

    centers: np.ndarray
    radii: np.ndarray
    material: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class TriangleArrays:
    """T world-space triangles: corners v0, v1, v2 (3, T); normals (3, T) unit geometric
    normals on the front side (counter-clockwise winding, kept outward for mirrored
    instances); corner_normals (3 corners, 3, T) unit shading normals, or None when every
    triangle is flat; material (T,) indices into the scene's material table; surface (T,)
    which continuous surface each triangle belongs to (``_surfaces``), so that adaptive
    anti-aliasing finds the edges a picture shows, not every edge of the tessellation;
    terminator_offset (T,) the shadow terminator's geometry offset of each triangle's mesh
    (``core.terminator``; 0 on flat meshes), or None when no smooth mesh has one."""

    v0: np.ndarray
    v1: np.ndarray
    v2: np.ndarray
    normals: np.ndarray
    corner_normals: np.ndarray | None
    material: np.ndarray
    surface: np.ndarray
    terminator_offset: np.ndarray | None = None

    def __len__(self) -> int:
        return self.v0.shape[1]


@dataclass(frozen=True)
class MaterialArrays:
    """The scene's material table (M entries): ambient / diffuse / specular (M, 3)
    reflectances, exponent (M,) = shininess / 4 (the article's Blinn-Phong exponent),
    reflection (M,); entries: the M core materials themselves (``core.bsdf`` reads the
    physically based ones' lobes)."""

    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    reflection: np.ndarray
    entries: tuple = ()

    def __len__(self) -> int:
        return len(self.reflection)


@dataclass(frozen=True)
class LightArrays:
    """positions (L, 3), ambient / diffuse / specular (L, 3) intensities, radii (L,)."""

    positions: np.ndarray
    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    radii: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class SceneArrays:
    spheres: SphereArrays
    triangles: TriangleArrays
    materials: MaterialArrays
    lights: LightArrays
    background: np.ndarray   # (3,)
    ambient: np.ndarray      # (3,) scene ambient intensity (default semantics)


def _rows(values, width: int) -> np.ndarray:
    return np.asarray(values, np.float64).reshape(-1, width)


class _MaterialTable:
    """Collects materials once each (by identity), handing out their indices."""

    def __init__(self):
        self.entries, self._index = [], {}

    def add(self, material) -> int:
        key = id(material)
        if key not in self._index:
            self._index[key] = len(self.entries)
            self.entries.append(material)
        return self._index[key]

    def arrays(self) -> MaterialArrays:
        table = self.entries
        return MaterialArrays(
            ambient=_rows([m.ambient for m in table], 3),
            diffuse=_rows([m.diffuse for m in table], 3),
            specular=_rows([m.specular for m in table], 3),
            exponent=np.asarray([m.shininess / 4 for m in table], np.float64),
            reflection=np.asarray([m.reflection for m in table], np.float64),
            entries=tuple(table))


def _remap(table: _MaterialTable, materials, indices) -> np.ndarray:
    """A set's local material indices (n,) as indices into the scene's table."""
    mapping = np.asarray([table.add(m) for m in materials], np.intp)
    return mapping[indices]


def _unit(vectors: np.ndarray) -> np.ndarray:
    """Rows of ``vectors`` (..., 3) scaled to unit length (zero rows stay zero)."""
    size = np.sqrt((vectors * vectors).sum(axis=-1, keepdims=True))
    return vectors / np.where(size > 0, size, 1.0)


def _mesh_triangles(mesh, table: _MaterialTable):
    """World-space corners (K*T, 3, 3), front normals (K*T, 3), corner normals
    (K*T, 3, 3) or None, materials (K*T,) of one mesh, instance by instance.

    Points map by each instance's matrix; normals by the inverse transpose of its 3 x 3.  A
    mirroring instance (negative determinant) reverses the winding of its world-space
    triangles; its normals are turned back so that the front stays the object's outside,
    as Blender does."""
    linear = mesh.transforms[:, :3, :3]                                       # (K, 3, 3)
    world = (np.einsum("kij,vj->kvi", linear, mesh.vertices)
             + mesh.transforms[:, None, :3, 3])                              # (K, V, 3)
    corners = world[:, mesh.triangles].reshape(-1, 3, 3)                    # (K*T, 3, 3)
    orientation = np.repeat(np.sign(np.linalg.det(linear)), len(mesh.triangles))
    normals = _unit(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
                    * orientation[:, None])
    smooth = None
    if mesh.corner_normals is not None:
        inverse_t = np.linalg.inv(linear).transpose(0, 2, 1)                  # (K, 3, 3)
        smooth = _unit(np.einsum("kij,tcj->ktci", inverse_t, mesh.corner_normals)
                       .reshape(-1, 3, 3))
    materials = np.tile(_remap(table, mesh.materials, mesh.material_indices),
                        len(mesh.transforms))
    return corners, normals, smooth, materials


def _surfaces(mesh, normals: np.ndarray, first_instance: int) -> np.ndarray:
    """(K*T,) surface ids of one mesh's triangles, instance by instance: each instance is a
    surface of its own; a flat-shaded mesh's facets (triangles with the same plane normal,
    such as a quad's two halves) are surfaces too, because its shading jumps at their edges,
    whereas a smooth mesh shades continuously across its triangles.  Ids are
    ``instance * FACETS_PER_INSTANCE + facet``."""
    count = len(mesh.triangles)
    instance = first_instance + np.repeat(np.arange(len(mesh.transforms)), count)
    facet = np.zeros(len(instance), np.int64)
    if mesh.corner_normals is None and len(instance):
        # Normals agreeing to about a thousandth of a radian are one plane.
        rounded = np.round(normals * 1024).astype(np.int64)
        keys = np.concatenate([instance[:, None], rounded], axis=1)
        _, facet = np.unique(keys, axis=0, return_inverse=True)
        facet = facet.reshape(-1) % FACETS_PER_INSTANCE
    return instance * FACETS_PER_INSTANCE + facet


#: Facet ids per instance in a surface id (a flat mesh with more distinct planes wraps around,
#: which at worst misses an edge between two far-apart facets).
FACETS_PER_INSTANCE = 1 << 24


def _triangle_arrays(meshes, table: _MaterialTable) -> TriangleArrays:
    parts = [_mesh_triangles(mesh, table) for mesh in meshes]
    if not parts:
        empty = np.zeros((3, 0))
        return TriangleArrays(empty, empty, empty, empty, None, np.zeros(0, np.intp),
                              np.zeros(0, np.int64))
    first_instances = np.cumsum([0] + [len(mesh.transforms) for mesh in meshes])
    surfaces = np.concatenate([_surfaces(mesh, part[1], first)
                               for mesh, part, first in zip(meshes, parts, first_instances)])
    corners = np.concatenate([p[0] for p in parts])
    normals = np.concatenate([p[1] for p in parts])
    corner_normals = None
    if any(p[2] is not None for p in parts):
        # Flat meshes beside smooth ones: their corners carry the geometric normal.
        corner_normals = np.concatenate([
            p[2] if p[2] is not None else np.repeat(p[1][:, None, :], 3, axis=1)
            for p in parts]).transpose(1, 2, 0).copy()
    terminator = None
    if any(mesh.corner_normals is not None and mesh.shadow_terminator_offset > 0
           for mesh in meshes):
        terminator = np.concatenate([
            np.full(len(mesh), mesh.shadow_terminator_offset
                    if mesh.corner_normals is not None else 0.0) for mesh in meshes])
    vertices = corners.transpose(1, 2, 0)                                      # (3, 3, T)
    return TriangleArrays(vertices[0].copy(), vertices[1].copy(), vertices[2].copy(),
                          normals.T.copy(), corner_normals,
                          np.concatenate([p[3] for p in parts]), surfaces, terminator)


def scene_arrays(scene: Scene) -> SceneArrays:
    table = _MaterialTable()
    spheres = scene.spheres
    centers = [_rows([s.center for s in spheres], 3)]
    radii = [np.asarray([s.radius for s in spheres], np.float64)]
    materials = [np.asarray([table.add(s.material) for s in spheres], np.intp)]
    for sphere_set in scene.sphere_sets:
        centers.append(sphere_set.centers)
        radii.append(sphere_set.radii)
        materials.append(_remap(table, sphere_set.materials, sphere_set.material_indices))
    triangles = _triangle_arrays(scene.meshes, table)
    # The article's point lights; Blender's light types are prepared by ``core.lights``.
    lights = [light for light in scene.lights if isinstance(light, PointLight)]
    return SceneArrays(
        spheres=SphereArrays(np.concatenate(centers), np.concatenate(radii),
                             np.concatenate(materials)),
        triangles=triangles,
        materials=table.arrays(),
        lights=LightArrays(
            positions=_rows([l.position for l in lights], 3),
            ambient=_rows([l.ambient for l in lights], 3),
            diffuse=_rows([l.diffuse for l in lights], 3),
            specular=_rows([l.specular for l in lights], 3),
            radii=np.asarray([l.radius for l in lights], np.float64),
        ),
        background=np.asarray(scene.background, np.float64),
        ambient=np.asarray(scene.ambient, np.float64),
    )
