"""Meshes that are spheres become analytic spheres.

A mesh is a sphere when

1. its vertices lie on one sphere: a least-squares fit (the linear form
   ``|v|^2 = 2 c.v + (r^2 - |c|^2)``, solved with NumPy on the vertices read with
   ``foreach_get``) gives centre c and radius r, and every vertex is within
   ``RADIUS_TOLERANCE * r + FLOAT32_SLACK * max|v|`` of that sphere.  UV and ico spheres put
   their vertices exactly ON the sphere of the primitive's radius, so r is that radius.
   Tolerance: 1e-4 r is a tenth of a pixel even for a sphere 2000 pixels across, i.e. nothing
   anyone could see; the second term allows for vertex coordinates being float32 (relative
   rounding 2^-24 per coordinate; 8 ulps of the largest coordinate covers the rounding of the
   coordinates and of the fit), which matters for a small sphere modelled far from its
   origin;
2. it is closed (every edge borders exactly two faces), so a hemisphere or a cap is not a
   sphere;
3. its faces follow the sphere: every face centre lies within ``MAX_FACE_SAGITTA * r`` of
   the surface.  A tessellated sphere's faces sag inwards by about r (1 - cos(pi / segments)):
   0.5 % for a 32-segment UV sphere, 20.5 % for the coarsest ico sphere (an icosahedron).  A
   cube or an octahedron also has all its vertices on a sphere, but its face centres sag by
   42 % of the radius: it is a box, not a sphere, and is reported as such.

The object's world matrix must then be a rotation times a uniform scale (mirroring allowed):
a non-uniformly scaled sphere is an ellipsoid, which the core cannot draw.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

RADIUS_TOLERANCE = 1e-4
FLOAT32_SLACK = 8 * 2.0 ** -24
MAX_FACE_SAGITTA = 0.25
#: Relative tolerance on the world matrix being a rotation times a uniform scale.
UNIFORM_SCALE_TOLERANCE = 1e-5


@dataclass(frozen=True)
class SphereFit:
    """A mesh's sphere in the mesh's own (object) coordinates."""

    center: tuple[float, float, float]
    radius: float


def _read(collection, attribute: str, width: int, dtype=np.float64) -> np.ndarray:
    values = np.empty(len(collection) * width, dtype)
    collection.foreach_get(attribute, values)
    return values.reshape(-1, width) if width > 1 else values


def fit_sphere(points: np.ndarray) -> Optional[SphereFit]:
    """Least-squares sphere through points (n, 3), or None when they do not lie on one.

    Only criterion 1 of the module docstring: the vertices, not the faces.
    """
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
    distances = np.linalg.norm(local - center, axis=1)
    tolerance = RADIUS_TOLERANCE * radius + FLOAT32_SLACK * float(np.abs(points).max())
    if np.abs(distances - radius).max() > tolerance:
        return None
    return SphereFit(tuple(float(c) for c in center + origin), radius)


def mesh_sphere(mesh) -> Optional[SphereFit]:
    """The sphere an (evaluated) bpy Mesh is, in object space, or None if it is not one."""
    if len(mesh.vertices) < 4 or len(mesh.polygons) == 0:
        return None
    fit = fit_sphere(_read(mesh.vertices, "co", 3))
    if fit is None:
        return None
    edge_use = np.bincount(_read(mesh.loops, "edge_index", 1, np.int64),
                           minlength=len(mesh.edges))
    if (edge_use != 2).any():
        return None
    face_centers = _read(mesh.polygons, "center", 3)
    sag = fit.radius - np.linalg.norm(face_centers - np.asarray(fit.center), axis=1)
    if np.abs(sag).max() > MAX_FACE_SAGITTA * fit.radius:
        return None
    return fit


def uniform_scale(matrix) -> Optional[float]:
    """s if the 3x3 part of a 4x4 matrix is s times a rotation (or a mirror), else None."""
    linear = np.asarray(matrix, np.float64)[:3, :3]
    gram = linear.T @ linear
    scale_squared = np.trace(gram) / 3.0
    if not scale_squared > 0:
        return None
    if np.abs(gram - scale_squared * np.eye(3)).max() > UNIFORM_SCALE_TOLERANCE * scale_squared:
        return None
    return float(np.sqrt(scale_squared))


def world_sphere(fit: SphereFit, matrix) -> Optional[tuple[tuple[float, float, float], float]]:
    """(world centre, world radius) of an object-space sphere under a 4x4 world matrix, or None
    when the matrix scales non-uniformly (the sphere would be an ellipsoid)."""
    scale = uniform_scale(matrix)
    if scale is None:
        return None
    world = np.asarray(matrix, np.float64)
    center = world[:3, :3] @ np.asarray(fit.center) + world[:3, 3]
    return tuple(float(c) for c in center), fit.radius * scale
