"""The tracing loop: follow a bundle of camera rays through up to max_depth bounces.

Each bounce: nearest hit among the spheres the bundle can reach (``core.cull``), shade the
hits (``core.shading``), then compact: only paths that hit something, that the article's
shadows did not end, whose material reflects, and whose remaining weight can still add more
than ``contribution_cutoff`` go on as reflection rays.  Rays are (3, n) bundles
(``core.vectors``); nothing per pixel runs in Python.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import CameraRays
from .context import ARTICLE_OFFSET, RayStats, TraceContext, ray_offsets
from .cull import DENSE_CANDIDATES, REFLECTION_CELLS, candidate_roots, direction_cells
from .intersect import first_hit_distance
from .shading import shade
from .vectors import dot, take

_SIGNATURE_PRIME = np.uint64(1_000_003)


@dataclass
class PrimaryHits:
    """What each camera ray hit first (render passes), read at depth 0 of the bounce loop:
    t (n,) distance along the ray (inf: missed), sphere (n,) scene sphere index (-1: none),
    normal (3, n) unit shading normal facing the ray (0 where missed)."""

    t: np.ndarray
    sphere: np.ndarray
    normal: np.ndarray

    @classmethod
    def missed(cls, n: int, dtype) -> "PrimaryHits":
        return cls(np.full(n, np.inf, dtype), np.full(n, -1, np.intp), np.zeros((3, n), dtype))


@dataclass
class BundleResult:
    """colour (3, n) unclipped; coverage (n,) whether the camera ray hit a sphere;
    signature (n,) uint64 hash of what the path hit (spheres and shadowing at every bounce):
    neighbours with different signatures straddle an edge; None unless adaptive AA asks.
    primary: PrimaryHits when asked for (``trace_bundle(record_primary=True)``), else None."""

    colour: np.ndarray
    coverage: np.ndarray
    signature: np.ndarray | None
    primary: PrimaryHits | None = None


def nearest_sphere(ctx: TraceContext, origins, directions, t_min, t_max, exclude,
                   stats: RayStats, terms=None, key=None):
    """Nearest hit per ray: (t (n,), scene sphere index (n,), -1 for none).

    origins (3, 1) with ``terms`` (OriginTerms at that origin) when all rays share it, else
    (3, n); directions (3, n).  t_min, t_max: scalars or (n,).  exclude: (n,) sphere each ray
    must ignore (-1: none), or None.  key: optional (n,) packing key (``cull.candidate_roots``).
    """
    n = directions.shape[1]
    best_t = np.full(n, np.inf, directions.dtype)
    best = np.full(n, -1, np.intp)
    for block in candidate_roots(ctx.centers, ctx.radii, ctx.clusters, origins, directions,
                                 t_max, terms, article=ctx.article, stats=stats, key=key):
        distances = first_hit_distance(block.t_near, block.t_far, block.valid,
                                       block.per_pair(t_min), article=ctx.article)
        distances[~(distances < block.per_pair(t_max))] = np.inf
        if exclude is not None:
            distances[block.spheres == block.per_pair(exclude)] = np.inf
        t, sphere = block.nearest(distances)
        # Strictly nearer only: on a tie the earlier block (earlier in scene order) keeps it.
        better = t < best_t[block.rays]
        best_t[block.rays] = np.where(better, t, best_t[block.rays])
        best[block.rays] = np.where(better, sphere, best[block.rays])
    return best_t, best


def trace_bundle(ctx: TraceContext, rays: CameraRays, stats: RayStats,
                 record_primary: bool = False) -> BundleResult:
    dtype = ctx.dtype
    n = rays.directions.shape[1]
    primary = PrimaryHits.missed(n, dtype) if record_primary else None
    colour = np.zeros((3, n), dtype)
    # Signatures feed adaptive anti-aliasing only: no work for them otherwise.
    signature = np.zeros(n, np.uint64) if ctx.settings.anti_aliasing == "adaptive" else None
    coverage = np.zeros(n, bool)
    background = ctx.arrays.background.astype(dtype)[:, None]
    add_background = not ctx.article and background.any()
    reflection = ctx.materials.reflection
    max_depth = ctx.settings.max_depth
    cutoff = ctx.settings.contribution_cutoff

    path = np.arange(n)
    weight = np.ones(n, dtype)
    origins, directions = rays.origins, rays.directions
    t_min, t_max = rays.t_min, rays.t_max
    terms = ctx.camera_terms if rays.shared_origin else None
    exclude = key = None
    stats.camera_rays += n
    for depth in range(max_depth):
        t, sphere = nearest_sphere(ctx, origins, directions, t_min, t_max, exclude, stats, terms,
                                   key)
        hit = sphere >= 0
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + (sphere + 1).astype(np.uint64)
        if depth == 0:
            coverage = hit.copy()
        if add_background and not hit.all():
            missed = np.flatnonzero(~hit)
            colour[:, path[missed]] += weight[missed] * background
        keep = np.flatnonzero(hit)
        if len(keep) == 0:
            break
        if len(keep) < len(hit):
            path, weight, t, sphere = path[keep], weight[keep], t[keep], sphere[keep]
            directions = take(directions, keep)
            origins = origins if origins.shape[1] == 1 else take(origins, keep)

        points = origins + t * directions
        normals = points - take(ctx.centers_t, sphere)
        normals *= 1 / np.sqrt(dot(normals, normals))
        cos_in = dot(directions, normals)
        front = cos_in < 0
        if not ctx.article and not front.all():
            # Shade the side the ray sees: inside a sphere the normal faces inwards.
            normals *= np.where(front, 1, -1).astype(dtype)
            cos_in = np.where(front, cos_in, -cos_in)
        if primary is not None and depth == 0:
            primary.t[path], primary.sphere[path], primary.normal[:, path] = t, sphere, normals
        illumination, goes_on, shadow_code = shade(ctx, points, normals, directions, sphere,
                                                   front, stats)
        illumination *= weight
        if depth == 0 and len(path) == n:
            colour += illumination
        else:
            colour[:, path] += illumination
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + shadow_code

        weight = weight * reflection.take(sphere)
        bounces_left = max_depth - depth - 1
        if bounces_left == 0:
            break
        goes_on &= weight * (ctx.path_gain_bound * bounces_left) > cutoff
        keep = np.flatnonzero(goes_on)
        if len(keep) == 0:
            break
        if len(keep) < len(goes_on):
            path, weight, sphere, front = path[keep], weight[keep], sphere[keep], front[keep]
            points, normals = take(points, keep), take(normals, keep)
            directions, cos_in = take(directions, keep), cos_in[keep]
        directions = directions - (2 * cos_in) * normals
        if ctx.article:
            origins = points + ARTICLE_OFFSET * normals
            exclude = None
        else:
            origins = points + ray_offsets(points) * normals
            exclude = np.where(front, sphere, -1)
        t_min, t_max, terms = 0.0, np.inf, None
        if len(ctx.radii) > DENSE_CANDIDATES:
            # Reflection rays leaving one sphere in one direction cell cull well together.
            key = (sphere * (6 * REFLECTION_CELLS ** 2)
                   + direction_cells(directions, REFLECTION_CELLS))
        stats.reflection_rays += len(path)
    return BundleResult(colour, coverage, signature, primary)
