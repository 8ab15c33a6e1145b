"""The tracing loop: follow a bundle of camera rays through up to max_depth bounces.

Each bounce: the nearest hits (``ctx.geometry.nearest``, the scene's one aggregate), shade
them (``core.shading``), then compact: only paths that hit something, that the article's
shadows did not end, whose material reflects, and whose remaining weight can still add more
than ``contribution_cutoff`` go on as reflection rays (``ctx.geometry.spawn``).  Rays are
(3, n) bundles (``core.vectors``); nothing per pixel runs in Python, and nothing here knows
how the geometry finds its hits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import CameraRays
from .context import RayStats, TraceContext
from .bsdf import scatter
from .rays import RayBatch, SharedOrigin
from .shading import shade
from .vectors import take

_SIGNATURE_PRIME = np.uint64(1_000_003)


@dataclass
class PrimaryHits:
    """What each camera ray hit first (render passes), read at depth 0 of the bounce loop:
    t (n,) distance along the ray (inf: missed), primitive and material (n,) global ids (-1:
    none), normal (3, n) unit shading normal facing the ray (0 where missed)."""

    t: np.ndarray
    primitive: np.ndarray
    material: np.ndarray
    normal: np.ndarray

    @classmethod
    def missed(cls, n: int, dtype) -> "PrimaryHits":
        return cls(np.full(n, np.inf, dtype), np.full(n, -1, np.intp), np.full(n, -1, np.intp),
                   np.zeros((3, n), dtype))


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
                   stats: RayStats, terms=None):
    """Nearest hit per ray, (t (n,), primitive (n,), -1 for none), for a bare batch: origins
    (3, 1) with ``terms`` (``core.intersect.OriginTerms`` at that origin) when all rays share
    it, else (3, n); directions (3, n); t_min, t_max: scalars or (n,); exclude: (n,) or None.
    (The numerical tests' entry point; the tracer itself calls ``ctx.geometry.nearest``.)"""
    shared = None
    if terms is not None:
        shared = SharedOrigin(np.asarray(origins[:, 0], np.float64), terms)
    t, primitive, _ = ctx.geometry.intersect(
        RayBatch(origins, directions, t_min, t_max, shared, exclude), stats)
    return t, primitive


def _accumulate(colour, path, values, unique: bool, whole: bool):
    """colour[:, path] += values (3, k); paths repeat once rays split (refraction), and then
    every repeat must add."""
    if whole:
        colour += values
    elif unique:
        colour[:, path] += values
    else:
        for row in range(3):
            colour[row] += np.bincount(path, values[row], colour.shape[1])


def trace_bundle(ctx: TraceContext, rays: CameraRays, stats: RayStats,
                 record_primary: bool = False) -> BundleResult:
    """Follow the bundle: article semantics as the article does (one mirror ray per hit, a
    scalar weight); default semantics with Blender's look (``ctx.look``) with colour weights
    and, where ``core.bsdf`` says so, several secondary rays per hit (mirror, refraction,
    straight through)."""
    dtype = ctx.dtype
    geometry = ctx.geometry
    n = rays.directions.shape[1]
    primary = PrimaryHits.missed(n, dtype) if record_primary else None
    colour = np.zeros((3, n), dtype)
    # Signatures feed adaptive anti-aliasing only: no work for them otherwise.
    signature = np.zeros(n, np.uint64) if ctx.settings.anti_aliasing == "adaptive" else None
    coverage = np.zeros(n, bool)
    background = ctx.background.astype(dtype)[:, None]
    add_background = not ctx.article and background.any()
    reflection = ctx.materials.reflection
    look = None if ctx.article or ctx.look is None or not ctx.look.active else ctx.look
    max_depth = ctx.settings.max_depth
    cutoff = ctx.settings.contribution_cutoff

    path = np.arange(n)
    shares = None if ctx.article else rays.shares   # the article's lights are points
    unique = True   # every path index appears once (until rays split)
    # (n,) in article semantics and for the article's materials alone; (3, n) colour weights
    # for Blender's look.
    weight = np.ones((3, n) if look is not None else n, dtype)
    batch = RayBatch(rays.origins, rays.directions, rays.t_min, rays.t_max,
                     ctx.camera_origin if rays.shared_origin else None)
    stats.camera_rays += n
    for depth in range(max_depth):
        hits = geometry.nearest(batch, stats)
        if signature is not None:
            signature[path] = (signature[path] * _SIGNATURE_PRIME
                               + geometry.surface_keys(hits.primitive_per_ray))
        if depth == 0:
            coverage = hits.primitive_per_ray >= 0
        if add_background and len(hits) < len(batch):
            missed = np.flatnonzero(hits.primitive_per_ray < 0)
            _accumulate(colour, path[missed], weight[..., missed] * background, unique, False)
        if len(hits) == 0:
            break
        if len(hits) < len(batch):
            path, weight = path[hits.rays], weight[..., hits.rays]

        points, directions, primitive = hits.points, hits.directions, hits.primitive
        geometric, normals, front, cos_in = hits.normals, hits.shading, hits.front, hits.cos_in
        if not ctx.article and not front.all():
            # Shade the side the ray sees: inside a sphere, behind a triangle, the normal
            # faces the other way.
            normals = normals * np.where(front, 1, -1).astype(dtype)
            cos_in = np.where(front, cos_in, -cos_in)
        if primary is not None and depth == 0:
            primary.t[path], primary.normal[:, path] = hits.t, normals
            primary.primitive[path], primary.material[path] = primitive, hits.material
        exclude = None if ctx.article else geometry.exclusions(primitive, front)
        illumination, goes_on, shadow_code = shade(
            ctx, points, normals, directions, hits.material, exclude, stats,
            shares=None if shares is None else shares.take(path))
        illumination *= weight
        _accumulate(colour, path, illumination, unique, depth == 0 and len(path) == n)
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + shadow_code

        bounces_left = max_depth - depth - 1
        if look is not None:
            if bounces_left == 0:
                break
            batch = _secondary_rays(ctx, look, hits, normals, cos_in, path, weight,
                                    bounces_left, cutoff)
            if batch is None:
                break
            batch, path, weight = batch
            unique = unique and len(np.unique(path)) == len(path)
            stats.reflection_rays += len(path)
            continue
        weight = weight * reflection.take(hits.material)
        if bounces_left == 0:
            break
        goes_on &= weight * (ctx.path_gain_bound * bounces_left) > cutoff
        keep = np.flatnonzero(goes_on)
        if len(keep) == 0:
            break
        if len(keep) < len(goes_on):
            path, weight, primitive, front = path[keep], weight[keep], primitive[keep], front[keep]
            points, directions, cos_in = take(points, keep), take(directions, keep), cos_in[keep]
            shared_normals = normals is geometric
            geometric = take(geometric, keep)
            normals = geometric if shared_normals else take(normals, keep)
        directions = directions - (2 * cos_in) * normals
        # Reflections leave on the side the ray came from.
        batch = geometry.spawn(points, geometric, primitive, directions, front)
        stats.reflection_rays += len(path)
    return BundleResult(colour, coverage, signature, primary)


def _secondary_rays(ctx, look, hits, normals, cos_in, path, weight, bounces_left, cutoff):
    """The next bounce's rays for Blender's look (``core.bsdf.scatter``), or None:
    (RayBatch, path (k,), weight (3, k)).  Mirror rays leave on the side the ray came from;
    refracted and straight-through rays on the other (``Aggregate.spawn``)."""
    branches = scatter(look.surfaces, normals, hits.directions, cos_in, hits.material,
                       hits.front)
    parts = []
    for branch in branches:
        w = weight[:, branch.index] * branch.weights
        alive = np.flatnonzero(w.max(axis=0) * (ctx.path_gain_bound * bounces_left) > cutoff)
        if len(alive) == 0:
            continue
        index = branch.index[alive]
        front = hits.front[index]
        rays = ctx.geometry.spawn(take(hits.points, index), take(hits.normals, index),
                                  hits.primitive[index], take(branch.directions, alive),
                                  ~front if branch.through else front)
        parts.append((rays, path[index], w[:, alive]))
    if not parts:
        return None
    if len(parts) == 1:
        return parts[0]
    joined = RayBatch(np.concatenate([p[0].origins for p in parts], axis=1),
                      np.concatenate([p[0].directions for p in parts], axis=1),
                      exclude=np.concatenate([p[0].exclude for p in parts]),
                      source=np.concatenate([p[0].source for p in parts]))
    return (joined, np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts], axis=1))
