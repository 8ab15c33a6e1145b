"""What a scene is: spheres, triangle meshes, materials, lights, a camera, a background.

The ``Scene`` and its shapes (``Sphere``, ``SphereSet``, ``TriangleMesh``) are here; its parts
have modules of their own: ``core.materials``, ``core.light_sources``, ``core.camera`` (the
cameras), and how to render it, ``core.settings``.

All of it is plain, immutable data with units and conventions spelled out; the tracer
turns it into arrays (``core.arrays``).  Construction validates every field, so a scene that
exists is a scene the tracer can render: bad input fails here, naming the field and the
value, before any ray is traced (the checks and limits: ``core.validation``; the reflectance
formulas the materials use: ``core.reflectance``).

Conventions
-----------
* World space is Blender's: right-handed, Z up.  (The article's scene uses Y up; that is
  just a different choice of numbers, the tracer does not care.)
* Lengths are in scene units (Blender units / metres), angles in radians, colours are linear
  RGB triples.
* Colours and intensities follow the article for its types (``Material``, ``PointLight``): a
  pixel's colour is the sum of Blinn-Phong terms, clipped to [0, 1] at the end (article
  semantics).  The physically based types (``SurfaceMaterial``, ``SphereLight``,
  ``SpotLight``, ``SunLight``, ``AreaLight``) use Cycles' units: scene-linear Rec.709 radiance
  in W / (m^2 sr), light power in W, sun strength in W/m^2; default semantics hands the
  unclipped radiance to Blender (see ``core.lights`` and ``core.bsdf`` for the formulas).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import BlenderCamera, Camera, ScreenCamera
from .light_sources import LIGHT_TYPES
from .materials import Material, SurfaceMaterial, _is_program
from .terminator import DEFAULT_GEOMETRY_OFFSET
from .validation import (MAX_MAGNITUDE, SceneError, Vec3, usable_triangles, value_text,
                         _checked_array, _colour, _first_bad, _fraction, _frozen, _frozen_array,
                         _index_text, _positive, _require_finite, _require_indices, _set,
                         _set_label, _unit_rows, _vec3)


@dataclass(frozen=True)
class Sphere:
    """A sphere in world space: ``center`` (3,), ``radius`` > 0, a material and a name."""

    center: Vec3
    radius: float
    material: Material = field(default_factory=Material)
    name: str = ""

    def __post_init__(self):
        where = f"sphere {value_text(self.name)}" if self.name else "sphere"
        _set(self, "center", _vec3(f"{where}.center", self.center))
        _set(self, "radius", _positive(f"{where}.radius", self.radius))
        if not isinstance(self.material, (Material, SurfaceMaterial)):
            raise SceneError(f"{where}.material must be a Material or SurfaceMaterial, "
                             f"got {value_text(self.material)}")
        # Named here: a material shared by many spheres is checked again for each, so an
        # invalid one (built past its own check) names the sphere that uses it.
        self.material.validate(f"{where}.material")


# --------------------------------------------------------------------------------------------
# Array sets: many primitives described as arrays, validated in whole-array operations (a
# million spheres validate in milliseconds).  Errors name the set, the field and the first
# offending index.  The arrays are copied and made read-only, so a set, once built, cannot
# change under the tracer.  (eq=False: equality is identity; comparing arrays element-wise
# is not what ``==`` on a scene should mean.)

#: The material types the tracer shades; the geometry treats them as opaque table entries.
MATERIAL_TYPES = (Material, SurfaceMaterial)


def _materials(where: str, materials) -> tuple:
    try:
        table = tuple(materials)
    except TypeError:
        raise SceneError(f"{where}: materials must be a sequence of materials, "
                         f"got {value_text(materials)}") from None
    if not table:
        raise SceneError(f"{where}: materials must hold at least one material")
    for i, material in enumerate(table):
        if not isinstance(material, MATERIAL_TYPES):
            raise SceneError(f"{where}: materials[{i}] must be a material, got "
                             f"{value_text(material)}")
    return table


@dataclass(frozen=True, eq=False)
class SphereSet:
    """N spheres as arrays (point clouds, particles, molecules): world-space ``centers``
    (N, 3), ``radii`` (N,), ``material_indices`` (N,) into ``materials`` (at least one).

    Spheres that draw nothing in Cycles, of radius <= 0 or a centre or radius that is not
    finite, are left out (``warnings`` counts them, in one line)."""

    centers: np.ndarray
    radii: np.ndarray
    material_indices: np.ndarray
    materials: tuple
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        where = _set_label("sphere set", self.name)
        centers = _frozen_array(where, "centers", self.centers, np.float64, (None, 3))
        count = len(centers)
        radii = _frozen_array(where, "radii", self.radii, np.float64, (count,))
        indices = _frozen_array(where, "material_indices", self.material_indices, np.int64,
                                (count,))
        materials = _materials(where, self.materials)
        _require_indices(where, "material_indices", indices, len(materials), "materials")
        # Compared this way round, NaN radii are left out too, without a NumPy warning.
        drawn = np.isfinite(centers).all(axis=1) & (radii > 0) & (radii <= MAX_MAGNITUDE)
        if not drawn.all():
            first = int(np.flatnonzero(~drawn)[0])
            culprit = (f"radii[{first}] is {value_text(radii[first])}"
                       if np.isfinite(centers[first]).all() else
                       f"centers[{first}] is {value_text(centers[first])}")
            _set(self, "warnings", (f"{where}: {int((~drawn).sum())} of {count} spheres draw "
                                    f"nothing, as in Cycles ({culprit})",))
            centers, radii, indices = (_frozen(a[drawn]) for a in (centers, radii, indices))
        for name, value in (("centers", centers), ("radii", radii),
                            ("material_indices", indices), ("materials", materials)):
            _set(self, name, value)

    def __len__(self) -> int:
        return len(self.radii)


def _identity_transforms() -> np.ndarray:
    return np.eye(4)[None]


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A triangle mesh in object space, drawn once per instance transform.

    vertices (V, 3); triangles (T, 3) vertex indices, counter-clockwise seen from the front
    (Blender's winding); corner_normals (T, 3, 3) per-corner normals in object space (unit
    after validation: they are normalised), or None for flat shading (the geometric normal);
    material_indices (T,) into ``materials`` (at least one); transforms (K, 4, 4)
    object-to-world matrices, one per instance (affine: last row 0 0 0 1, invertible 3 x 3).
    Normals go to world space by the inverse transpose of each instance's 3 x 3.
    shadow_terminator_offset: Blender's Shadow Terminator > Geometry Offset in [0, 1] (its
    default 0.1): how many of a smooth mesh's grazing shadow rays leave from the smooth
    surface over its facets rather than from the facets (``core.terminator``); 0 keeps the
    facets' faceted terminator.  Flat meshes (corner_normals None) have none.
    uv_maps: ((name, (T, 3, 2) corner UVs), ...): the UV maps shader programs read, the
    first the active render map (a program's 'uv' coordinate); () where none reads one.
    tangent_maps: ((UV map name, (T, 3, 4) corner tangents and bitangent signs), ...): the
    MikkTSpace tangents of the UV maps Normal Map nodes read, object space, the first the
    active render map's; () where none reads them.
    attributes: ((name, (T, 3, 4) corner values and alpha), ...): the mesh attributes
    Attribute and Vertex Color nodes read ('' the render colour attribute); () where none.
    Triangles that touch a vertex that is not finite are left out, as Cycles leaves them
    (``warnings`` counts them, in one line).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray | None
    material_indices: np.ndarray
    materials: tuple
    transforms: np.ndarray = field(default_factory=_identity_transforms)
    name: str = ""
    shadow_terminator_offset: float = DEFAULT_GEOMETRY_OFFSET
    uv_maps: tuple = ()
    tangent_maps: tuple = ()
    attributes: tuple = ()
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        where = _set_label("mesh", self.name)
        vertices = _frozen_array(where, "vertices", self.vertices, np.float64, (None, 3))
        triangles = _frozen_array(where, "triangles", self.triangles, np.int64, (None, 3))
        count = len(triangles)
        indices = _frozen_array(where, "material_indices", self.material_indices, np.int64,
                                (count,))
        materials = _materials(where, self.materials)
        transforms = _frozen_array(where, "transforms", self.transforms, np.float64,
                                   (None, 4, 4))
        _require_indices(where, "triangles", triangles, len(vertices), "vertices")
        _require_indices(where, "material_indices", indices, len(materials), "materials")
        vertices, keep, dropped = usable_triangles(vertices, triangles)
        vertices = _frozen(vertices)
        _require_finite(where, "transforms", transforms)
        if len(transforms) == 0:
            raise SceneError(f"{where}: transforms must hold at least one 4 x 4 matrix")
        bad = _first_bad(np.any(transforms[:, 3, :] != (0.0, 0.0, 0.0, 1.0), axis=1))
        if bad is not None:
            raise SceneError(f"{where}: transforms{_index_text(bad)} must be affine (last row "
                             f"0 0 0 1), got {value_text(transforms[bad][3])}")
        linear = transforms[:, :3, :3]
        # Judged on the matrix divided by its largest entry, so that a scene modelled at any
        # scale (1e-150 or 1e155) is not singular through under- or overflow of the det.
        scale = np.abs(linear).max(axis=(1, 2))
        unit = linear / np.where(scale > 0, scale, 1.0)[:, None, None]
        bad = _first_bad((scale == 0) | (np.abs(np.linalg.det(unit)) <= 1e-12))
        if bad is not None:
            raise SceneError(f"{where}: transforms{_index_text(bad)} is singular (its 3 x 3 "
                             f"part has no inverse)")
        normals = self.corner_normals
        if normals is not None:
            # Not copied first: the normalised normals are a new array anyway.
            normals = _checked_array(where, "corner_normals", normals, np.float64,
                                     (count, 3, 3))
            if keep is not None:
                normals = normals[keep]
            _require_finite(where, "corner_normals", normals)
            normals = _unit_rows(where, "corner_normals", normals)
        if keep is not None:
            triangles, indices = _frozen(triangles[keep]), _frozen(indices[keep])
            _set(self, "warnings", (f"{where}: {dropped}",))
        for name, value in (("vertices", vertices), ("triangles", triangles),
                            ("corner_normals", normals), ("material_indices", indices),
                            ("materials", materials), ("transforms", transforms)):
            _set(self, name, value)
        _set(self, "shadow_terminator_offset",
             _fraction(f"{where}.shadow_terminator_offset", self.shadow_terminator_offset))
        maps = []
        for name, corners in self.uv_maps:
            if not isinstance(name, str):
                raise SceneError(f"{where}: uv_maps names must be strings, got {name!r}")
            corners = _frozen_array(where, f"uv_maps[{name!r}]", corners, np.float32,
                                    (count, 3, 2))
            _require_finite(where, f"uv_maps[{name!r}]", corners)
            maps.append((name, corners if keep is None else _frozen(corners[keep])))
        _set(self, "uv_maps", tuple(maps))
        tangents = []
        for name, corners in self.tangent_maps:
            corners = _frozen_array(where, f"tangent_maps[{name!r}]", corners, np.float32,
                                    (count, 3, 4))
            _require_finite(where, f"tangent_maps[{name!r}]", corners)
            tangents.append((str(name), corners if keep is None else _frozen(corners[keep])))
        _set(self, "tangent_maps", tuple(tangents))
        attributes = []
        for name, corners in self.attributes:
            if not isinstance(name, str):
                raise SceneError(f"{where}: attributes names must be strings, got {name!r}")
            corners = _frozen_array(where, f"attributes[{name!r}]", corners, np.float32,
                                    (count, 3, 4))
            # (Imported data may hold NaN: read as zero, as a missing attribute is.)
            if not np.isfinite(corners).all():
                corners = _frozen(np.nan_to_num(corners, nan=0.0, posinf=0.0, neginf=0.0))
            attributes.append((name, corners if keep is None else _frozen(corners[keep])))
        _set(self, "attributes", tuple(attributes))

    def __len__(self) -> int:
        """Triangles drawn: triangles per instance times instances."""
        return len(self.triangles) * len(self.transforms)


@dataclass(frozen=True)
class Scene:
    """A whole scene.

    spheres: hand-made spheres (may be empty).  lights: any of ``LIGHT_TYPES``; their
    contributions sum.  sphere_sets: spheres as arrays (``SphereSet``); meshes: triangle
    meshes (``TriangleMesh``).
    camera: a ScreenCamera (the article's) or a BlenderCamera.
    background: RGB seen where a ray escapes (default semantics; the article's is black).
    world: the world's shader program (``core.shader.program.ShaderProgram``: its value is
        the radiance of the directions rays escape in), which the path integrator runs;
        ``background`` is then its value straight up.  None: the world is ``background``.
    ambient: an RGB ambient intensity lighting every point in addition to the lights' own
        ambient terms (default semantics only).  For a SurfaceMaterial it is the radiance of
        a constant environment: a diffuse surface reflects albedo x ambient, a rough glossy
        one F(N.V) x ambient (Blender's world colour x strength plays this role).
    """

    camera: Camera
    spheres: tuple[Sphere, ...] = ()
    lights: tuple = ()
    background: Vec3 = (0.0, 0.0, 0.0)
    ambient: Vec3 = (0.0, 0.0, 0.0)
    sphere_sets: tuple[SphereSet, ...] = ()
    meshes: tuple[TriangleMesh, ...] = ()
    world: object = None

    def __post_init__(self):
        if not isinstance(self.camera, (ScreenCamera, BlenderCamera)):
            raise SceneError(f"scene.camera must be a ScreenCamera or BlenderCamera, "
                             f"got {value_text(self.camera)}")
        _set(self, "spheres", tuple(self.spheres))
        _set(self, "lights", tuple(self.lights))
        for i, sphere in enumerate(self.spheres):
            if not isinstance(sphere, Sphere):
                raise SceneError(f"scene.spheres[{i}] must be a Sphere, got {value_text(sphere)}")
        for i, light in enumerate(self.lights):
            if not isinstance(light, LIGHT_TYPES):
                raise SceneError(f"scene.lights[{i}] must be a PointLight, SphereLight, "
                                 f"SpotLight, SunLight or AreaLight, got {value_text(light)}")
        _set(self, "sphere_sets", tuple(self.sphere_sets))
        _set(self, "meshes", tuple(self.meshes))
        for i, sphere_set in enumerate(self.sphere_sets):
            if not isinstance(sphere_set, SphereSet):
                raise SceneError(f"scene.sphere_sets[{i}] must be a SphereSet, got "
                                 f"{value_text(sphere_set)}")
        for i, mesh in enumerate(self.meshes):
            if not isinstance(mesh, TriangleMesh):
                raise SceneError(f"scene.meshes[{i}] must be a TriangleMesh, got "
                                 f"{value_text(mesh)}")
        _set(self, "background", _colour("scene.background", self.background))
        _set(self, "ambient", _colour("scene.ambient", self.ambient))
        if self.world is not None and not _is_program(self.world):
            raise SceneError(f"scene.world must be a core.shader ShaderProgram or None, got "
                             f"{type(self.world).__name__}")

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the scene's parts render otherwise than they hold it (a light that emits
        nothing, triangles or spheres left out, ...), one line each naming the part and
        the field."""
        parts = (self.camera, *self.lights, *self.sphere_sets, *self.meshes)
        return tuple(line for part in parts for line in getattr(part, "warnings", ()))

    @property
    def sphere_count(self) -> int:
        """Spheres, listed one by one or in sets."""
        return len(self.spheres) + sum(len(s) for s in self.sphere_sets)

    @property
    def triangle_count(self) -> int:
        """Triangles drawn (each mesh's triangles times its instances)."""
        return sum(len(mesh) for mesh in self.meshes)
