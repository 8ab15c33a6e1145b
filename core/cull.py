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

import numpy as np

from .intersect import OriginTerms, offset_roots, origin_roots

_ANGLE_MARGIN = 1e-6  # radians
#: Rays per packet (a 16 x 16 pixel block of camera rays).
PACKET_SIZE = 256
#: Rays per packet of keyed (secondary) rays, whose runs of equal keys are often short.
KEYED_PACKET_SIZE = 64
#: Cube-map cells per face side for grouping reflection rays by direction.
CELLS = 8
#: With at most this many bundle-level candidates, one dense pass beats per-packet culling.
DENSE_CANDIDATES = 8
#: Bundle-level candidates intersected at once in the dense pass; bounds (k, n) temporaries.
DENSE_CHUNK = 16
#: Upper bound on ray/sphere pairs per block of packets; bounds the (k, n) temporaries.
BLOCK_PAIRS = 1 << 19


def cones(origins, directions):
    """Bounding cones of P groups of R rays: (apex (P, 3), spread (P,), axis (P, 3), half (P,)).

    origins: (3, P, R), or (3, 1, 1) when every ray starts there; directions: (3, P, R) unit.
    spread is the half diagonal of the group's origin bounding box.
    """
    groups = directions.shape[1]
    if origins.shape[1] == 1 and origins.shape[2] == 1:
        apex = np.repeat(origins[:, 0, 0].astype(np.float64)[None, :], groups, axis=0)
        spread = np.zeros(groups)
    else:
        low = origins.min(axis=2).astype(np.float64)
        high = origins.max(axis=2).astype(np.float64)
        apex = ((low + high) / 2).T
        spread = np.sqrt(((high - low) ** 2).sum(axis=0)) / 2
    mean = directions.sum(axis=2, dtype=np.float64)                     # (3, P)
    norm = np.sqrt((mean ** 2).sum(axis=0))
    degenerate = norm < 1e-9 * directions.shape[2]
    axis = mean / np.where(degenerate, 1.0, norm)
    cos_half = np.einsum("cp,cpr->pr", axis.astype(directions.dtype), directions).min(axis=1)
    # The dot products were rounded in the render precision: widen by its epsilon.
    half = np.arccos(np.clip(cos_half, -1.0, 1.0)) + 4 * np.sqrt(np.finfo(directions.dtype).eps)
    half = np.where(degenerate, np.pi, np.minimum(half, np.pi))
    return apex, spread, axis.T, half


def reachable(centers, radii, apex, spread, axis, half, max_distance):
    """(P, K) mask: may a ray of group p hit sphere k within max_distance (P,)?

    centers (K, 3), radii (K,); the groups' cones as ``cones`` returns them."""
    to_center = centers[None, :, :] - apex[:, None, :]                  # (P, K, 3)
    distance = np.sqrt(np.einsum("pkc,pkc->pk", to_center, to_center))
    grown = radii[None, :] + spread[:, None]
    contains = distance <= grown
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_angle = np.einsum("pkc,pc->pk", to_center, axis) / distance
        angular_radius = np.arcsin(np.clip(grown / distance, 0.0, 1.0))
    allowed = half[:, None] + angular_radius + _ANGLE_MARGIN
    within_cone = (allowed >= np.pi) | (np.arccos(np.clip(cos_angle, -1.0, 1.0)) <= allowed)
    near_enough = distance - grown <= (max_distance + spread)[:, None] * (1 + 1e-9) + 1e-9
    return contains | (within_cone & near_enough)


def _per_ray(values, n):
    return np.broadcast_to(np.asarray(values, np.float64), (n,))


def direction_cells(directions):
    """(n,) cube-map cell of each unit direction (3, n): CELLS x CELLS cells on each of the six
    faces, so rays sharing a cell point within about 90 / CELLS degrees of each other."""
    major = np.argmax(np.abs(directions), axis=0)
    columns = np.arange(directions.shape[1])
    along = directions[major, columns]
    u = directions[(major + 1) % 3, columns] / np.abs(along)
    v = directions[(major + 2) % 3, columns] / np.abs(along)
    face = 2 * major + (along < 0)
    cell_u = np.minimum(((u + 1) * (CELLS / 2)).astype(np.intp), CELLS - 1)
    cell_v = np.minimum(((v + 1) * (CELLS / 2)).astype(np.intp), CELLS - 1)
    return (face * CELLS + cell_u) * CELLS + cell_v


def _packets(n, key, size):
    """Packets over n rays: (order (n,), starts (P,), lengths (P,)).  Without a key, runs of
    ``size`` consecutive rays; with one, rays sorted by key (stably) and cut where it changes."""
    if key is None:
        starts = np.arange(0, n, size)
        return np.arange(n), starts, np.minimum(size, n - starts)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    run_start = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    run_length = np.diff(np.r_[run_start, n])
    pieces = -(-run_length // size)
    starts = np.repeat(run_start, pieces) + size * (
        np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces))
    return order, starts, np.minimum(size, np.repeat(run_start + run_length, pieces) - starts)


def candidate_roots(centers, radii, origins, directions, max_distance, terms: OriginTerms = None,
                    *, article=False, stats=None, key=None):
    """Ray/sphere roots for every pair culling cannot rule out, in blocks.

    centers (N, 3), radii (N,) in float64; origins (3, 1) with ``terms`` (OriginTerms at that
    origin) when all rays share it, else (3, n); directions (3, n) unit; max_distance: scalar
    or (n,), how far each ray reaches.  key: optional (n,) integers; rays with equal keys are
    packed together (secondary rays: the sphere they leave, and their direction cell).
    Yields ``(rays, ids, t_near, t_far, valid)``: rays, a slice or index array of the n rays;
    ids (K, m) or (K, 1), the scene index of each row's sphere (-1 for padding, never valid);
    the roots (K, m).  Rows keep scene order, so ties go to the sphere listed first.
    """
    n = directions.shape[1]
    if n == 0 or len(radii) == 0:
        return
    dtype = directions.dtype
    shared = terms is not None
    reach = _per_ray(max_distance, n)
    apex, spread, axis, half = cones(origins[:, None, :], directions[:, None, :])
    candidates = np.flatnonzero(reachable(centers, radii, apex, spread, axis, half,
                                          np.array([reach.max()]))[0])
    if len(candidates) == 0:
        return
    if len(candidates) <= DENSE_CANDIDATES or n <= PACKET_SIZE:
        for first in range(0, len(candidates), DENSE_CHUNK):
            chunk = candidates[first:first + DENSE_CHUNK]
            if stats is not None:
                stats.sphere_tests += n * len(chunk)
            if shared:
                roots = origin_roots(terms.f[chunk].T[:, :, None],
                                     terms.c_prime[chunk][:, None],
                                     terms.article_c[chunk][:, None], radii[chunk][:, None],
                                     directions[:, None, :], article=article)
            else:
                roots = offset_roots(origins[:, None, :] - centers[chunk].T.astype(dtype)[:, :, None],
                                     directions[:, None, :],
                                     radii[chunk].astype(dtype)[:, None], article=article)
            yield slice(0, n), chunk[:, None], *roots
        return

    # Second level: packets, each padded to ``size`` with copies of its last ray.
    size = PACKET_SIZE if key is None else KEYED_PACKET_SIZE
    order, starts, lengths = _packets(n, key, size)
    packets = len(starts)
    slot = np.arange(size)
    filled = slot[None, :] < lengths[:, None]                              # (P, R)
    padded = order[starts[:, None] + np.minimum(slot[None, :], lengths[:, None] - 1)]
    packet_dirs = directions[:, padded]                                    # (3, P, R)
    packet_origins = origins[:, None, :] if shared else origins[:, padded]
    apex, spread, axis, half = cones(packet_origins, packet_dirs)
    packet_reach = reach[padded].max(axis=1)
    mask = reachable(centers[candidates], radii[candidates], apex, spread, axis, half,
                     packet_reach)                                       # (P, Kc)
    counts = mask.sum(axis=1)
    # Stable sort puts each packet's candidates first, in scene order.
    rank = np.argsort(~mask, axis=1, kind="stable")
    first = 0
    while first < packets:
        # Grow the block while its padded pair count stays bounded.
        last, widest = first, 0
        while last < packets:
            widest_next = max(widest, int(counts[last]))
            if last > first and (last + 1 - first) * widest_next * size > BLOCK_PAIRS:
                break
            widest, last = widest_next, last + 1
        block = slice(first, last)
        first = last
        if widest == 0:
            continue
        slots = rank[block, :widest]
        ids = np.where(np.take_along_axis(mask[block], slots, axis=1),
                       candidates[slots], -1)                              # (g, K)
        safe = np.maximum(ids, 0)
        if stats is not None:
            stats.sphere_tests += int(counts[block].sum() * size)
        rays_block = packet_dirs[:, block, None, :]                        # (3, g, 1, R)
        if shared:
            roots = origin_roots(terms.f[safe].transpose(2, 0, 1)[..., None],
                                 terms.c_prime[safe][..., None], terms.article_c[safe][..., None],
                                 radii[safe][..., None], rays_block, article=article)
        else:
            f = (packet_origins[:, block, None, :]
                 - centers[safe].transpose(2, 0, 1).astype(dtype)[..., None])
            roots = offset_roots(f, rays_block, radii[safe].astype(dtype)[..., None],
                                 article=article)
        keep = filled[block].ravel()
        t_near, t_far, valid = (np.moveaxis(r, 1, 0).reshape(widest, -1)[:, keep]
                                for r in roots)                            # (K, m)
        row_ids = np.repeat(ids.T, size, axis=1)[:, keep]
        yield padded[block].ravel()[keep], row_ids, t_near, t_far, valid & (row_ids >= 0)
