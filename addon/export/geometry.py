"""Sphere or triangles: which meshes Glint draws as analytic spheres.

A mesh is drawn as an analytic sphere only where the render cannot tell the two apart.  Two
steps:

1. **Is it a tessellated sphere at all?**  (``mesh_sphere``, once per evaluated mesh)

   a. its vertices lie near one sphere: a least-squares fit (the linear form
      ``|v|^2 = 2 c.v + (r^2 - |c|^2)``, solved with NumPy on the vertices read with
      ``foreach_get``) gives centre c and radius r, and every vertex is within
      ``MAX_RADIUS_SCATTER * r`` of it.  UV and ico spheres put their vertices exactly on the
      sphere; a Subdivision-Surface UV sphere scatters them by about 1 % of r, CLEVR's sphere
      asset by 3.7e-4;
   b. it is closed (every edge borders exactly two faces): a hemisphere is not a sphere;
   c. its faces follow the sphere: every face centre lies within ``MAX_FACE_SAGITTA * r`` of
      it.  A tessellated sphere's faces sag by about r (1 - cos(pi / segments)): 0.5 % for a
      32-segment UV sphere, 20.5 % for an icosahedron; a cube or an octahedron also has its
      vertices on a sphere but sags by 42 %: it is a box;
   d. all its faces use one material (a sphere cannot show per-face materials).

   The fit records the mesh's **deviation** from its sphere, in object units: the largest of
   the vertices' radial scatter ``max |(|v - c| - r)|`` and the faces' sagitta
   ``max (r - |face centre - c|)``; for a mesh with flat-shaded faces also the longest edge,
   since a flat facet shows as soon as it covers a visible part of a pixel.

2. **Can the render show the difference?**  (``sphere_instances``, per instance)
   An instance is drawn as its analytic sphere when its world transform is a rotation times
   a uniform scale s and ``s * deviation < MAX_DEVIATION_PIXELS * pixel``, with ``pixel`` the
   size of one pixel at the sphere's nearest visible depth (``ExportContext.footprint``):
   the analytic silhouette then stays within a quarter of a pixel of the mesh's, so no pixel
   centre can fall on different sides of the two outlines except where the mesh's own outline
   passes within that distance of it, and anti-aliasing changes edge coverage by at most a
   quarter.  Otherwise the instance is drawn as the mesh's triangles, as Blender draws it: a
   coarse sphere large in frame (an icosahedron, an 8-segment UV sphere), a non-uniformly
   scaled sphere (an ellipsoid), a sphere the camera is inside or almost touching.

   An object whose custom property ``glint_analytic_sphere`` is true is drawn as its analytic
   sphere whatever its size on screen, provided step 1 holds (the article's scene uses this:
   its floor is a sphere of radius 9000 seen from 0.7 away, far beyond any tessellation).

A zero-scale instance draws nothing in Blender and is skipped as degenerate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

#: Largest vertex scatter around the fitted sphere, relative to r, for a mesh to count as a
#: tessellated sphere (step 1a); the pixel rule (step 2) decides whether the scatter shows.
MAX_RADIUS_SCATTER = 0.05
#: Vertex coordinates are float32 (relative rounding 2^-24 per coordinate); 8 ulps of the
#: largest coordinate covers the rounding of the coordinates and of the fit.
FLOAT32_SLACK = 8 * 2.0 ** -24
MAX_FACE_SAGITTA = 0.25
#: Largest deviation of the tessellation from its sphere, in pixels, drawn as the sphere.
MAX_DEVIATION_PIXELS = 0.25
#: Relative tolerance on a world matrix being a rotation times a uniform scale.
UNIFORM_SCALE_TOLERANCE = 1e-5
#: An object custom property forcing the analytic sphere (module docstring).
ANALYTIC_SPHERE_PROPERTY = "glint_analytic_sphere"


@dataclass(frozen=True)
class SphereFit:
    """A mesh's sphere in the mesh's own (object) coordinates, and how far the mesh strays
    from it (module docstring, step 1)."""

    center: tuple[float, float, float]
    radius: float
    deviation: float = 0.0


#: The types Blender stores float properties and integer attributes in.  ``foreach_get``
#: copies in bulk only into an array of the stored type, and converts item by item into any
#: other (pip bpy 5.0.1, a mesh of 504,482 vertices: ``vertices.co`` 0.10 s into float32
#: against 0.42 s into float64; 2 M ``corner_normals`` 0.036 s against 1.34 s; the
#: ``.corner_vert`` attribute 0.001 s into int32 against 0.24 s into int64).
STORED_FLOAT, STORED_INT = np.float32, np.int32


def read_array(collection, attribute: str, width: int, dtype=np.float64,
               stored=None) -> np.ndarray:
    """A bpy collection's attribute as an (n, width) array (or (n,) when width is 1) of
    ``dtype``, read with one ``foreach_get``; stored: the type Blender keeps it in
    (STORED_FLOAT, STORED_INT), read as such and then converted, which is much faster."""
    values = np.empty(len(collection) * width, stored or dtype)
    collection.foreach_get(attribute, values)
    if stored is not None and np.dtype(stored) != np.dtype(dtype):
        values = values.astype(dtype)
    return values.reshape(-1, width) if width > 1 else values


def corner_values(mesh, attribute: str, fallback, field: str) -> np.ndarray:
    """(n,) int64: one of a mesh's integer attributes (``.corner_vert``, ``.corner_edge``),
    read from the attribute in bulk; where a mesh has none of that name, the same values
    through ``fallback``'s ``field`` (the slower per-element property)."""
    stored = mesh.attributes.get(attribute)
    if stored is not None and stored.data_type == 'INT':
        return read_array(stored.data, "value", 1, np.int64, stored=STORED_INT)
    return read_array(fallback, field, 1, np.int64, stored=STORED_INT)


def fit_sphere(points: np.ndarray) -> Optional[SphereFit]:
    """Least-squares sphere through points (n, 3), or None when they do not lie near one
    (step 1a).  ``deviation`` is the vertices' radial scatter only."""
    points = np.asarray(points, np.float64)
    if len(points) < 4 or not np.isfinite(points).all():
        return None
    # Centring first keeps the linear system well conditioned far from the origin.
    origin = points.mean(axis=0)
    local = points - origin
    system = np.hstack([2.0 * local, np.ones((len(local), 1))])
    target = np.einsum("nc,nc->n", local, local)
    solution, _, rank, _ = np.linalg.lstsq(system, target, rcond=None)
    if rank < 4:  # coplanar or collinear vertices
        return None
    center = solution[:3]
    radius_squared = solution[3] + center @ center
    if not radius_squared > 0:
        return None
    radius = float(np.sqrt(radius_squared))
    scatter = float(np.abs(np.linalg.norm(local - center, axis=1) - radius).max())
    rounding = FLOAT32_SLACK * float(np.abs(points).max())
    if scatter > MAX_RADIUS_SCATTER * radius + rounding:
        return None
    return SphereFit(tuple(float(c) for c in center + origin), radius, scatter)


def mesh_sphere(mesh, vertices: Optional[np.ndarray] = None) -> Optional[SphereFit]:
    """The sphere an (evaluated) bpy Mesh is, in object space, with its deviation, or None if
    it is not a tessellated sphere (step 1).  vertices: its (V, 3) coordinates if already
    read."""
    if len(mesh.vertices) < 4 or len(mesh.polygons) == 0:
        return None
    if vertices is None:
        vertices = read_array(mesh.vertices, "co", 3, stored=STORED_FLOAT)
    fit = fit_sphere(vertices)
    if fit is None:
        return None
    edge_use = np.bincount(corner_values(mesh, ".corner_edge", mesh.loops, "edge_index"),
                           minlength=len(mesh.edges))
    if (edge_use != 2).any():
        return None
    face_materials = read_array(mesh.polygons, "material_index", 1, np.int64)
    if (face_materials != face_materials[0]).any():
        return None
    face_centers = read_array(mesh.polygons, "center", 3, stored=STORED_FLOAT)
    sag = fit.radius - np.linalg.norm(face_centers - np.asarray(fit.center), axis=1)
    if np.abs(sag).max() > MAX_FACE_SAGITTA * fit.radius:
        return None
    deviation = max(fit.deviation, float(sag.max()))
    if not read_array(mesh.polygons, "use_smooth", 1, bool).all():
        ends = read_array(mesh.edges, "vertices", 2, np.int64)
        edges = vertices[ends[:, 1]] - vertices[ends[:, 0]]
        deviation = max(deviation, float(np.sqrt((edges * edges).sum(axis=1).max())))
    return SphereFit(fit.center, fit.radius, deviation)


def uniform_scales(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(scales (K,), uniform (K,) bool) of 4x4 matrices (K, 4, 4): s where the 3x3 part is s
    times a rotation (or a mirror), with ``uniform`` False where it is not (s is then the
    root mean square of the axis lengths).  Whole-array arithmetic on the columns (NumPy's
    batched matmul and det cost microseconds per tiny matrix)."""
    linear = np.asarray(matrices, np.float64)[:, :3, :3]
    x, y, z = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]
    lengths = np.stack([(x * x).sum(axis=1), (y * y).sum(axis=1), (z * z).sum(axis=1)])
    scale_squared = lengths.mean(axis=0)
    offset = np.maximum.reduce([np.abs(lengths - scale_squared).max(axis=0),
                                np.abs((x * y).sum(axis=1)), np.abs((y * z).sum(axis=1)),
                                np.abs((z * x).sum(axis=1))])
    uniform = (scale_squared > 0) & (offset <= UNIFORM_SCALE_TOLERANCE * scale_squared)
    return np.sqrt(np.maximum(scale_squared, 0.0)), uniform


def degenerate_transforms(matrices: np.ndarray) -> np.ndarray:
    """(K,) bool: 4x4 matrices whose 3x3 part flattens space (a zero scale on some axis), so
    the instance draws nothing."""
    linear = np.asarray(matrices, np.float64)[:, :3, :3]
    x, y, z = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]
    determinant = (x * np.cross(y, z)).sum(axis=1)
    size = np.abs(linear).max(axis=(1, 2))
    return np.abs(determinant) <= 1e-12 * np.maximum(size, 1e-300) ** 3


@dataclass(frozen=True)
class PlacedSpheres:
    """The instances of one sphere-like mesh drawn as analytic spheres."""

    chosen: np.ndarray    # (K,) bool: which instances are spheres
    centers: np.ndarray   # (n, 3) world centres of the chosen ones
    radii: np.ndarray     # (n,)


def sphere_instances(fit: SphereFit, matrices: np.ndarray, footprint,
                     forced: np.ndarray) -> PlacedSpheres:
    """Which instances (object-to-world matrices (K, 4, 4)) of a mesh whose sphere is ``fit``
    are drawn as analytic spheres (module docstring, step 2).  footprint: the context's
    ``CameraFootprint``; forced: (K,) bool, instances whose object asks for the sphere."""
    matrices = np.asarray(matrices, np.float64)
    scales, uniform = uniform_scales(matrices)
    centers = matrices[:, :3, :3] @ np.asarray(fit.center) + matrices[:, :3, 3]
    radii = fit.radius * scales
    pixel = footprint.pixel_size(centers, radii)
    unseen = fit.deviation * scales < MAX_DEVIATION_PIXELS * pixel
    chosen = uniform & (scales > 0) & (unseen | np.asarray(forced, bool))
    return PlacedSpheres(chosen, centers[chosen], radii[chosen])
