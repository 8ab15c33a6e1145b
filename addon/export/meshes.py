"""Meshes -> analytic spheres (``core.Sphere``, ``core.SphereSet``) or ``core.TriangleMesh``.

Every object Blender evaluates to a mesh arrives here as a MESH instance of the depsgraph:
mesh objects with their modifiers, and curve, text, surface and metaball objects, whose
evaluated mesh the depsgraph yields as an instance of the object itself (their own CURVE /
FONT / SURFACE / META entry carries no faces and is passed over by ``scene``).

Per instance only a key and the world matrix are recorded (``MeshExporter.add``); each
evaluated mesh is read once, whatever its number of instances, keyed by the evaluated mesh and
the materials in its object's slots (``MeshUse``).  Reading is ``foreach_get`` only, never a
Python loop over vertices or faces:

* ``vertices.co``; ``loop_triangles.vertices`` (the triangulation Blender renders),
  ``loop_triangles.loops`` and ``corner_normals.vector``, which give each triangle corner the
  normal Blender shades with (flat faces, smooth faces, auto smooth / sharp edges and custom
  split normals all end up in ``corner_normals``, Blender 4.1+); a mesh whose normals
  domain is FACE (all flat) gets ``corner_normals=None``: the geometric normal is the same;
* ``loop_triangles.material_index``: each triangle keeps its face's material slot; indices
  past the last slot use the last one, as Blender does.  Materials go through the context's
  cache (``ExportContext.material``).

Zero-area triangles (which no renderer hits) are dropped; so are the triangles that touch a
vertex that is not finite or past ``CYCLES_REACH``, which Cycles drops too, with a warning
(``core.validation.usable_triangles``); a mesh without faces (loose vertices and edges, a
Geometry Nodes host whose output is points) draws nothing, in Blender too, and is passed over
without a warning.  Instances whose matrix is not finite draw nothing, as in Cycles, and are
skipped with a warning, as zero-scale ones are.  Whether an instance of a
sphere-like mesh is drawn as a sphere is ``geometry``'s rule; the others become one
``TriangleMesh`` per evaluated mesh with one transform per instance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...core import SceneError, Sphere, SphereSet, TriangleMesh
from ...core.validation import row_blocks, usable_triangles
from ...core.terminator import DEFAULT_GEOMETRY_OFFSET
from ...core.shader.input_nodes import ATTRIBUTE_PREFIX, RENDER_COLOR
from ..compat import matrix_bytes
from .context import instance_name
from .errors import ExportError
from .geometry import (ANALYTIC_SPHERE_PROPERTY, STORED_FLOAT, STORED_INT, SphereFit,
                       corner_values, degenerate_transforms, mesh_sphere, read_array,
                       sphere_instances)


#: How far from the origin a vertex may be for Cycles to draw its triangles: it intersects in
#: float32, whose squares overflow past about 1.8e19; measured with a UV sphere one of whose
#: vertices was moved to x: drawn at 1e18, left out (the render equal to a NaN vertex's) at
#: 1e19 and beyond.  A vertex Blender holds past it is left out here, as there.
CYCLES_REACH = 1e19

#: Object types whose evaluated mesh the depsgraph yields as a MESH instance of the object
#: itself; their own entry has nothing more to draw.
EVALUATED_AS_MESH = {'CURVE', 'FONT', 'SURFACE', 'META'}


#: Objects drawing one sphere-like mesh with the same materials beyond which their spheres
#: are one SphereSet (named after the first object, whose Object Index it gets, as a
#: triangle mesh shared by several objects does) instead of a named ``core.Sphere`` each:
#: each Sphere checks its material again, 80 microseconds apiece (100,000 linked
#: duplicates: 8 s of a 9 s export).
MAX_NAMED_SPHERES = 1000


@dataclass(frozen=True)
class MeshArrays:
    """An evaluated mesh's triangles as Glint draws them (object space)."""

    vertices: np.ndarray                  # (V, 3) float64
    triangles: np.ndarray                 # (T, 3) int64
    corner_normals: Optional[np.ndarray]  # (T, 3, 3) float64, or None: flat shading
    slots: np.ndarray                     # (T,) int64 material slot of each triangle
    corner_loops: np.ndarray              # (T, 3) int64 each corner's loop (its UVs' index)
    dropped: Optional[str] = None         # what usable_triangles left out, or None
    faces: Optional[np.ndarray] = None    # (T,) int64 each triangle's face


def face_slots(mesh, faces: np.ndarray) -> np.ndarray:
    """(T,) int64 the material slot of each of ``faces`` (face indices): the mesh's
    ``material_index`` attribute (absent when every face uses the first slot)."""
    attribute = mesh.attributes.get("material_index")
    if attribute is None or attribute.domain != 'FACE':
        return np.zeros(len(faces), np.int64)
    return read_array(attribute.data, "value", 1, np.int64, stored=STORED_INT)[faces]


def _area_vectors(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(n, 3) each triangle's edge cross product (twice its area along its normal)."""
    corners = vertices[triangles]
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def _nonzero_area(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T,) bool: the triangles whose area vector is not zero, block by block."""
    keep = np.empty(len(triangles), bool)
    for block in row_blocks(len(triangles)):
        keep[block] = _area_vectors(vertices, triangles[block]).any(axis=1)
    return keep


def _gathered(values: np.ndarray, index: np.ndarray, dtype) -> np.ndarray:
    """``values[index].astype(dtype)``, block by block into the result."""
    result = np.empty(index.shape + values.shape[1:], dtype)
    for block in row_blocks(len(index)):
        result[block] = values[index[block]]
    return result


def _flat_where_zero(normals: np.ndarray, vertices: np.ndarray,
                     triangles: np.ndarray) -> np.ndarray:
    """``normals`` (T, 3, 3), where a corner's normal Blender left zero (a degenerate
    neighbourhood) replaced, in place, by its triangle's area vector: it shades flat.  Area
    vectors are worked out for those triangles only."""
    zero = ~normals.any(axis=2)
    rows = np.flatnonzero(zero.any(axis=1))
    if len(rows):
        flat = np.repeat(_area_vectors(vertices, triangles[rows])[:, None, :], 3, axis=1)
        normals[rows] = np.where(zero[rows][:, :, None], flat, normals[rows])
    return normals


def read_mesh(mesh) -> MeshArrays:
    """The triangles of an evaluated bpy Mesh (module docstring), with ``foreach_get``:
    each triangle's corners (``loop_triangles.loops``, the one read Blender does not serve
    in bulk: 0.55 s for a million triangles), its vertices through the ``.corner_vert``
    attribute and its face (``loop_triangle_polygons``) and slot through the face's
    ``material_index``, so the same values as ``loop_triangles.vertices`` and
    ``.material_index`` without their per-element reads (0.65 and 0.5 s more).  The
    per-triangle arithmetic runs in blocks (``core.validation.row_blocks``: whole-mesh
    temporaries were fresh pages at every export)."""
    vertices = read_array(mesh.vertices, "co", 3, stored=STORED_FLOAT)
    triangulation = mesh.loop_triangles
    loops = read_array(triangulation, "loops", 3, np.int64, stored=STORED_INT)
    triangles = corner_values(mesh, ".corner_vert", mesh.loops, "vertex_index")[loops]
    faces = read_array(mesh.loop_triangle_polygons, "value", 1, np.int64, stored=STORED_INT)
    slots = face_slots(mesh, faces)
    vertices, usable, dropped = usable_triangles(vertices, triangles, CYCLES_REACH)
    keep = _nonzero_area(vertices, triangles)
    if usable is not None:
        keep &= usable
    normals = None
    if mesh.normals_domain != 'FACE':
        # Gathered from Blender's float32 and widened as they land: half the memory traffic.
        corner_normals = read_array(mesh.corner_normals, "vector", 3, STORED_FLOAT)
        normals = _flat_where_zero(_gathered(corner_normals, loops, np.float64), vertices,
                                   triangles)
    if not keep.all():
        triangles, slots, loops, faces = triangles[keep], slots[keep], loops[keep], faces[keep]
        normals = normals[keep] if normals is not None else None
    return MeshArrays(vertices, triangles, normals, slots, loops, dropped, faces)


def evaluated_materials(obj) -> tuple:
    """The bpy materials in an evaluated object's slots (None for an empty slot)."""
    return tuple(slot.material for slot in obj.material_slots)


def terminator_offset(obj) -> float:
    """The object's Shadow Terminator > Geometry Offset (Cycles' per-object setting, which
    Glint's smooth triangles honour: ``core.terminator``)."""
    return float(getattr(obj, "shadow_terminator_geometry_offset", DEFAULT_GEOMETRY_OFFSET))


def forces_sphere(obj) -> bool:
    original = obj.original
    return bool(original.get(ANALYTIC_SPHERE_PROPERTY, False)) if original else False


@dataclass
class MeshUse:
    """One evaluated mesh with one set of slot materials, and every instance that draws it."""

    name: str                       # the first instance's name
    mesh: object                    # the evaluated bpy Mesh (read in ``finish``)
    materials: tuple                # bpy materials per slot
    holdout: bool = False           # its instances are holdouts (``ExportContext.is_holdout``)
    terminator_offset: float = DEFAULT_GEOMETRY_OFFSET   # the objects' (``terminator_offset``)
    matrices: list = field(default_factory=list)   # per instance: 64 bytes, float32 4x4
    names: list = field(default_factory=list)      # per instance: its name, or None
    forced: list = field(default_factory=list)     # per instance: glint_analytic_sphere
    blocks: list = field(default_factory=list)     # (K, 4, 4) arrays of bulk instances

    def instances(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(matrices (K, 4, 4), names (K,) object (None for set members), forced (K,) bool)
        of every instance, those added one by one first."""
        single = np.frombuffer(b"".join(self.matrices), np.float32).reshape(-1, 4, 4)
        matrices = np.concatenate([single.astype(np.float64), *self.blocks])
        names = np.full(len(matrices), None, dtype=object)
        names[:len(self.names)] = self.names
        forced = np.zeros(len(matrices), bool)
        forced[:len(self.forced)] = self.forced
        return matrices, names, forced


@dataclass(frozen=True)
class MeshPlacement:
    """What every instance of one (original object, evaluated mesh, instancer) shares: the
    instance walk (``instances.InstanceWalk``) works it out once and then only adds
    matrices."""

    use: MeshUse
    forced: bool
    name: Optional[str]           # the object's name for its own geometry, else None

    def add(self, matrix_world) -> None:
        use = self.use
        use.matrices.append(matrix_bytes(matrix_world))
        use.names.append(self.name)
        use.forced.append(self.forced)


def _coordinates(materials) -> set:
    """The texture coordinates the materials' programs read."""
    names = set()
    for material in materials:
        program = getattr(material, "program", None)
        if program is not None:
            names |= set(program.coordinates)
    return names


def _reads_coordinates(materials) -> bool:
    names = _coordinates(materials)
    return bool(names & {"uv", "generated", "object", "tangent", RENDER_COLOR}
                or any(name.startswith(("uv:", "tangent:", ATTRIBUTE_PREFIX)) for name in names))


def _uv_names(materials):
    """The UV maps the materials' programs read: None for none, else the names ('' for the
    active render map)."""
    names = _coordinates(materials)
    wanted = {name[3:] for name in names if name.startswith("uv:")}
    if "uv" in names or "tangent" in names:
        wanted.add("")
    return wanted or None


def _chosen_uv_layers(mesh, names) -> list:
    """The mesh's UV layers ``names`` asks for (None: none), the active render map first."""
    if not names or not len(mesh.uv_layers):
        return []
    active = next((layer for layer in mesh.uv_layers if layer.active_render),
                  mesh.uv_layers[0])
    return [active] + [layer for layer in mesh.uv_layers
                       if layer.name in names and layer is not active]


def uv_maps(mesh, arrays: MeshArrays, names) -> tuple:
    """((name, (T, 3, 2) float32 corner UVs), ...) of the maps ``names`` ('' the active
    render map, which goes first) of the evaluated mesh, for its drawn triangles; () for
    None."""
    maps = []
    for layer in _chosen_uv_layers(mesh, names):
        corners = read_array(layer.uv, "vector", 2, np.float32, stored=STORED_FLOAT)
        maps.append((layer.name, corners[arrays.corner_loops].astype(np.float32)))
    return tuple(maps)


def _tangent_names(materials):
    """The UV maps whose tangents the materials' programs read: None for none, else the
    names ('' for the active render map)."""
    names = _coordinates(materials)
    wanted = {name[8:] for name in names if name.startswith("tangent:")
              and not name.endswith("_sign")}
    if "tangent" in names:
        wanted.add("")
    return wanted or None


def tangent_maps(mesh, arrays: MeshArrays, names, context=None) -> tuple:
    """((UV map name, (T, 3, 4) float32 corner tangents and signs), ...) for ``names`` (as
    ``uv_maps``), Blender's MikkTSpace tangents (``Mesh.calc_tangents``, which Cycles uses
    too); () for None or where Blender cannot compute them (faces of more than 4 corners:
    a note says so)."""
    maps = []
    for layer in _chosen_uv_layers(mesh, names):
        try:
            mesh.calc_tangents(uvmap=layer.name)
        except RuntimeError as error:
            if context is not None:
                context.note(f"mesh '{mesh.name}': no tangents for UV map '{layer.name}' "
                             f"({error}); its Normal Map nodes leave the normal as it is")
            continue
        tangent = read_array(mesh.loops, "tangent", 3, np.float32, stored=STORED_FLOAT)
        sign = read_array(mesh.loops, "bitangent_sign", 1, np.float32, stored=STORED_FLOAT)
        corners = np.concatenate([tangent, sign[:, None]], axis=1)[arrays.corner_loops]
        maps.append((layer.name, corners.astype(np.float32)))
    return tuple(maps)


#: How a mesh attribute's data type is read (its ``data`` items' field and width) as the
#: Attribute node sees it: a float as (f, f, f), a 2D vector with z 0, colours with alpha.
_ATTRIBUTE_FIELDS = {"FLOAT": ("value", 1), "INT": ("value", 1), "INT8": ("value", 1),
                     "BOOLEAN": ("value", 1), "FLOAT2": ("vector", 2),
                     "FLOAT_VECTOR": ("vector", 3), "FLOAT_COLOR": ("color", 4),
                     "BYTE_COLOR": ("color", 4)}


def _attribute_names(materials):
    """The mesh attributes the materials' programs read: None for none, else their names
    ('' for the mesh's render colour attribute, a Vertex Color node's default)."""
    names = _coordinates(materials)
    wanted = {name[len(ATTRIBUTE_PREFIX):] for name in names
              if name.startswith(ATTRIBUTE_PREFIX)}
    if RENDER_COLOR in names:
        wanted.add("")
    return wanted or None


def attribute_maps(mesh, arrays: MeshArrays, names) -> tuple:
    """((name, (T, 3, 4) float32 corner values and alpha), ...) of the point, corner and face
    attributes ``names`` of the evaluated mesh ('' its render colour attribute), as
    Cycles' Attribute node reads them (``_ATTRIBUTE_FIELDS``: colours scene-linear, byte
    colours too); names the mesh lacks, or of other domains and types, are left out (they
    read as zero)."""
    if not names:
        return ()
    maps = []
    for name in sorted(names):
        attribute = mesh.attributes.get(name) if name else _render_color(mesh)
        if attribute is None or attribute.data_type not in _ATTRIBUTE_FIELDS:
            continue
        domain = attribute.domain
        if domain == 'POINT':
            rows = arrays.triangles
        elif domain == 'CORNER':
            rows = arrays.corner_loops
        elif domain == 'FACE' and arrays.faces is not None:
            rows = np.repeat(arrays.faces[:, None], 3, axis=1)
        else:
            continue
        field_name, width = _ATTRIBUTE_FIELDS[attribute.data_type]
        stored = STORED_INT if attribute.data_type in ("INT", "INT8") else None
        values = read_array(attribute.data, field_name, width, np.float32, stored=stored)
        values = values.reshape(len(attribute.data), width)
        table = np.zeros((len(values), 4), np.float32)
        table[:, 3] = 1.0
        if width == 1:
            table[:, :3] = values
        else:
            table[:, :width] = values
        maps.append((name, table[rows]))
    return tuple(maps)


def _render_color(mesh):
    """The mesh's colour attribute for rendering (Cycles' default vertex colours), or None."""
    colors = mesh.color_attributes
    index = getattr(colors, "render_color_index", -1)
    if 0 <= index < len(colors):
        return colors[index]
    return colors.active_color if len(colors) else None


def own_geometry(instance) -> bool:
    """Whether an instance is a scene object's own geometry (exported under its name) rather
    than one of many instances (exported within a set): a curve, text, surface or metaball
    object's evaluated mesh comes as an instance of the object itself."""
    if not instance.is_instance:
        return True
    parent = instance.parent
    return parent.type in EVALUATED_AS_MESH and parent.name == instance.object.name


def _material_key(materials: tuple) -> tuple:
    return tuple(m.as_pointer() if m else 0 for m in materials)


class MeshExporter:
    """Collects mesh instances during the depsgraph walk, converts them in ``finish``."""

    def __init__(self, context):
        self.context = context
        self.uses: dict = {}
        # (original object, evaluated mesh) -> (its MeshUse, forced): an object's slots and
        # custom property are read once, not once per instance.
        self.objects: dict = {}

    def add(self, instance) -> None:
        """One MESH instance of the depsgraph walk.  Per instance this costs two pointer
        reads, a dictionary look-up and a 64-byte copy of the matrix (matrix_world lives only
        until the walk moves on)."""
        self.placement(instance).add(instance.matrix_world)

    def placement(self, instance) -> "MeshPlacement":
        """Where the instances of this instance's (original object, evaluated mesh) go: its
        MeshUse, the object's glint_analytic_sphere and the name it is exported under."""
        obj = instance.object
        # An instance is a holdout as its instancer is (as Cycles reads it).
        holder = instance.parent if instance.is_instance else obj
        key = (obj.original.as_pointer(), obj.data.as_pointer(), holder.as_pointer())
        known = self.objects.get(key)
        if known is None:
            materials = evaluated_materials(obj)
            holdout = self.context.is_holdout(holder)
            offset = terminator_offset(obj)
            use_key = (key[1], _material_key(materials), holdout, offset)
            use = self.uses.get(use_key)
            if use is None:
                use = self.uses[use_key] = MeshUse(instance_name(instance), obj.data, materials,
                                                   holdout, offset)
            known = self.objects[key] = (use, forces_sphere(obj))
        use, forced = known
        return MeshPlacement(use, forced, obj.name if own_geometry(instance) else None)

    def add_bulk(self, mesh, materials: tuple, matrices: np.ndarray, display_name: str,
                 holdout: bool = False, offset: float = DEFAULT_GEOMETRY_OFFSET) -> None:
        """Instances of one evaluated mesh given as (K, 4, 4) world matrices (instances read
        in bulk, ``instances``); holdout: their instancer is a holdout; offset: its
        ``terminator_offset``."""
        key = (mesh.as_pointer(), _material_key(materials), holdout, offset)
        use = self.uses.get(key)
        if use is None:
            use = self.uses[key] = MeshUse(display_name, mesh, materials, holdout, offset)
        use.blocks.append(np.asarray(matrices, np.float64).reshape(-1, 4, 4))

    def finish(self) -> None:
        for use in self.uses.values():
            self._export(use)

    # ------------------------------------------------------------------------------------
    def _arrays(self, mesh) -> tuple[MeshArrays, Optional[SphereFit]]:
        key = mesh.as_pointer()
        cache = self.context
        if key not in cache.mesh_arrays:
            arrays = read_mesh(mesh)
            cache.mesh_arrays[key] = arrays
            # (A mesh with triangles left out has a hole: no sphere, whatever its vertices.)
            cache.sphere_fits[key] = None if arrays.dropped else mesh_sphere(mesh,
                                                                             arrays.vertices)
        return cache.mesh_arrays[key], cache.sphere_fits[key]

    def _export(self, use: MeshUse) -> None:
        context = self.context
        matrices, names, forced = use.instances()
        unplaced = ~np.isfinite(matrices).all(axis=(1, 2))
        degenerate = unplaced | degenerate_transforms(np.where(unplaced[:, None, None], 0.0,
                                                                matrices))
        for index in np.flatnonzero(degenerate)[:1]:
            context.skip(names[index] or use.name, "matrix not finite: draws nothing, as in "
                         "Cycles" if unplaced[index] else "zero scale: draws nothing")
        drawn = ~degenerate
        if not use.mesh.polygons:
            return  # loose vertices and edges: Blender renders nothing either
        arrays, fit = self._arrays(use.mesh)
        if arrays.dropped:
            context.note(f"object '{use.name}': {arrays.dropped}, as Cycles leaves them out")
        if len(arrays.triangles) == 0:
            return
        slot_materials = ([context.material(m, use.name, use.holdout) for m in use.materials]
                          or [context.material(None, use.name, use.holdout)])
        # A mesh whose material reads texture coordinates is drawn as Cycles draws it: its
        # own triangles and UVs, not an analytic sphere (which keeps no rotation or UVs).
        if fit is not None and drawn.any() and not _reads_coordinates(slot_materials):
            placed = sphere_instances(fit, matrices[drawn], context.footprint, forced[drawn])
            as_sphere = np.zeros(len(matrices), bool)
            as_sphere[np.flatnonzero(drawn)[placed.chosen]] = True
            material = slot_materials[min(int(arrays.slots[0]), len(slot_materials) - 1)]
            self._spheres(use, names[as_sphere], placed, material)
            drawn &= ~as_sphere
        if drawn.any():
            self._triangles(use, arrays, matrices[drawn], slot_materials)

    def _spheres(self, use: MeshUse, names, placed, material) -> None:
        context = self.context
        single = np.array([name is not None for name in names], bool)
        if single.sum() > MAX_NAMED_SPHERES:
            single[:] = False  # many objects sharing a mesh: one set, like a shared mesh
        try:
            for name, center, radius in zip(names[single], placed.centers[single],
                                            placed.radii[single]):
                context.spheres.append(Sphere(tuple(center), float(radius), material, name))
            if (~single).any():
                centers, radii = placed.centers[~single], placed.radii[~single]
                context.sphere_sets.append(SphereSet(
                    centers=centers, radii=radii, material_indices=np.zeros(len(radii), int),
                    materials=(material,), name=f"{use.name} ({len(radii)} instances)"))
        except SceneError as error:
            raise ExportError(f"object '{use.name}': {error}") from None

    def _triangles(self, use: MeshUse, arrays: MeshArrays, matrices, slot_materials) -> None:
        slots = np.minimum(arrays.slots, len(slot_materials) - 1)
        used = np.unique(slots)
        # Only the slots the triangles use enter the mesh's material table.
        remap = np.zeros(len(slot_materials), np.int64)
        remap[used] = np.arange(len(used))
        name = use.name if len(matrices) == 1 else f"{use.name} ({len(matrices)} instances)"
        materials = tuple(slot_materials[i] for i in used)
        try:
            self.context.meshes.append(TriangleMesh(
                vertices=arrays.vertices, triangles=arrays.triangles,
                corner_normals=arrays.corner_normals, material_indices=remap[slots],
                materials=materials, transforms=matrices,
                name=name, shadow_terminator_offset=use.terminator_offset,
                uv_maps=uv_maps(use.mesh, arrays, _uv_names(materials)),
                tangent_maps=tangent_maps(use.mesh, arrays, _tangent_names(materials),
                                          self.context),
                attributes=attribute_maps(use.mesh, arrays, _attribute_names(materials))))
        except SceneError as error:
            raise ExportError(f"object '{use.name}': {error}") from None
