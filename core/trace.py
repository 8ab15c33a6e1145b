"""The tracing loop: follow a bundle of camera rays through up to max_depth bounces.

Each bounce: the nearest hits (``ctx.geometry.nearest``, the scene's one aggregate), shade
them (``core.shading``), then compact: only paths that hit something, that the article's
shadows did not end, whose material reflects, and whose remaining weight can still add more
than ``contribution_cutoff`` go on as reflection rays (``ctx.geometry.spawn``).  Rays are
(3, n) bundles (``core.vectors``); nothing per pixel runs in Python, and nothing here knows
how the geometry finds its hits.

Alpha and holdouts follow Cycles: a ray is on the camera's path while it is the camera ray or
went on from it only straight through Transparent BSDFs (``Branch.straight``).  Such a ray that
escapes makes the average of its weight's channels of its sample transparent (unless
``RenderSettings.film`` is 'opaque'), and with film 'transparent' adds no background; one that
meets a holdout makes ``holdout`` x that average transparent (an object holdout: all but its
transparency, through which the ray goes on, and nothing of its shading shows).  Rays off the
camera's path (mirrors, refraction, shadows) see a Holdout shader black and a holdout object
as its material.  Alpha = 1 - transparency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import CameraRays
from .context import RayStats, TraceContext
from .failures import RenderCancelled
from .bsdf import held_share, scatter
from .rays import RayBatch
from .sampler import hash_u32
from .shading import shade_translucent
from .vectors import facing, take

_SIGNATURE_PRIME = np.uint64(1_000_003)
#: Rays per camera ray a bounce may spawn by splitting at glass and mirrors (reflected and
#: refracted rays both followed); beyond it each hit follows one of its branches, chosen in
#: proportion to its weight and weighted by the inverse of that chance.  Nested glass would
#: otherwise double the rays at every bounce (2^depth); with the budget a bounce traces at
#: most this many rays a camera ray, so time and memory grow with the depth, not its power.
#: 4 leaves a glass ball at the default depth of 3 (at most 4 rays a camera ray) split
#: exactly.
BRANCH_BUDGET = 4


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
    """colour (3, n) unclipped; alpha (n,) 1 - the sample's transparency (module docstring:
    0 where the camera ray escaped or met a full holdout, 1 where it hit something opaque);
    signature (n,) uint64 hash of what the path hit (spheres and shadowing at every bounce):
    neighbours with different signatures straddle an edge; None unless adaptive AA asks.
    primary: PrimaryHits when asked for (``trace_bundle(record_primary=True)``), else None.
    world_noise: (3, n) the standard deviation of the colour's estimate of the world's
    occlusion along each path (``shade``'s world_noise, weighted as the colour; summed over
    the bounces, an upper bound), for pixel centres where adaptive AA asks and the world's
    occlusion is traced; else None."""

    colour: np.ndarray
    alpha: np.ndarray
    signature: np.ndarray | None
    primary: PrimaryHits | None = None
    emission: np.ndarray | None = None   # (3, n) record_emission: see trace_bundle
    world_noise: np.ndarray | None = None   # (3, n) see the docstring


def _accumulate(colour, path, values, unique: bool, whole: bool):
    """colour[:, path] += values (3, k); paths repeat once rays split (refraction), and then
    every repeat must add."""
    if whole:
        colour += values
    elif unique:
        for row in range(3):   # (row by row: half the time of one (3, k) fancy index)
            colour[row, path] += values[row]
    else:
        for row in range(3):
            colour[row] += np.bincount(path, values[row], colour.shape[1])


def _accumulate_scalar(total, path, values, unique: bool):
    """total[path] += values (k,), every repeat of a path index adding."""
    if unique:
        total[path] += values
    else:
        total += np.bincount(path, values, total.shape[0]).astype(total.dtype)


def _mean_channel(weight):
    """The average of a weight's channels (k,): Cycles' ``average`` of a throughput."""
    return weight.mean(axis=0) if weight.ndim == 2 else weight


def trace_bundle(ctx: TraceContext, rays: CameraRays, stats: RayStats,
                 record_primary: bool = False, record_emission: bool = False,
                 primary_only: bool = False, stop=None) -> BundleResult:
    """Follow the bundle: article semantics as the article does (one mirror ray per hit, a
    scalar weight); the physically based model (``ctx.physical``) with colour weights and,
    where ``core.bsdf`` says so, several secondary rays per hit (mirror, refraction,
    straight through).  record_emission: also sum, into ``BundleResult.emission``, the
    emission the camera's path meets (module docstring: the camera ray and what it sees
    straight through Transparent BSDFs, weighted; not what mirrors or refraction show), as
    Cycles' Emission pass does.  primary_only (with record_primary): stop at the first
    hits, recorded and not shaded (the render passes' depth, normals and indices need
    nothing more; the colour is then left black).  stop: a threading.Event; once set, the
    bundle raises RenderCancelled at its next bounce (a deep bundle of glass takes seconds)."""
    dtype = ctx.dtype
    geometry = ctx.geometry
    n = rays.directions.shape[1]
    primary = PrimaryHits.missed(n, dtype) if record_primary else None
    colour = np.zeros((3, n), dtype)
    # Signatures feed adaptive anti-aliasing only: no work for them otherwise.
    signature = np.zeros(n, np.uint64) if ctx.settings.anti_aliasing == "adaptive" else None
    transparency = np.zeros(n, dtype)
    emission = np.zeros((3, n), dtype) if record_emission else None
    film = ctx.settings.film
    background = ctx.background.astype(dtype)[:, None]
    shading = ctx.shading   # the article's or Glint's own (``core.shading``)
    add_background = shading.sees_background and background.any()
    reflection = ctx.materials.reflection
    physical = ctx.physical
    max_depth = ctx.settings.max_depth
    cutoff = ctx.settings.contribution_cutoff

    path = np.arange(n)
    shares, world_shift = rays.shares, rays.world_shift
    # How noisy each centre's world occlusion is (``BundleResult.world_noise``), for adaptive
    # AA's edge test.
    world_noise = (np.zeros((3, n), dtype) if signature is not None and world_shift is not None
                   and shares is None else None)
    unique = True   # every path index appears once (until rays split)
    camera_path = np.ones(n, bool)   # per ray of the batch: the camera's view (docstring)
    holdouts = physical is not None and physical.surfaces.any_holdout
    # (n,) in article semantics and for the article's materials alone; (3, n) colour weights
    # for the physically based model.
    weight = np.ones((3, n) if physical is not None else n, dtype)
    batch = RayBatch(rays.origins, rays.directions, rays.t_min, rays.t_max,
                     ctx.camera_origin if rays.shared_origin else None)
    stats.camera_rays += n
    for depth in range(max_depth):
        if depth and stop is not None and stop.is_set():
            raise RenderCancelled("render cancelled")
        hits = geometry.nearest(batch, stats)
        if signature is not None:
            signature[path] = (signature[path] * _SIGNATURE_PRIME
                               + geometry.surface_keys(hits.primitive_per_ray))
        if len(hits) < len(batch):
            missed = np.flatnonzero(hits.primitive_per_ray < 0)
            escaped = missed[camera_path[missed]]
            if film != "opaque" and len(escaped):
                _accumulate_scalar(transparency, path[escaped],
                                   _mean_channel(weight[..., escaped]), unique)
            if add_background:
                shown = missed[~camera_path[missed]] if film == "transparent" else missed
                _accumulate(colour, path[shown], weight[..., shown] * background, unique,
                            False)
        if len(hits) == 0:
            break
        if len(hits) < len(batch):
            path, weight = path[hits.rays], weight[..., hits.rays]
            camera_path = camera_path[hits.rays]

        points, directions, primitive = hits.points, hits.directions, hits.primitive
        geometric, normals, front, cos_in = hits.normals, hits.shading, hits.front, hits.cos_in
        if shading.shades_seen_side and not front.all():
            # Shade the side the ray sees: inside a sphere, behind a triangle, the normal
            # faces the other way.
            normals = facing(normals, front)
            cos_in = np.where(front, cos_in, -cos_in)
        if primary is not None and depth == 0:
            primary.t[path], primary.normal[:, path] = hits.t, normals
            primary.primitive[path], primary.material[path] = primitive, hits.material
            if primary_only:
                break
        exclude = geometry.exclusions(primitive, front) if geometry.rules.excludes else None
        point_shares = None if shares is None else shares.take(path)
        point_shift = None if world_shift is None else world_shift[path]
        noise = None if world_noise is None else np.zeros_like(points)
        illumination, goes_on, shadow_code = shading.shade(ctx, points, normals, directions,
                                                           hits.material, exclude, stats,
                                                           shares=point_shares,
                                                           terminator=hits.terminator,
                                                           world_shift=point_shift,
                                                           world_noise=noise)
        if physical is not None and physical.translucent is not None:
            through, code = shade_translucent(ctx, points, normals, directions, hits.material,
                                              geometry.exclusions(primitive, ~front), stats,
                                              shares=point_shares, world_shift=point_shift,
                                              world_noise=noise)
            illumination += through
            shadow_code = shadow_code * _SIGNATURE_PRIME + code  # edges of light shone through
        illumination *= weight
        held_object = None
        if holdouts and camera_path.any():
            held_object = _hold_out(physical.surfaces, hits.material, camera_path, path,
                                    weight, transparency, unique)
            if held_object is not None:
                illumination[:, held_object] = 0
                if noise is not None:
                    noise[:, held_object] = 0
        if emission is not None and physical is not None and physical.surfaces.any_emission:
            seen = np.flatnonzero(camera_path)
            if held_object is not None:
                seen = np.setdiff1d(seen, held_object, assume_unique=True)
            _accumulate(emission, path[seen],
                        take(physical.surfaces.emission, hits.material[seen])
                        * weight[:, seen], unique, False)
        _accumulate(colour, path, illumination, unique, depth == 0 and len(path) == n)
        if noise is not None:
            _accumulate(world_noise, path, noise * weight, unique, False)
        if signature is not None:
            signature[path] = signature[path] * _SIGNATURE_PRIME + shadow_code

        bounces_left = max_depth - depth - 1
        if physical is not None:
            if bounces_left == 0:
                break
            batch = _secondary_rays(ctx, physical, hits, normals, cos_in, path, weight,
                                    bounces_left, cutoff, camera_path, held_object,
                                    _arrived_from(batch), BRANCH_BUDGET * n)
            if batch is None:
                break
            batch, path, weight, camera_path = batch
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
        reflected = normals * (2 * cos_in)
        directions = np.subtract(directions, reflected, out=reflected)
        # Reflections leave on the side the ray came from.
        batch = geometry.spawn(points, geometric, primitive, directions, front,
                               _arrived_from(batch))
        camera_path = np.zeros(len(path), bool)  # mirror rays
        stats.reflection_rays += len(path)
    alpha = np.subtract(1, transparency, out=transparency)
    # clipped to [0, 1] (as np.clip, without its Python wrapper's cost on every bundle)
    np.minimum(np.maximum(alpha, 0, out=alpha), 1, out=alpha)
    return BundleResult(colour, alpha, signature, primary, emission, world_noise)


def traces_bounces(ctx: TraceContext) -> bool:
    """Whether the frame's rays may leave hit points as secondary rays (``trace_bundle``):
    bounces allowed (max_depth > 1) and a material that sends rays on, a mirror weight
    (the article's ``reflection``) or, with the physically based model, a mirror lobe,
    transmission or transparency (``core.bsdf.scatter``'s branches)."""
    if ctx.settings.max_depth <= 1:
        return False
    physical = ctx.physical
    if physical is None:
        return bool(np.any(ctx.materials.reflection > 0))
    surfaces = physical.surfaces
    return bool(np.any(surfaces.reflection > 0) or surfaces.mirror.any()
                or surfaces.any_through)


def _arrived_from(batch: RayBatch):
    """The point every ray of the batch left (a perspective camera's eye), or None: where
    the rays the batch's hits spawn arrived from (``RayBatch.arrived_from``)."""
    return None if batch.shared is None else batch.shared.position


def _hold_out(surfaces, materials, camera_path, path, weight, transparency, unique):
    """Add what the holdouts hit on the camera's path take of their samples to transparency
    (module docstring); the indices (k,) of the hits on holdout objects, whose shading the
    camera does not see, or None."""
    viewed = np.flatnonzero(camera_path)
    material = materials[viewed]
    holdout, whole = surfaces.holdout[material], surfaces.holdout_object[material]
    if not (holdout.any() or whole.any()):
        return None
    held = held_share(holdout, whole, take(surfaces.transparency, material), weight[:, viewed])
    _accumulate_scalar(transparency, path[viewed], held, unique)
    return viewed[whole] if whole.any() else None


def _secondary_rays(ctx, physical, hits, normals, cos_in, path, weight, bounces_left, cutoff,
                    camera_path, held_object=None, arrived_from=None, budget=np.inf):
    """The next bounce's rays of the physically based model (``core.bsdf.scatter``), or
    None: (RayBatch, path (k,), weight (3, k), camera_path (k,)).  Mirror rays leave on the
    side the ray came from; refracted and straight-through rays on the other
    (``Aggregate.spawn``).  camera_path (m,): which hits the camera sees (module docstring);
    held_object: indices of hits on holdout objects, which only pass their transparency on;
    arrived_from: ``RayBatch.arrived_from`` of the rays spawned.  budget: the most rays the
    bounce may spawn by splitting; beyond it each hit sends one of its branches on
    (``_one_branch_each``)."""
    branches = scatter(physical.surfaces, normals, hits.directions, cos_in, hits.material,
                       hits.front)
    blocked = None
    if held_object is not None:
        blocked = np.zeros(len(path), bool)
        blocked[held_object] = True
    candidates = []
    for branch in branches:
        w = weight[:, branch.index] * branch.weights
        going = w.max(axis=0) * (ctx.path_gain_bound * bounces_left) > cutoff
        if blocked is not None and not branch.straight:
            going &= ~blocked[branch.index]
        alive = np.flatnonzero(going)
        if len(alive):
            candidates.append((branch, alive, branch.index[alive], w[:, alive]))
    if sum(len(index) for _, _, index, _ in candidates) > budget and len(candidates) > 1:
        candidates = _one_branch_each(candidates, hits.points, len(path), bounces_left)
    parts = []
    for branch, alive, index, w in candidates:
        front = hits.front[index]
        rays = ctx.geometry.spawn(take(hits.points, index), take(hits.normals, index),
                                  hits.primitive[index], take(branch.directions, alive),
                                  ~front if branch.through else front, arrived_from)
        seen = camera_path[index] if branch.straight else np.zeros(len(index), bool)
        parts.append((rays, path[index], w, seen))
    if not parts:
        return None
    if len(parts) == 1:
        return parts[0]
    joined = RayBatch(np.concatenate([p[0].origins for p in parts], axis=1),
                      np.concatenate([p[0].directions for p in parts], axis=1),
                      exclude=np.concatenate([p[0].exclude for p in parts]),
                      source=np.concatenate([p[0].source for p in parts]),
                      arrived_from=arrived_from)
    return (joined, np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts], axis=1), np.concatenate([p[3] for p in parts]))


def _one_branch_each(candidates, points, m: int, bounces_left: int):
    """The candidates (branch, alive, index (k,) into the m hits, weight (3, k)), reduced to
    one branch per hit: chosen with probability in proportion to the mean of its weight's
    channels, its weight divided by that probability (unbiased).  The choice hashes the hit
    point's float32 bits and the bounce, so it is the same for any tiling, thread or
    process."""
    hit = np.concatenate([index for _, _, index, _ in candidates])
    part = np.concatenate([np.full(len(index), j) for j, (_, _, index, _) in
                           enumerate(candidates)])
    position = np.concatenate([np.arange(len(index)) for _, _, index, _ in candidates])
    share = np.concatenate([w.mean(axis=0) for _, _, _, w in candidates]).astype(np.float64)
    order = np.lexsort((part, hit))
    hit, part, position, share = hit[order], part[order], position[order], share[order]
    total = np.bincount(hit, share, minlength=m)
    first = np.r_[True, hit[1:] != hit[:-1]]
    last = np.r_[hit[1:] != hit[:-1], True]
    after = np.cumsum(share)
    before = after - share
    base = before[first][np.cumsum(first) - 1]
    bits = np.ascontiguousarray(points, np.float32).view(np.uint32)
    key = hash_u32(bits[2] ^ hash_u32(bits[1] ^ hash_u32(bits[0] ^ np.uint32(bounces_left))))
    u = (key >> np.uint32(8)).astype(np.float64) * 2.0 ** -24   # [0, 1)
    target = u[hit] * total[hit]
    chosen = (before - base <= target) & ((target < after - base) | last)
    reduced = []
    for j, (branch, alive, index, w) in enumerate(candidates):
        mine = chosen & (part == j)
        keep = np.sort(position[mine])
        scale = (total[hit[mine]] / share[mine])[np.argsort(position[mine])]
        reduced.append((branch, alive[keep], index[keep],
                        w[:, keep] * scale.astype(w.dtype)))
    return [c for c in reduced if len(c[2])]
