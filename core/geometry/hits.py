"""Hits from what the accelerators found: each ray's distance, primitive and barycentrics
become the surface it met (point, normals, material, side, the terminator lift), as
Mitsuba's ``compute_surface_interaction`` or pbrt's ``SurfaceInteraction`` do."""

from __future__ import annotations

import numpy as np

from ..rays import Hits, RayBatch
from ..terminator import TerminatorLift, smooth_surface_lift
from ..vectors import dot, facing, take
from .spheres import Spheres
from .triangles import Triangles


def surface_interaction(rays: RayBatch, t, primitive, barycentrics, spheres: Spheres,
                        triangles: Triangles) -> Hits:
    """The hits (``core.rays.Hits``) of the rays of a batch that hit something, from each
    ray's nearest hit: t (n,), primitive (n,) global id or -1, barycentrics (b0, b1, b2)
    (n,) each of triangle hits (None without triangles).

    A sphere's point is o + t d and its normal from its centre; a triangle's point is made
    from the barycentrics (its error then scales with the corners, not with the distance
    travelled: pbrt's choice), its shading normal interpolated from the corner normals."""
    dtype = spheres.dtype
    keep = np.flatnonzero(primitive >= 0)
    origins, directions = rays.origins, rays.directions
    if len(keep) < len(primitive):
        t, hit_primitive = t[keep], primitive[keep]
        directions = take(directions, keep)
        origins = origins if origins.shape[1] == 1 else take(origins, keep)
    else:
        hit_primitive = primitive
    is_triangle = hit_primitive >= spheres.count
    lifted = None    # smooth triangles' terminator lift (``_terminator_lift``)
    hit_barycentrics = None
    if not is_triangle.any():
        points = t * directions
        points += origins
        normals = take(spheres.centers_t, hit_primitive)
        np.subtract(points, normals, out=normals)
        size = dot(normals, normals)
        np.sqrt(size, out=size)
        normals *= np.reciprocal(size, out=size)
        shading = normals
        material = spheres.material.take(hit_primitive)
    else:
        points = np.empty((3, len(keep)), dtype)
        normals = np.empty_like(points)
        material = np.empty(len(keep), np.intp)
        on_spheres = np.flatnonzero(~is_triangle)
        if len(on_spheres):
            sphere = hit_primitive[on_spheres]
            p = (origins if origins.shape[1] == 1 else take(origins, on_spheres)) \
                + t[on_spheres] * take(directions, on_spheres)
            n = p - take(spheres.centers_t, sphere)
            n *= 1 / np.sqrt(dot(n, n))
            points[:, on_spheres], normals[:, on_spheres] = p, n
            material[on_spheres] = spheres.material.take(sphere)
        tris = np.flatnonzero(is_triangle)
        triangle = hit_primitive[tris] - spheres.count
        rows = keep[tris]
        b0, b1, b2 = (b[rows].astype(dtype) for b in barycentrics)
        hit_barycentrics = tuple(b[keep] for b in barycentrics)
        v0, v1, v2 = (take(v, triangle) for v in triangles.v)
        points[:, tris] = b0 * v0 + b1 * v1 + b2 * v2
        normals[:, tris] = take(triangles.normals, triangle)
        material[tris] = triangles.material.take(triangle)
        shading = normals
        if triangles.corner_normals is not None:
            shading = normals.copy()
            corners = tuple(take(c, triangle) for c in triangles.corner_normals)
            smooth = b0 * corners[0] + b1 * corners[1] + b2 * corners[2]
            shading[:, tris] = smooth * (1 / np.sqrt(dot(smooth, smooth)))
            if triangles.terminator is not None:
                lifted = (tris, triangle, (v0, v1, v2), corners, (b0, b1, b2))
    cos_in = dot(directions, shading)
    front = cos_in < 0 if shading is normals else dot(directions, normals) < 0
    terminator = None
    if lifted is not None:
        terminator = _terminator_lift(triangles, normals, shading, front, *lifted)
    return Hits(keep, primitive, t, hit_primitive, material, points, directions, normals,
                shading, cos_in, front, terminator, hit_barycentrics)


def _terminator_lift(triangles: Triangles, normals, shading, front, tris, triangle, corners,
                     corner_normals, barycentrics) -> TerminatorLift:
    """The hits' ``TerminatorLift`` (``core.terminator``): the smooth-surface offsets of the
    hits ``tris`` on triangles ``triangle`` (k,), their corners, corner normals (3, k) each
    and barycentrics (k,) each; the other hits keep their origins."""
    geometric, seen_shading = facing(normals, front), facing(shading, front)
    lift = np.zeros_like(normals)
    lift[:, tris] = smooth_surface_lift(corners, corner_normals, barycentrics,
                                        geometric[:, tris])
    cutoff = np.zeros(normals.shape[1], normals.dtype)
    cutoff[tris] = triangles.terminator.take(triangle)
    return TerminatorLift(lift, cutoff, geometric, seen_shading)
