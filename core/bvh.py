"""A bounding volume hierarchy built and traversed in whole-array NumPy.

Build (``BVH.build``): primitives sorted by the 63-bit Morton code of their box centres
(a linear BVH, Lauterbach et al. 2009), cut into leaves of LEAF_SIZE consecutive
primitives; each level above groups WIDTH consecutive nodes of the level below, so node i
of a level has children i * WIDTH .. i * WIDTH + WIDTH - 1.  Bounds are ``reduceat`` over
the sorted boxes: no Python loop per node.

Traversal (``BVH.traverse``) is wavefront-style over (ray, node) pairs.  From the root down
to the *treelet* level (TREELET_DEPTH or more levels above the leaves) every live pair is expanded
to its children at once and kept where the ray's segment meets the child's box.  The
(ray, treelet) pairs are then sorted by entry distance and visited front to back in rounds
(the first treelet of each ray, then the next one, then two, four, ...): a round descends
its treelets to their leaves, pruning by each ray's nearest hit so far, intersects the
leaves' primitives, and a ray whose next treelet starts beyond its nearest hit is finished,
so a ray stops at its nearest hit; for occlusion a ray is finished at its first blocker.
Pairs stay grouped by ray throughout, so per-ray reductions are ``reduceat``.

Boxes are float64 and padded, so culling stays conservative for rays in either precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .runs import rank_within_runs

#: Primitives per leaf, children per inner node, and the least depth (in levels above the
#: leaves) of the subtrees ("treelets") visited front to back.
#: (Leaves of 2 against 4, CPU time on one thread at 320x180: 1,000 spheres 0.63 vs 0.80 s,
#: 100,000 2.09 vs 2.07 s, 1,000,000 4.49 vs 4.66 s; leaves of 8: 1.34 s and 2.80 s.)
LEAF_SIZE = 2
WIDTH = 4
TREELET_DEPTH = 3
#: The treelets are the nodes TREELET_DEPTH levels above the leaves, or higher up while
#: that level has more than MAX_TREELETS nodes (measured, CPU time at 320x180: 1e5 spheres
#: 1.93 s at depth 3 vs 2.26 s at 4; 1e6 spheres 5.17 s at 3, 3.98 s at 4, 5.19 s at 5).
MAX_TREELETS = 1000
#: Rays traversed together: bounds the (ray, node) pairs held at once.
RAY_CHUNK = 4096
#: Relative padding of every box (conservative culling under rounding).
BOX_PADDING = 1e-7


def _spread21(values):
    """Insert two zero bits after each of the low 21 bits (63-bit 3-D Morton codes)."""
    v = values.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def morton_order(points: np.ndarray) -> np.ndarray:
    """Indices that sort points (N, 3) along a 63-bit Morton curve over their bounding box."""
    low = points.min(axis=0)
    extent = np.ptp(points, axis=0)
    cells = ((points - low) / np.where(extent > 0, extent, 1) * (2 ** 21 - 1)).astype(np.uint64)
    code = _spread21(cells[:, 0]) | (_spread21(cells[:, 1]) << np.uint64(1)) \
        | (_spread21(cells[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


@dataclass(frozen=True)
class BVH:
    """primitives: (P,) primitive ids in leaf order, padded with -1 to a whole number of
    leaves; levels[0] the leaves' boxes, levels[-1] the root's: each (low (3, k), high
    (3, k)) float64; blocks[k]: level k's boxes as (k-level parents, WIDTH, 6) rows."""

    primitives: np.ndarray
    levels: tuple
    blocks: tuple = ()       # per level below the root: (parents, WIDTH, 6) child boxes

    @classmethod
    def build(cls, ids: np.ndarray, low: np.ndarray, high: np.ndarray) -> "BVH":
        """A tree over primitives ``ids`` (P,) with boxes low, high (P, 3)."""
        order = morton_order((low + high) / 2)
        ids, low, high = ids[order], low[order], high[order]
        pad = BOX_PADDING * (np.abs(low).max(axis=1) + np.abs(high).max(axis=1)
                             + (high - low).max(axis=1))[:, None] + 1e-300
        low, high = low - pad, high + pad
        starts = np.arange(0, len(ids), LEAF_SIZE)
        levels = [(np.minimum.reduceat(low, starts).T.copy(),
                   np.maximum.reduceat(high, starts).T.copy())]
        while levels[-1][0].shape[1] > 1:
            below_low, below_high = levels[-1]
            starts = np.arange(0, below_low.shape[1], WIDTH)
            levels.append((np.minimum.reduceat(below_low, starts, axis=1),
                           np.maximum.reduceat(below_high, starts, axis=1)))
        padded = np.full(levels[0][0].shape[1] * LEAF_SIZE, -1, np.intp)
        padded[:len(ids)] = ids
        # Each node's children as one contiguous block of rows (low xyz, high xyz), so that
        # expanding a (ray, node) pair gathers its WIDTH child boxes at once.
        blocks = []
        for low_k, high_k in levels[:-1]:
            count = low_k.shape[1]
            rows = np.zeros((-(-count // WIDTH) * WIDTH, 6))
            rows[:count, :3], rows[:count, 3:] = low_k.T, high_k.T
            blocks.append(rows.reshape(-1, WIDTH, 6))
        return cls(padded, tuple(levels), tuple(blocks))

    # ---- traversal ----------------------------------------------------------------------

    def traverse(self, origins, inverse, t_min, t_max, visit, accept=None, *, any_hit=False,
                 stats=None):
        """Visit, front to back, the primitives whose leaves each ray's segment reaches.

        origins (3, n) or (3, 1) and inverse (3, n) (1 / direction) float64; t_min scalar
        or (n,), t_max (n,) float64, updated in place as hits are found.
        ``visit(rays, prims)`` gets (ray, primitive) pairs (E,) grouped by ray and returns
        each pair's hit distance (inf for none; with ``any_hit`` any value < inf blocks).
        ``accept(rays, pairs)`` is told, after each visit, which pair (index into that
        visit's pairs) is each improved ray's new nearest hit (ties: the lower primitive id).
        Returns (n,) bool: whether a hit (any_hit: a blocker) was found for each ray.
        """
        n = inverse.shape[1]
        found = np.zeros(n, bool)
        rows = (np.concatenate([origins, origins]).T.copy(),
                np.concatenate([inverse, inverse]).T.copy())
        for first in range(0, n, RAY_CHUNK):
            self._traverse(np.arange(first, min(first + RAY_CHUNK, n)), origins, inverse,
                           rows, t_min, t_max, visit, accept, found, any_hit, stats)
        return found

    def _traverse(self, rays, origins, inverse, rows, t_min, t_max, visit, accept, found,
                  any_hit, stats):
        top = len(self.levels) - 1
        treelet = min(TREELET_DEPTH, top)
        while self.levels[treelet][0].shape[1] > MAX_TREELETS and treelet < top:
            treelet += 1
        nodes = np.zeros(len(rays), np.intp)
        keep, near = self._boxes(top, nodes, rays, origins, inverse, t_min, t_max, stats)
        rays, nodes, near = rays[keep], nodes[keep], near[keep]
        for level in range(top - 1, treelet - 1, -1):
            rays, nodes, near = self._expand(level, rays, nodes, *rows, t_min, t_max, stats)
        if len(rays) == 0:
            return
        order = np.lexsort((near, rays))
        rays, nodes, near = rays[order], nodes[order], near[order]
        first = np.r_[True, rays[1:] != rays[:-1]]
        starts = np.flatnonzero(first)
        rank = rank_within_runs(np.diff(np.r_[starts, len(rays)]))
        done_rank, size = 0, 1
        while True:
            chosen = (rank >= done_rank) & (rank < done_rank + size)
            if not chosen.any():
                break
            pick = np.flatnonzero(chosen)
            r, node, entry = rays[pick], nodes[pick], near[pick]
            live = entry <= t_max[r]
            if any_hit:
                live &= ~found[r]
            r, node = r[live], node[live]
            for level in range(treelet - 1, -1, -1):
                r, node, _ = self._expand(level, r, node, *rows, t_min, t_max, stats)
            if len(r):
                leaf_rays = np.repeat(r, LEAF_SIZE)
                prims = self.primitives[(node[:, None] * LEAF_SIZE
                                         + np.arange(LEAF_SIZE)).ravel()]
                real = prims >= 0
                leaf_rays, prims = leaf_rays[real], prims[real]
                if len(prims):
                    t = visit(leaf_rays, prims)
                    group = np.flatnonzero(np.r_[True, leaf_rays[1:] != leaf_rays[:-1]])
                    nearest = np.minimum.reduceat(t, group)
                    owner = leaf_rays[group]
                    hit = nearest < (np.inf if any_hit else t_max[owner])
                    found[owner[hit]] = True
                    if not any_hit and hit.any():
                        lengths = np.diff(np.r_[group, len(t)])
                        at_min = t == np.repeat(nearest, lengths)
                        lowest = np.minimum.reduceat(np.where(at_min, prims, np.iinfo(np.intp).max),
                                                     group)
                        # A primitive is visited once per ray and round: one winner per ray.
                        winner = np.flatnonzero(at_min & (prims == np.repeat(lowest, lengths)))
                        t_max[owner[hit]] = nearest[hit]
                        if accept is not None:
                            accept(owner[hit], winner[hit])
            done_rank += size
            size *= 2

    def _boxes(self, level, nodes, rays, origins, inverse, t_min, t_max, stats):
        """(hit (E,), entry distance (E,)) of pairs (ray, node of ``level``)."""
        low, high = self.levels[level]
        o = origins if origins.shape[1] == 1 else origins[:, rays]
        inv = inverse[:, rays]
        a = (low[:, nodes] - o) * inv
        b = (high[:, nodes] - o) * inv
        with np.errstate(invalid="ignore"):
            near = np.fmax(np.fmax(np.fmin(a[0], b[0]), np.fmin(a[1], b[1])),
                           np.fmin(a[2], b[2]))
            far = np.fmin(np.fmin(np.fmax(a[0], b[0]), np.fmax(a[1], b[1])),
                          np.fmax(a[2], b[2]))
        near = np.maximum(near, t_min[rays] if np.ndim(t_min) else t_min)
        far = np.minimum(far, t_max[rays])
        if stats is not None:
            stats.node_tests += len(nodes)
        return near <= far, near

    def _expand(self, level, rays, nodes, origins, inverse, t_min, t_max, stats):
        """The children at ``level`` of pairs (ray, node one level up) that the rays'
        segments reach: (rays, children, entry distances), still grouped by ray.

        origins, inverse: per ray (n, 6) rows (x, y, z, x, y, z), origins possibly (1, 6):
        a pair gathers one row of each and its node's WIDTH child boxes as one block, and the
        slab distances of all six planes come out of one subtraction and one product."""
        count = self.levels[level][0].shape[1]
        t = self.blocks[level][nodes]                                        # (m, W, 6)
        t -= (origins if len(origins) == 1 else origins[rays])[:, None, :]
        with np.errstate(invalid="ignore"):
            t *= inverse[rays][:, None, :]
            # fmin / fmax: a 0 * inf (a ray in a box's plane) is NaN and is ignored.
            low = np.fmin(t[..., :3], t[..., 3:])
            high = np.fmax(t[..., :3], t[..., 3:])
            near = np.fmax(np.fmax(low[..., 0], low[..., 1]), low[..., 2])
            far = np.fmin(np.fmin(high[..., 0], high[..., 1]), high[..., 2])
        np.maximum(near, t_min[rays][:, None] if np.ndim(t_min) else t_min, out=near)
        np.minimum(far, t_max[rays][:, None], out=far)
        children = nodes[:, None] * WIDTH + np.arange(WIDTH)
        exists = children < count
        hit = (near <= far) & exists
        if stats is not None:
            stats.node_tests += int(exists.sum())
        rows, slots = np.nonzero(hit)
        return rays[rows], children[rows, slots], near[rows, slots]
