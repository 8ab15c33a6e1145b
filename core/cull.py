"""Conservative culling: which spheres a bundle of rays can possibly hit.

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
own candidates, padded to the longest list in a block of packets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .intersect import OriginTerms, offset_roots, origin_roots
from .runs import rank_within_runs, run_starts, value_run_starts
from .vectors import dot, length, take

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
#: With at most this many bundle-level candidates, one dense pass beats per-packet culling.
DENSE_CANDIDATES = 8
#: Upper bound on ray/sphere pairs per block of packets; bounds the (k, n) temporaries.
BLOCK_PAIRS = 1 << 19
#: Spheres per culling cluster, and how much larger than the median a sphere must be to get
#: a cluster of its own.
CLUSTER_SIZE = 16
HUGE_RADIUS_RATIO = 8.0


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


def _spread_bits(values):
    """Insert two zero bits after each of the low 10 bits (for 3-D Morton codes)."""
    values = values.astype(np.uint32) & 0x3FF
    values = (values | (values << 16)) & 0x030000FF
    values = (values | (values << 8)) & 0x0300F00F
    values = (values | (values << 4)) & 0x030C30C3
    return (values | (values << 2)) & 0x09249249


def cluster_spheres(centers, radii, size: int = CLUSTER_SIZE) -> SphereClusters:
    """Clusters of ``size`` spheres neighbouring in Morton order of their centres.  A sphere
    much larger than the median (a floor) gets a cluster of its own, so that it does not
    inflate its neighbours' bound."""
    count = len(radii)
    huge = radii > HUGE_RADIUS_RATIO * np.median(radii) if count else np.zeros(0, bool)
    ordinary = np.flatnonzero(~huge)
    groups = []
    if len(ordinary):
        points = centers[ordinary]
        low, extent = points.min(axis=0), np.ptp(points, axis=0)
        cells = ((points - low) / np.where(extent > 0, extent, 1) * 1023).astype(np.uint32)
        code = (_spread_bits(cells[:, 0]) | (_spread_bits(cells[:, 1]) << 1)
                | (_spread_bits(cells[:, 2]) << 2))
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


def _per_ray(values, n):
    return np.broadcast_to(np.asarray(values, np.float64), (n,))


def direction_cells(directions, cells):
    """(n,) cube-map cell of each unit direction (3, n): cells x cells cells on each of the six
    faces, so rays sharing a cell point within about 90 / cells degrees of each other."""
    major = np.argmax(np.abs(directions), axis=0)
    columns = np.arange(directions.shape[1])
    along = directions[major, columns]
    u = directions[(major + 1) % 3, columns] / np.abs(along)
    v = directions[(major + 2) % 3, columns] / np.abs(along)
    face = 2 * major + (along < 0)
    cell_u = np.minimum(((u + 1) * (cells / 2)).astype(np.intp), cells - 1)
    cell_v = np.minimum(((v + 1) * (cells / 2)).astype(np.intp), cells - 1)
    return (face * cells + cell_u) * cells + cell_v


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
class DenseBlock:
    """Every one of the bundle's rays against the same k spheres: arrays (k, n)."""

    spheres: np.ndarray        # (k, 1) scene indices
    t_near: np.ndarray
    t_far: np.ndarray
    valid: np.ndarray
    rays: slice

    def per_pair(self, values):
        """A per-ray array (n,) (or a scalar) as per-pair values."""
        return values[self.rays][None, :] if np.ndim(values) else values

    def nearest(self, distances):
        """(t (n,), sphere (n,) or -1) of the smallest distance per ray (scene order on ties)."""
        row = np.argmin(distances, axis=0)
        t = np.take_along_axis(distances, row[None, :], axis=0)[0]
        return t, np.where(np.isfinite(t), self.spheres[row, 0], -1)

    def any(self, hits):
        return hits.any(axis=0)


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
                    terms: OriginTerms = None, *, textbook=False, stats=None, key=None,
                    candidates=None):
    """Ray/sphere roots for every pair culling cannot rule out, in blocks.

    centers (N, 3), radii (N,) in float64, and their ``clusters``; origins (3, 1) with
    ``terms`` (OriginTerms at that origin) when all rays share it, else (3, n); directions
    (3, n) unit; max_distance: scalar or (n,), how far each ray reaches.  key: optional (n,)
    integers; rays with equal keys are packed together (secondary rays: the sphere they
    leave and their direction cell).  textbook: the article's root formula
    (``core.intersect``), else the stable one.  candidates: the bundle's candidates when the
    caller has them (``bundle_candidates``).  Yields ``DenseBlock`` or ``PairBlock`` objects;
    every pair culling keeps appears in exactly one block, candidates in scene order.
    """
    n = directions.shape[1]
    if n == 0 or len(radii) == 0:
        return
    dtype = directions.dtype
    shared = terms is not None
    reach = _per_ray(max_distance, n)
    centers_t = centers.T
    if candidates is None:
        candidates = bundle_candidates(centers, radii, origins, directions, reach.max())
    if len(candidates) == 0:
        return
    if len(candidates) <= DENSE_CANDIDATES:
        # One (k, n) pass over all of them: k <= DENSE_CANDIDATES bounds the temporaries.
        if stats is not None:
            stats.sphere_tests += n * len(candidates)
        if shared:
            roots = origin_roots(terms.f[candidates].T[:, :, None],
                                 terms.c_prime[candidates][:, None],
                                 terms.article_c[candidates][:, None], radii[candidates][:, None],
                                 directions[:, None, :], article=textbook)
        else:
            roots = offset_roots(origins[:, None, :]
                                 - centers[candidates].T.astype(dtype)[:, :, None],
                                 directions[:, None, :],
                                 radii[candidates].astype(dtype)[:, None], article=textbook)
        yield DenseBlock(candidates[:, None], *roots, slice(0, n))
        return

    # Second level: packets of coherent rays, each with its own candidates; then explicit
    # (ray, sphere) pairs, so no work is spent on padding.
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
        per_ray = counts[ray_packet]
        pair_owner = np.repeat(np.arange(len(rays)), per_ray)
        pair_index = np.repeat(first_pair[ray_packet], per_ray) + rank_within_runs(per_ray)
        spheres = pair_sphere[pair_index]
        pair_rays = rays[pair_owner]
        if stats is not None:
            stats.sphere_tests += len(spheres)
        pair_dirs = take(directions, pair_rays)
        if shared:
            roots = origin_roots(terms.f[spheres].T, terms.c_prime[spheres],
                                 terms.article_c[spheres], radii[spheres], pair_dirs,
                                 article=textbook)
        else:
            roots = offset_roots(take(origins, pair_rays) - take(centers_t, spheres).astype(dtype),
                                 pair_dirs, radii[spheres].astype(dtype), article=textbook)
        yield PairBlock(spheres, *roots, rays, pair_rays, run_starts(per_ray))
