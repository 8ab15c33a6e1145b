"""Flat culling: the accelerator for scenes of few primitives, and for the huge spheres kept
out of a tree (``FlatSpheres``, ``FlatTriangles``), by conservative culling of which
primitives a bundle of rays can possibly hit.

A group of rays starts within a ball (centre, radius rb) and points within a cone (unit axis,
half angle).  A ray from o, |o - centre| <= rb, that hits sphere (c, r) passes within r + rb
of c when moved to start at the centre, so it suffices to test the grown sphere (c, r + rb)
against the cone from the centre: the sphere is reachable only if the angle between the axis
and (c - centre) is at most half + asin((r + rb) / |c - centre|), and its near side lies
within the rays' reach.  Spheres that contain the apex always pass.  Margins keep the test
conservative under rounding.

Two levels: the whole bundle (a tile's camera rays share their origin, so this is exactly
"can this sphere appear in this tile"), then packets of PACKET_SIZE consecutive rays (tiles
are traced in 16 x 16 pixel blocks, and compaction keeps order, so packets stay coherent).
Packets matter for secondary rays: a tile's reflection or shadow rays fan out too widely for
one cone, a packet's do not.  ``candidate_roots`` then intersects each packet only with its
own candidates.  A batch culled to a few spheres (``GeometryPolicy.dense_candidates``)
skips the packets: every ray is tested against each of them in turn (``FewSpheres``).

Triangles are culled by their bounding spheres against the whole batch's cone, then tested
in blocks of (triangle, ray) pairs that share a shear's axes (``watertight_axes``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..rays import RayBatch
from ..runs import rank_within_runs, run_starts, value_run_starts
from ..vectors import dot, length, take
from .cells import direction_cells, morton_codes
from .pairs import per_ray
from .spheres import FewSpheres, OriginTerms, offset_roots, origin_roots
from .triangles import Shear, watertight_axes

#: Slack on cosines (about 1e-6 radians of angle) that keeps culling conservative.
_COS_MARGIN = 1e-6
#: Rays per packet (a 16 x 16 pixel block of camera rays).
PACKET_SIZE = 256
#: Rays per packet of keyed (secondary) rays, whose runs of equal keys are often short.
KEYED_PACKET_SIZE = 32
#: Cube-map cells per face side for packing reflection rays (~11 degrees each) and shadow
#: rays (~1.4 degrees: their origins coincide, so direction alone decides a packet's cone).
REFLECTION_CELLS = 4
SHADOW_CELLS = 64
#: Upper bound on ray/sphere pairs per block of packets; bounds the (k, n) temporaries.
BLOCK_PAIRS = 1 << 19
#: Upper bound on (ray, triangle) pairs intersected at once; bounds the (k, n) temporaries.
TRIANGLE_BLOCK_PAIRS = 1 << 18
#: Spheres per culling cluster.
CLUSTER_SIZE = 16


def cones(origins, directions):
    """Bounding cones of P groups of R rays: (apex (3, P), spread (P,), axis (3, P), half (P,)).

    origins: (3, P, R), or (3, 1, 1) when every ray starts there; directions: (3, P, R) unit.
    spread is the half diagonal of the group's origin bounding box.
    """
    groups = directions.shape[1]
    if origins.shape[1] == 1 and origins.shape[2] == 1:
        apex = np.repeat(origins[:, 0, :].astype(np.float64), groups, axis=1)
        spread = np.zeros(groups)
    else:
        low = origins.min(axis=2).astype(np.float64)
        high = origins.max(axis=2).astype(np.float64)
        apex = (low + high) / 2
        spread = length(high - low) / 2
    mean = directions.sum(axis=2, dtype=np.float64)                     # (3, P)
    norm = length(mean)
    degenerate = norm < 1e-9 * directions.shape[2]
    axis = mean / np.where(degenerate, 1.0, norm)
    cos_half = dot(axis.astype(directions.dtype)[:, :, None], directions).min(axis=1)
    # The dot products were rounded in the render precision: widen by its epsilon.
    half = np.arccos(np.clip(cos_half, -1.0, 1.0)) + 4 * np.sqrt(np.finfo(directions.dtype).eps)
    half = np.where(degenerate, np.pi, np.minimum(half, np.pi))
    return apex, spread, axis, half


def reachable(centers, radii, apex, spread, axis, half, max_distance):
    """May a ray of a group hit a sphere within max_distance?  Broadcasting over any shape,
    vectors first: centers, apex, axis (3, ...); radii, spread, half, max_distance (...).
    Returns (...) bool.

    The groups' cones are as ``cones`` returns them; a sphere may be a cluster's bound.  The
    angle test ``angle(c - apex, axis) <= half + asin(grown / distance)`` is done on cosines
    (cos(a + b) = cos a cos b - sin a sin b), which needs no inverse trigonometry; cones wider
    than a hemisphere pass everything."""
    to_center = centers - apex
    distance = length(to_center)
    grown = radii + spread
    contains = distance <= grown
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_grown = np.minimum(grown / distance, 1.0)
        cos_limit = (np.cos(half) * np.sqrt(1.0 - sin_grown * sin_grown)
                     - np.sin(half) * sin_grown - _COS_MARGIN)
        within_cone = (half >= np.pi / 2) | (dot(to_center, axis) >= cos_limit * distance)
    near_enough = distance - grown <= (max_distance + spread) * (1 + 1e-9) + 1e-9
    return contains | (within_cone & near_enough)


@dataclass(frozen=True)
class SphereClusters:
    """Spheres grouped for culling: members (C, M) scene indices (-1 pads), their centres
    (3, C, M) and radii (C, M) (pads: radius -inf, never reachable), and each cluster's
    bounding sphere, centers (3, C) and radii (C,)."""

    members: np.ndarray
    member_centers: np.ndarray
    member_radii: np.ndarray
    centers: np.ndarray
    radii: np.ndarray


def cluster_spheres(centers, radii, huge, size: int = CLUSTER_SIZE) -> SphereClusters:
    """Clusters of ``size`` spheres neighbouring in Morton order of their centres.  A sphere
    much larger than the median (``huge`` (N,), a floor) gets a cluster of its own, so that
    it does not inflate its neighbours' bound."""
    ordinary = np.flatnonzero(~huge)
    groups = []
    if len(ordinary):
        code = morton_codes(centers[ordinary].T)
        ordered = ordinary[np.argsort(code, kind="stable")]
        groups += [ordered[i:i + size] for i in range(0, len(ordered), size)]
    groups += [np.array([i]) for i in np.flatnonzero(huge)]
    members = np.full((len(groups), size), -1, np.intp)
    bounds = np.zeros((len(groups), 3))
    bound_radii = np.zeros(len(groups))
    for row, group in enumerate(groups):
        members[row, :len(group)] = group
        bounds[row] = centers[group].mean(axis=0)
        bound_radii[row] = (np.linalg.norm(centers[group] - bounds[row], axis=1)
                            + radii[group]).max() * (1 + 1e-12)
    real = members >= 0
    member_centers = np.where(real[None], centers[np.maximum(members, 0)].transpose(2, 0, 1), 0.0)
    member_radii = np.where(real, radii[np.maximum(members, 0)], -np.inf)
    return SphereClusters(members, member_centers, member_radii, bounds.T.copy(), bound_radii)


def _packet_candidates(radii, clusters: SphereClusters, cone, reach):
    """(packet (E,), sphere (E,)): the spheres each of P packets may hit, sorted by packet,
    then scene order.  Each packet's cone is tested against the cluster bounds, then against
    the members of the clusters that pass; packets go in chunks so that the (packets,
    clusters) tests stay within BLOCK_PAIRS elements however many spheres there are."""
    apex, spread, axis, half = cone
    chunk = max(1, BLOCK_PAIRS // max(len(clusters.radii), 1))
    packets, spheres = [], []
    for first in range(0, len(half), chunk):
        part = slice(first, first + chunk)
        passed = reachable(clusters.centers[:, None, :], clusters.radii[None, :],
                           apex[:, part, None], spread[part, None], axis[:, part, None],
                           half[part, None], reach[part, None])          # (p, C)
        packet, cluster = np.nonzero(passed)
        packet += first
        # Each passing (packet, cluster) pair tests the cluster's members at once.
        hit = reachable(clusters.member_centers[:, cluster], clusters.member_radii[cluster],
                        apex[:, packet, None], spread[packet, None], axis[:, packet, None],
                        half[packet, None], reach[packet, None])          # (E, M)
        # Padding never counts (with an unbounded reach the test alone would let it pass).
        pair, member = np.nonzero(hit & (clusters.members[cluster] >= 0))
        packets.append(packet[pair])
        spheres.append(clusters.members[cluster[pair], member])
    packet, sphere = np.concatenate(packets), np.concatenate(spheres)
    order = np.argsort(packet * len(radii) + sphere)
    return packet[order], sphere[order]


def _packets(n, key, size):
    """Packets over n rays: (order (n,), starts (P,), lengths (P,)).  Without a key, runs of
    ``size`` consecutive rays; with one, rays sorted by key (stably) and cut where it changes."""
    if key is None:
        starts = np.arange(0, n, size)
        return np.arange(n), starts, np.minimum(size, n - starts)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    run_start = value_run_starts(sorted_key)
    run_length = np.diff(np.r_[run_start, n])
    pieces = -(-run_length // size)
    starts = np.repeat(run_start, pieces) + size * rank_within_runs(pieces)
    return order, starts, np.minimum(size, np.repeat(run_start + run_length, pieces) - starts)


@dataclass
class PairBlock:
    """Explicit (ray, sphere) pairs, grouped by ray: arrays (E,); segments (m,) where each of
    the block's m rays ``rays`` (m,) starts."""

    spheres: np.ndarray
    t_near: np.ndarray
    t_far: np.ndarray
    valid: np.ndarray
    rays: np.ndarray
    pair_rays: np.ndarray
    segments: np.ndarray

    def per_pair(self, values):
        return values[self.pair_rays] if np.ndim(values) else values

    def nearest(self, distances):
        t = np.minimum.reduceat(distances, self.segments)
        # The first pair per ray reaching the minimum: candidates are in scene order.
        at_minimum = np.flatnonzero(distances == np.repeat(t, np.diff(np.r_[self.segments,
                                                                            len(distances)])))
        owner = np.searchsorted(self.segments, at_minimum, side="right") - 1
        first = np.r_[True, owner[1:] != owner[:-1]]
        sphere = np.full(len(t), -1, np.intp)
        sphere[owner[first]] = self.spheres[at_minimum[first]]
        return t, np.where(np.isfinite(t), sphere, -1)

    def any(self, hits):
        return np.logical_or.reduceat(hits, self.segments)


def bundle_candidates(centers, radii, origins, directions, reach) -> np.ndarray:
    """(k,) the spheres (indices into centers (N, 3), radii (N,)) that some ray of the bundle
    may hit within ``reach`` (a scalar): the bundle's cone against every sphere.  origins
    (3, 1) or (3, n), directions (3, n) unit."""
    apex, spread, axis, half = bundle_cone(origins, directions)
    return np.flatnonzero(reachable(centers.T, radii, apex, spread, axis, half, reach))


def bundle_cone(origins, directions):
    """``cones`` of one group, the whole bundle: (apex (3, 1), spread, axis (3, 1), half),
    with the same arithmetic, but its per-group scalars in Python floats (a bundle is one
    group: NumPy calls on arrays of one element cost more than the arithmetic).
    origins (3, 1) or (3, n); directions (3, n) unit."""
    n = directions.shape[1]
    if origins.shape[1] == 1:
        apex = origins.astype(np.float64)
        spread = 0.0
    else:
        low = origins.min(axis=1).astype(np.float64)
        high = origins.max(axis=1).astype(np.float64)
        apex = ((low + high) / 2)[:, None]
        spread = float(length(high - low)) / 2
    mean = directions.sum(axis=1, dtype=np.float64)
    x, y, z = (float(v) for v in mean)
    norm = math.sqrt(x * x + y * y + z * z)
    if norm < 1e-9 * n:
        return apex, spread, np.array([[1.0], [0.0], [0.0]]), math.pi
    axis = (mean / norm)[:, None]
    cos_half = float(dot(axis.astype(directions.dtype), directions).min())
    half = math.acos(min(max(cos_half, -1.0), 1.0)) + 4 * math.sqrt(
        float(np.finfo(directions.dtype).eps))
    return apex, spread, axis, min(half, math.pi)


def candidate_roots(centers, radii, clusters: SphereClusters, origins, directions, max_distance,
                    candidates, terms: OriginTerms = None, *, textbook=False, stats=None,
                    key=None):
    """Ray/sphere roots for every pair culling cannot rule out, in blocks.

    centers (N, 3), radii (N,) in float64, and their ``clusters``; origins (3, 1) with
    ``terms`` (OriginTerms at that origin) when all rays share it, else (3, n); directions
    (3, n) unit; max_distance: scalar or (n,), how far each ray reaches; candidates: the
    bundle's (``bundle_candidates``).  key: optional (n,) integers; rays with equal keys are
    packed together (secondary rays: the sphere they leave and their direction cell).
    textbook: the article's root formula (``spheres``), else the stable one.  Yields
    ``PairBlock`` objects; every pair culling keeps appears in exactly one block, candidates
    in scene order.
    """
    n = directions.shape[1]
    if n == 0 or len(radii) == 0 or len(candidates) == 0:
        return
    dtype = directions.dtype
    shared = terms is not None
    reach = per_ray(max_distance, n)
    centers_t = centers.T
    # Packets of coherent rays, each with its own candidates; then explicit (ray, sphere)
    # pairs, so no work is spent on padding.
    order, starts, lengths = _packets(n, key, PACKET_SIZE if key is None else KEYED_PACKET_SIZE)
    size = int(lengths.max())
    slot = np.arange(size)
    padded = order[starts[:, None] + np.minimum(slot[None, :], lengths[:, None] - 1)]
    packet_origins = origins[:, None, :] if shared else origins[:, padded]
    cone = cones(packet_origins, directions[:, padded])
    pair_packet, pair_sphere = _packet_candidates(radii, clusters, cone,
                                                  reach[padded].max(axis=1))
    counts = np.bincount(pair_packet, minlength=len(starts))
    first_pair = run_starts(counts)
    # Per packet: its rays (lengths) times its candidates (counts), ray-major.
    work = lengths * counts
    block_end = np.searchsorted(np.cumsum(work), np.arange(1, work.sum() // BLOCK_PAIRS + 2)
                                * BLOCK_PAIRS, side="right")
    edges = np.unique(np.r_[0, np.minimum(block_end, len(starts)), len(starts)])
    for low, high in zip(edges[:-1], edges[1:]):
        packets = np.arange(low, high)
        packets = packets[counts[packets] > 0]
        if len(packets) == 0:
            continue
        # Rays of these packets, each repeated once per candidate of its packet.
        ray_packet = np.repeat(packets, lengths[packets])
        ray_slot = rank_within_runs(lengths[packets])
        rays = order[starts[ray_packet] + ray_slot]
        pairs_per_ray = counts[ray_packet]
        pair_owner = np.repeat(np.arange(len(rays)), pairs_per_ray)
        pair_index = (np.repeat(first_pair[ray_packet], pairs_per_ray)
                      + rank_within_runs(pairs_per_ray))
        spheres = pair_sphere[pair_index]
        pair_rays = rays[pair_owner]
        if stats is not None:
            stats.sphere_tests += len(spheres)
        pair_dirs = take(directions, pair_rays)
        if shared:
            roots = origin_roots(terms.f[spheres].T, terms.c_prime[spheres],
                                 terms.article_c[spheres], radii[spheres], pair_dirs,
                                 textbook=textbook)
        else:
            roots = offset_roots(take(origins, pair_rays) - take(centers_t, spheres).astype(dtype),
                                 pair_dirs, radii[spheres].astype(dtype), textbook=textbook)
        yield PairBlock(spheres, *roots, rays, pair_rays, run_starts(pairs_per_ray))


class FlatSpheres:
    """Spheres culled flat, with no tree: all of a scene's few spheres, or the huge ones
    (a floor) beside a tree.  spheres: the scene's (``Spheres``); ids: (f,) the ones culled
    here, ascending (None: every sphere); rules: the hit rules; policy: the
    ``GeometryPolicy``; beside_tree: whether a tree holds the other spheres."""

    def __init__(self, spheres, ids, rules, policy, beside_tree: bool):
        self.ids = ids
        every = slice(None) if ids is None else ids
        self.centers = spheres.arrays.centers[every]
        self.radii = spheres.arrays.radii[every]
        self.count = len(self.radii)
        self.textbook = spheres.textbook
        self.rules = rules
        self.dense_candidates = policy.dense_candidates
        self.clusters = cluster_spheres(self.centers, self.radii, policy.is_huge(self.radii))
        # Huge spheres beside a tree, which nearly every bundle's cone reaches: every ray
        # tests each of them without the cone, which cost more than it saved.
        self.unculled = beside_tree and self.count <= policy.unculled_beside_tree

    def terms_at(self, position) -> OriginTerms | None:
        """The spheres' terms for rays leaving ``position`` (3,), or None without spheres."""
        return OriginTerms.at(position, self.centers, self.radii) if self.count else None

    def nearest(self, rays: RayBatch, stats):
        """(t (n,), primitive (n,) global id or -1) of each ray's nearest sphere hit."""
        n = len(rays)
        best_t = np.full(n, np.inf, rays.directions.dtype)
        best = np.full(n, -1, np.intp)
        if not self.count:
            return best_t, best
        ids = self.ids
        terms = rays.shared.sphere_terms if rays.shared is not None else None
        t_min, t_max, exclude = rays.t_min, rays.t_max, rays.exclude
        candidates = self.candidates(rays)
        if len(candidates) <= self.dense_candidates:
            if len(candidates):
                stats.sphere_tests += n * len(candidates)
                self._few(rays, terms).nearest(candidates, t_min, t_max, exclude, ids, best_t,
                                               best)
            return best_t, best
        for block in candidate_roots(self.centers, self.radii, self.clusters, rays.origins,
                                     rays.directions, t_max, candidates, terms,
                                     textbook=self.textbook, stats=stats, key=self._key(rays)):
            distances = self.rules.first_hit(block.t_near, block.t_far, block.valid,
                                             block.per_pair(t_min))
            distances[~(distances < block.per_pair(t_max))] = np.inf
            if exclude is not None:
                spheres = block.spheres if ids is None else ids[block.spheres]
                distances[spheres == block.per_pair(exclude)] = np.inf
            t, sphere = block.nearest(distances)
            if ids is not None:
                sphere = np.where(sphere >= 0, ids[sphere], -1)
            # Strictly nearer only: on a tie the earlier block (earlier in scene order) keeps it.
            better = t < best_t[block.rays]
            best_t[block.rays] = np.where(better, t, best_t[block.rays])
            best[block.rays] = np.where(better, sphere, best[block.rays])
        return best_t, best

    def occluded(self, segments: RayBatch, stats) -> np.ndarray:
        """(n,) whether a sphere other than the segment's ``exclude`` blocks it (the rules'
        ``blocks``)."""
        n = len(segments)
        blocked = np.zeros(n, bool)
        if not self.count:
            return blocked
        shared = segments.shared
        terms = shared.sphere_terms if shared is not None else None
        t_min, t_max, exclude = segments.t_min, segments.t_max, segments.exclude
        ids = self.ids
        candidates = self.candidates(segments)
        if len(candidates) <= self.dense_candidates:
            if len(candidates):
                stats.sphere_tests += n * len(candidates)
                self._few(segments, terms).blocked(candidates, t_min, t_max, exclude, ids,
                                                   blocked)
            return blocked
        for block in candidate_roots(self.centers, self.radii, self.clusters, segments.origins,
                                     segments.directions, t_max, candidates, terms,
                                     textbook=self.textbook, stats=stats,
                                     key=self._key(segments)):
            low, high = block.per_pair(t_min), block.per_pair(t_max)
            hit = block.valid & self.rules.blocks(block.t_near, block.t_far, low, high)
            if exclude is not None:
                spheres = block.spheres if ids is None else ids[block.spheres]
                hit &= spheres != block.per_pair(exclude)
            blocked[block.rays] |= block.any(hit)
        return blocked

    def _key(self, rays: RayBatch):
        """(n,) the packets the culling groups rays into (None: in their order).  Rays from
        one origin (a light sample) packed by direction make narrow cones; rays leaving one
        primitive (``source``) in one direction cell cull well together."""
        if self.count <= self.dense_candidates:
            return None
        if rays.shared is not None:
            return direction_cells(rays.directions, SHADOW_CELLS)
        if rays.source is not None:
            return (rays.source * (6 * REFLECTION_CELLS ** 2)
                    + direction_cells(rays.directions, REFLECTION_CELLS))
        return None

    def candidates(self, rays: RayBatch) -> np.ndarray:
        """(k,) the spheres (local indices) some ray of the batch may reach (all of them
        where they are ``unculled``)."""
        if len(rays) == 0:
            return np.zeros(0, np.intp)
        if self.unculled:
            return np.arange(self.count)
        reach = rays.t_max if np.ndim(rays.t_max) == 0 else rays.t_max.max()
        return bundle_candidates(self.centers, self.radii, rays.origins, rays.directions,
                                 float(reach))

    def _few(self, rays: RayBatch, terms) -> FewSpheres:
        return FewSpheres(self.centers, self.radii, rays.origins, rays.directions, terms,
                          textbook=self.textbook, rules=self.rules)


class FlatTriangles:
    """Triangles tested flat, with no tree (a scene's few triangles): triangles, the scene's
    (``Triangles``); ids (t,) the ones tested here; sphere_count: the global id of triangle
    0.  A batch's candidates are the triangles whose bounding spheres its cone reaches,
    tested in blocks of one shear's axes (``watertight_axes``)."""

    def __init__(self, triangles, ids, sphere_count: int):
        self.triangles = triangles
        self.ids = ids
        self.sphere_count = sphere_count
        self.dtype = triangles.dtype

    def __len__(self) -> int:
        return len(self.ids)

    def nearest(self, rays: RayBatch, t_max_now, stats):
        """(t (n,), triangle (n,) local index or -1, (b0, b1, b2) (n,) each) of the nearest
        triangle hit nearer than ``t_max_now`` (n,) and the batch's own t_max."""
        n = len(rays)
        # Hits must beat this; it shrinks as hits are found (the blocks read it each time).
        limit = np.minimum(np.asarray(t_max_now, self.dtype), per_ray(rays.t_max, n, self.dtype))
        found_t = np.full(n, np.inf, self.dtype)
        best = np.full(n, -1, np.intp)
        bary = [np.zeros(n, self.dtype) for _ in range(3)]
        for triangles, group, t, b0, b1, b2, valid in self._blocks(rays, limit, stats):
            t = np.where(valid, t, np.inf)
            row = np.argmin(t, axis=0)
            columns = np.arange(len(group))
            nearest = t[row, columns]
            better = np.flatnonzero(nearest < limit.take(group))
            rays_better = group.take(better)
            found_t[rays_better] = nearest.take(better)
            best[rays_better] = triangles.take(row.take(better))
            for store, b in zip(bary, (b0, b1, b2)):
                store[rays_better] = b[row.take(better), better]
            limit[rays_better] = found_t.take(rays_better)   # (each below its limit)
        return found_t, best, tuple(bary)

    def occluded(self, segments: RayBatch, stats) -> np.ndarray:
        blocked = np.zeros(len(segments), bool)
        for triangles, group, t, b0, b1, b2, valid in self._blocks(segments, segments.t_max,
                                                                   stats):
            blocked[group] |= valid.any(axis=0)
        return blocked

    def _candidates(self, rays: RayBatch, reach):
        """Triangles the batch's bounding cone can reach within ``reach`` (scalar)."""
        apex, spread, axis, half = cones(rays.origins[:, None, :], rays.directions[:, None, :])
        flat = self.ids
        return flat[reachable(self.triangles.centers[:, flat], self.triangles.radii[flat], apex,
                              spread, axis, half, reach)]

    def _blocks(self, rays: RayBatch, t_max, stats):
        """Yields (triangles (k,), rays (r,) of the batch, t, b0, b1, b2, valid (k, r)) over
        candidate triangles, the rays in groups of one shear's axes (``watertight_axes``:
        at most six, by the direction's largest axis and its sign), each ray's triangles in
        candidate order.  t_max: scalar or (n,), read again for every block (a nearest-hit
        search lowers it as hits are found)."""
        n = len(rays)
        reach = per_ray(t_max, n)
        finite = reach[np.isfinite(reach)]
        limit = np.inf if len(finite) < n else (finite.max() if n else 0.0)
        candidates = self._candidates(rays, limit)
        if len(candidates) == 0 or n == 0:
            return
        shear = Shear.of(rays.directions)
        kx, ky, kz = shear.axes
        key = 3 * kz + kx                     # (kz, kx) fixes the permutation
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(key.take(order))) + 1
        shared = rays.origins.shape[1] == 1
        origins = rays.origins.astype(self.dtype, copy=False)
        t_min = np.asarray(rays.t_min, self.dtype)
        for group in np.split(order, bounds):
            first = group[0]
            axes = (int(kx[first]), int(ky[first]), int(kz[first]))
            factors = take(shear.factors, group)
            starts = origins[:, None, :] if shared else take(origins, group)[:, None, :]
            low = t_min.take(group)[None, :] if t_min.ndim else t_min
            chunk = max(1, TRIANGLE_BLOCK_PAIRS // len(group))
            for start in range(0, len(candidates), chunk):
                triangles = candidates[start:start + chunk]
                if stats is not None:
                    stats.triangle_tests += len(group) * len(triangles)
                v0, v1, v2 = (v[:, triangles][:, :, None] for v in self.triangles.v)
                high = np.asarray(t_max, self.dtype)
                high = high.take(group)[None, :] if high.ndim else high
                t, b0, b1, b2, valid = watertight_axes(v0, v1, v2, starts, axes, factors,
                                                       low, high)
                if rays.exclude is not None:
                    valid &= ((triangles + self.sphere_count)[:, None]
                              != rays.exclude.take(group)[None, :])
                yield triangles, group, t, b0, b1, b2, valid
