"""The tracing loop: follow a bundle of camera rays through up to max_depth bounces.

Each bounce: nearest hit among the spheres the bundle can reach (``core.cull``), shade the
hits (``core.shading``), then compact: only paths that hit something, that the article's
shadows did not end, whose material reflects, and whose remaining weight can still add more
than ``contribution_cutoff`` go on as reflection rays.  Nothing per pixel runs in Python.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import CameraRays
from .context import ARTICLE_OFFSET, RAY_EPSILON, RayStats, TraceContext
from .cull import bundle_cone, reachable
from .intersect import first_hit_distance, nearest_hits, pair_roots, shared_origin_roots
from .shading import SPHERE_CHUNK, shade

#: Candidate spheres per (n, k, 3) chunk for rays with their own origins.
OWN_ORIGIN_CHUNK = 8

_SIGNATURE_PRIME = np.uint64(1_000_003)


@dataclass
class BundleResult:
    """colour (n, 3) unclipped; coverage (n,) whether the camera ray hit a sphere;
    signature (n,) uint64 hash of what the path hit (spheres and shadowing at every bounce):
    neighbours with different signatures straddle an edge; None unless adaptive AA asks."""

    colour: np.ndarray
    coverage: np.ndarray
    signature: np.ndarray


def nearest_sphere(ctx: TraceContext, origins, directions, t_min, t_max, exclude,
                   stats: RayStats, terms=None):
    """Nearest hit per ray: (t (n,), scene sphere index (n,), -1 for none).

    origins (1, 3) with ``terms`` (OriginTerms at that origin) when all rays share it, else
    (n, 3).  t_min, t_max: scalars or (n,).  exclude: (n,) sphere each ray must ignore, or None.
    """
    n = len(directions)
    best_t = np.full(n, np.inf, directions.dtype)
    best = np.full(n, -1, np.intp)
    if n == 0 or len(ctx.radii) == 0:
        return best_t, best
    apex, spread, axis, half = bundle_cone(origins, directions)
    max_distance = float(np.max(t_max))
    candidates = np.flatnonzero(reachable(ctx.centers, ctx.radii, apex, spread, axis, half,
                                          max_distance))
    t_min_col = t_min[:, None] if np.ndim(t_min) else t_min
    shared = terms is not None
    chunk_size = SPHERE_CHUNK if shared else OWN_ORIGIN_CHUNK
    for first in range(0, len(candidates), chunk_size):
        chunk = candidates[first:first + chunk_size]
        stats.sphere_tests += n * len(chunk)
        if shared:
            roots = shared_origin_roots(directions, terms, ctx.radii, chunk, article=ctx.article)
        else:
            roots = pair_roots(origins, directions, ctx.centers[chunk].astype(directions.dtype),
                               ctx.radii[chunk].astype(directions.dtype), article=ctx.article)
        distances = first_hit_distance(*roots, t_min_col, article=ctx.article)
        if exclude is not None:
            distances[exclude[:, None] == chunk[None, :]] = np.inf
        t, column = nearest_hits(distances, t_max)
        # Strictly nearer only: on a tie the earlier chunk (earlier in scene order) keeps it.
        better = t < best_t
        best_t[better] = t[better]
        best[better] = chunk[column[better]]
    return best_t, best


def trace_bundle(ctx: TraceContext, rays: CameraRays, stats: RayStats) -> BundleResult:
    dtype = ctx.dtype
    n = len(rays.directions)
    colour = np.zeros((n, 3), dtype)
    # Signatures feed adaptive anti-aliasing only: no work for them otherwise.
    signature = np.zeros(n, np.uint64) if ctx.settings.anti_aliasing == "adaptive" else None
    coverage = np.zeros(n, bool)
    background = ctx.arrays.background.astype(dtype)
    add_background = not ctx.article and background.any()
    reflection = ctx.materials.reflection
    max_depth = ctx.settings.max_depth
    cutoff = ctx.settings.contribution_cutoff

    path = np.arange(n)
    weight = np.ones(n, dtype)
    origins, directions = rays.origins, rays.directions
    t_min, t_max = rays.t_min, rays.t_max
    terms = ctx.camera_terms if rays.shared_origin else None
    exclude = None
    stats.camera_rays += n
    for depth in range(max_depth):
        t, sphere = nearest_sphere(ctx, origins, directions, t_min, t_max, exclude, stats, terms)
        hit = sphere >= 0
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + (sphere + 1).astype(np.uint64)
        if depth == 0:
            coverage = hit.copy()
        if add_background:
            colour[path[~hit]] += weight[~hit, None] * background
        keep = np.flatnonzero(hit)
        path, weight, t, sphere = path[keep], weight[keep], t[keep], sphere[keep]
        directions = directions[keep]
        origins = origins if len(origins) == 1 else origins[keep]
        if len(path) == 0:
            break

        points = origins + t[:, None] * directions
        normals = points - ctx.centers[sphere].astype(dtype)
        normals *= (1 / np.sqrt(np.einsum("nc,nc->n", normals, normals)))[:, None]
        cos_in = np.einsum("nc,nc->n", directions, normals)
        front = cos_in < 0
        if not ctx.article:
            # Shade the side the ray sees: inside a sphere the normal faces inwards.
            normals[~front] *= -1
            cos_in = np.where(front, cos_in, -cos_in)
        illumination, goes_on, shadow_code = shade(ctx, points, normals, directions, sphere,
                                                   front, stats)
        colour[path] += weight[:, None] * illumination
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + shadow_code

        weight = weight * reflection[sphere]
        bounces_left = max_depth - depth - 1
        goes_on &= weight * (ctx.path_gain_bound * bounces_left) > cutoff
        keep = np.flatnonzero(goes_on)
        if len(keep) == 0 or bounces_left == 0:
            break
        path, weight, sphere, front = path[keep], weight[keep], sphere[keep], front[keep]
        points, normals = points[keep], normals[keep]
        directions = directions[keep] - (2 * cos_in[keep])[:, None] * normals
        if ctx.article:
            origins = points + ARTICLE_OFFSET * normals
            exclude = None
        else:
            scale = (1 + np.abs(points).max(axis=1)) * dtype.type(RAY_EPSILON[dtype])
            origins = points + scale[:, None] * normals
            exclude = np.where(front, sphere, -1)
        t_min, t_max, terms = 0.0, np.inf, None
        stats.reflection_rays += len(path)
    return BundleResult(colour, coverage, signature)
