"""Direction bins: rays that share one origin, answered by binning instead of the tree (a
light buffer).

Haines and Greenberg's light buffer (1986), a rasterizer's binning: around one origin (the
camera's eye, a light sample) the directions are cut into cube-map cells (``cells
.face_cells``: CELLS x CELLS cells on each of six faces), and every primitive of the
tree is listed in each cell its bounding box may be seen through.  A ray from that origin
can then hit only the primitives of its own cell, so a batch is answered by pairing each ray
with its cell's primitives and intersecting those pairs exactly: no box tests at all, where
the tree spends tens of them per ray.

Conservative.  A box wholly in front of a face's plane (through the origin, along the face's
axis) projects onto the face inside the range of its corners' projections: u = a / g is
monotonic in the lateral coordinate a and in the depth g > 0, so the extremes are at the
box's faces.  A box straddling the plane reaches every u on the side of its lateral range
(a / g grows without bound as g -> 0+), and a box containing the origin covers everything.
The ranges are widened by ``bins_build.MARGIN`` (rays' cells come from directions rounded
in the render precision) before they are cut into cells.  Each listed primitive also keeps
its box's distance from the origin (scaled down by ``bins_build.NEAR_SLACK``): a pair whose
ray must stop before it (a hit found already, a segment's end) is never intersected.

The answer is the tree's, not an approximation of it: the pairs go through the very kernels
the tree's leaves use (``BVH.traverse``'s ``visit`` and ``accept`` contract), each cell lists
its primitives in id order, and a ray's nearest hit is its least distance, ties to the lower
primitive id, as the tree's leaf visits pick them (``bvh_traverse._visit_leaves``).

Whether bins pay is decided twice.  Per origin, before anything is listed: the entries the
boxes would make are counted from their cell ranges (each cell's count by 2-D difference
arrays); an origin whose bins would exceed ``GeometryPolicy.max_entries`` even with a
quarter of the cells
a side (boxes near the origin), or whose occupied cells list more than
``max_mean_candidates`` on average (a dense field, whose cells hold columns of primitives
along depth, which the tree, front to back, stops short of), is left to the tree.  Per
batch: its rays' candidates are counted from the cell offsets, and a batch with more than
``max_pairs_per_ray`` on average goes to the tree.  (``binning`` adds when to try:
batches large enough, trees small enough, a bound on the bytes held.)

Depth-ordered bins (``by_depth``, ``walk``) serve the dense fields refused above: each entry
keeps the least distance at which a ray within its cell's cone can meet the primitive's
bounding sphere (``bins_build._cone_near``; entries whose cone misses the sphere are dropped), cells
list their entries nearest first, and a ray walks its cell front to back until its next
entry lies beyond its nearest hit (ties walked on, for the lower id): the same answer, the
least distance and the lower id, for the rays the walk finishes; the others are handed back
to be answered by the tree.  Shadow segments keep to the tree: from a light, a lit point's
overlapping neighbours lie in its cell's cone before it, and 39 % of the 10^6 set's segments
were still walking after the last round.

Parallel bins (``ParallelBins``) are the light buffer of a sun: its shadow rays share a
direction, not an origin, so the spheres are binned across that direction (an orthographic
projection) and a ray's candidates are its cell's spheres not wholly behind its origin.

This module holds the bins and the queries over them (``OriginBins.plan``, ``traverse``,
``walk``; ``ParallelBins.pairs``); the origin bins' build and storage layout are
``bins_build``'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runs import rank_within_runs
from .bins_build import BLOCK, build_origin_bins, rectangle_cells, stored_place
from .cells import face_cells
from .pairs import keep_nearest
from .policy import DEFAULT_POLICY, GeometryPolicy

#: Upper bound on pairs intersected at once; bounds the per-pair temporaries.
BLOCK_PAIRS = 1 << 18


@dataclass(frozen=True)
class OriginBins:
    """The primitives of a tree binned by direction around one origin (module docstring).

    cells: cells per face side (a multiple of BLOCK).  Cells are stored by blocks of BLOCK x
    BLOCK, only where a block lists something: ``slots`` (6 (cells / BLOCK)^2,) each block's
    place among the stored ones (-1: empty); ``starts`` (stored blocks BLOCK^2 + 2,) offsets
    of each stored cell's entries, block by block, cells u-major within a block (the last
    two: an empty cell for rays in empty blocks); primitives: (E,) int32 global primitive
    ids, in id order within a cell; near: (E,) float64 lower bound on the distance at which
    a ray from the origin can meet the primitive."""

    cells: int
    slots: np.ndarray
    starts: np.ndarray
    primitives: np.ndarray
    near: np.ndarray
    #: Cells list their primitives by ``near`` (ties by id), to be walked front to back
    #: (``walk``), instead of by id.
    by_depth: bool = False

    @classmethod
    def build(cls, position, ids, low, high, **options) -> "OriginBins | None":
        """Bins around ``position`` (3,) of primitives ``ids`` (K,) ascending, with bounding
        boxes low, high (K, 3), or None where they do not pay (``bins_build
        .build_origin_bins``, which tells the ``options``)."""
        made = build_origin_bins(position, ids, low, high, **options)
        return None if made is None else cls(*made)

    @property
    def entries(self) -> int:
        return len(self.primitives)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.slots, self.starts, self.primitives, self.near))

    def cell_entries(self, cell: int) -> np.ndarray:
        """The primitives (k,) listed in one cell (``cells.direction_cells``' numbering)."""
        face, rest = divmod(int(cell), self.cells * self.cells)
        u, v = divmod(rest, self.cells)
        place = int(stored_place(self.slots, face, np.array([u]), np.array([v]),
                           self.cells // BLOCK, len(self.starts) - 2)[0])
        return self.primitives[self.starts[place]:self.starts[place + 1]]

    def plan(self, directions, max_pairs_per_ray: float = DEFAULT_POLICY.max_pairs_per_ray):
        """(cell start (n,), candidates (n,)) of rays along unit ``directions`` (3, n), or
        None when the batch averages more than ``max_pairs_per_ray`` candidates (the tree's
        then)."""
        place = stored_place(self.slots, *face_cells(directions, self.cells), self.cells // BLOCK,
                       len(self.starts) - 2)
        start = self.starts.take(place)
        count = self.starts.take(place + 1) - start
        if not self.by_depth and count.sum() > max_pairs_per_ray * len(count):
            return None
        return start, count

    def traverse(self, plan, t_max, visit, accept=None, *, any_hit=False, exclude=None,
                 reach_shift=None):
        """``BVH.traverse``'s contract over the batch's candidate pairs: plan from ``plan``;
        t_max (n,) float64, lowered in place to each ray's nearest hit; ``visit(rays,
        prims)`` gets (ray, primitive) pairs (E,) grouped by ray, each ray's pairs in id
        order, and returns each pair's hit distance (inf for none; with ``any_hit`` any
        value < inf blocks); ``accept(rays, pairs)`` learns which pair (index into that
        visit's pairs) is each improved ray's nearest hit (ties: the lower primitive id).
        exclude: (n,) the primitive each ray ignores (-1: none), or None; a ray's pair with
        it is not visited at all (``visit`` would find no hit there).  reach_shift: (n,)
        how much further than its t_max each ray may be from the bins' origin at its t_max
        (rays that do not leave the origin itself: ``DirectionBins._mirror_groups``), or None.
        Returns (n,) bool: whether a hit (any_hit: a blocker) was found for each ray."""
        start, count = plan
        n = len(count)
        found = np.zeros(n, bool)
        # Blocks of whole rays of at most about BLOCK_PAIRS pairs.
        ends = np.cumsum(count)
        cuts = np.searchsorted(ends, np.arange(BLOCK_PAIRS, int(ends[-1]) if n else 0,
                                               BLOCK_PAIRS), side="right")
        edges = np.unique(np.r_[0, cuts, n])
        for first, stop in zip(edges[:-1], edges[1:]):
            part_count = count[first:stop]
            # Each pair's entry: its ray's start plus its rank among the ray's pairs, as its
            # place among the part's pairs less that of its ray's first pair (``ends``).
            before = int(ends[first - 1]) if first else 0
            entry = np.repeat(start[first:stop] - (ends[first:stop] - part_count - before),
                              part_count)
            entry += np.arange(len(entry))
            ray = np.repeat(np.arange(first, stop), part_count)
            # Pairs whose ray stops before the primitive's box, or ignores the primitive, are
            # never intersected.
            reach = t_max.take(ray)
            if reach_shift is not None:
                reach += reach_shift.take(ray)
            keep = self.near.take(entry) < reach
            if exclude is not None:
                keep &= self.primitives.take(entry) != exclude.take(ray)
            keep = np.flatnonzero(keep)
            if len(keep) == 0:
                continue
            ray = ray.take(keep)
            prims = self.primitives.take(entry.take(keep)).astype(np.intp)
            # (Cells list their primitives once each: unique per ray.)
            keep_nearest(ray, prims, visit(ray, prims), t_max, found, accept, any_hit)
        return found

    def walk(self, plan, t_max, visit, accept=None, *, exclude=None,
             rounds=DEFAULT_POLICY.walk_rounds):
        """Depth-ordered bins' (``by_depth``) answer to ``traverse``'s nearest-hit question
        (shadow segments keep to the tree: module docstring), walking each ray's cell front
        to back: round k meets the next rounds[k] entries of every ray still walking, and a
        ray stops at the end of its cell, or once its next entry's ``near`` is beyond its
        nearest hit so far (a hit there could at best tie: walked on while equal, for the
        lower id) or beyond its t_max.  plan, t_max (lowered in place), accept, exclude: as
        ``traverse``'s; ``visit(rays, prims, reach)`` as ``traverse``'s visit with each
        pair's reach (E,) float64: hits nearer than it count (inf where a ray has a hit
        already: its ties are settled here, by id).  Returns (found (n,) bool, rest (k,)
        ascending): the rays still walking after the last round, cleared in found; their
        t_max and what accept recorded for them are the caller's to reset: the tree answers
        them afresh."""
        start, count = plan
        n = len(count)
        found = np.zeros(n, bool)
        best = np.full(n, -1, np.int64)     # each ray's nearest primitive so far
        live = np.flatnonzero(count > 0)
        position = start.take(live).astype(np.intp)
        end = position + count.take(live)
        for size in rounds:
            live, position, end = self._walking(live, position, end, t_max, found)
            if len(live) == 0:
                break
            step = np.minimum(end - position, size)
            ray = np.repeat(live, step)
            entry = np.repeat(position, step) + rank_within_runs(step)
            position += step
            # Pairs beyond their ray's reach, or with the primitive it ignores, are skipped.
            reach, near, settled = t_max.take(ray), self.near.take(entry), found.take(ray)
            keep = np.where(settled, near <= reach, near < reach)
            if exclude is not None:
                keep &= self.primitives.take(entry) != exclude.take(ray)
            keep = np.flatnonzero(keep)
            if len(keep) == 0:
                continue
            ray, prims = ray.take(keep), self.primitives.take(entry.take(keep)).astype(np.intp)
            t = visit(ray, prims, np.where(settled.take(keep), np.inf, reach.take(keep)))
            keep_nearest(ray, prims, t, t_max, found, accept, best=best)
        live, position, end = self._walking(live, position, end, t_max, found)
        found[live] = False
        return found, live

    def _walking(self, live, position, end, t_max, found):
        """(live, position, end) of ``walk``'s rays that walk on: entries left, and the next
        one within reach (up to an equal distance once a hit is found)."""
        go = position < end
        near = self.near.take(np.minimum(position, len(self.near) - 1))
        reach, settled = t_max.take(live), found.take(live)
        go &= np.where(settled, near <= reach, near < reach)
        go = np.flatnonzero(go)
        return live.take(go), position.take(go), end.take(go)


@dataclass(frozen=True)
class ParallelBins:
    """Spheres binned across one direction: the light buffer of a sun, whose shadow rays
    are all parallel (an orthographic projection where ``OriginBins`` is a perspective one).

    Every sphere (centre c, radius r, grown by ``pad``) projects onto the plane across the
    direction d as a disc; it is listed in each square cell (``cell`` a side, in the basis
    u, v of that plane) that the disc's bounding square meets, with its far depth
    d.c + (r + pad) |d|.  A ray o + t d with t > t_min >= 0 keeps its projection (o.u, o.v)
    (up to d.u, d.v, which round to about 1e-16) and only gains depth, so a sphere it meets
    lies in its cell with a far depth at least d.o: the ray's candidates are its cell's
    entries whose far depth reaches its origin's (``pairs``).  ``pad`` must cover what the
    kernels' rounding may add to a sphere (the tree's box padding does).  Conservative, and
    the same kernels decide: the blocked rays are the tree's.

    direction (3,), u, v (3,) float64; corner (2,) the cells' low corner (u, v); shape
    (cells along u, along v); starts (cells + 1,) offsets of each cell's entries (u-major);
    entries (E,) each entry's sphere (an index into the spheres given to ``build``); far
    (E,) float64 each entry's far depth."""

    direction: np.ndarray
    u: np.ndarray
    v: np.ndarray
    corner: tuple
    cell: float
    shape: tuple
    pad: float
    starts: np.ndarray
    entries: np.ndarray
    far: np.ndarray

    @classmethod
    def build(cls, direction, centres, radii, pad: float,
              policy: GeometryPolicy = DEFAULT_POLICY):
        """Bins of spheres centres (3, P), radii (P,) (float64) across ``direction`` (3,),
        with cells of ``policy.parallel_cell_diameters`` median spheres, or None where they
        would list more than ``policy.parallel_max_entries_per_primitive`` entries a
        sphere."""
        d = np.asarray(direction, np.float64)
        # (The rays' own direction, unnormalised: they are parallel to it exactly.)
        axis = np.zeros(3)
        axis[int(np.argmin(np.abs(d)))] = 1.0
        u = np.cross(d, axis)
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        v /= np.linalg.norm(v)
        reach = radii + pad
        cu, cv = u @ centres, v @ centres
        cell = policy.parallel_cell_diameters * 2 * float(np.median(reach))
        corner = (float((cu - reach).min()), float((cv - reach).min()))
        first_u = np.floor((cu - reach - corner[0]) / cell).astype(np.intp)
        first_v = np.floor((cv - reach - corner[1]) / cell).astype(np.intp)
        span_u = np.floor((cu + reach - corner[0]) / cell).astype(np.intp) - first_u + 1
        span_v = np.floor((cv + reach - corner[1]) / cell).astype(np.intp) - first_v + 1
        count = span_u * span_v
        if count.sum() > policy.parallel_max_entries_per_primitive * len(radii):
            return None
        shape = (int((first_u + span_u).max()), int((first_v + span_v).max()))
        cell_u, cell_v, sphere = rectangle_cells(np.arange(len(radii)), first_u,
                                          first_u + span_u - 1, first_v, first_v + span_v - 1)
        cells = cell_u * shape[1] + cell_v
        order = np.argsort(cells, kind="stable")
        starts = np.zeros(shape[0] * shape[1] + 1, np.intp)
        np.cumsum(np.bincount(cells, minlength=shape[0] * shape[1]), out=starts[1:])
        entries = sphere.take(order)
        far = (d @ centres + reach * np.linalg.norm(d)).take(entries)
        return cls(d, u, v, corner, cell, shape, float(pad), starts, entries, far)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.starts, self.entries, self.far))

    def pairs(self, origins):
        """(rays (k,), entries (k,)): the candidates of rays from ``origins`` (3, n) along
        the bins' direction, grouped by ray: their cell's entries whose far depth reaches the
        ray's origin (less the padding, for the dot products' rounding)."""
        origins = np.asarray(origins, np.float64)
        n = origins.shape[1]
        u = np.floor((self.u @ origins - self.corner[0]) / self.cell)
        v = np.floor((self.v @ origins - self.corner[1]) / self.cell)
        inside = (u >= 0) & (u < self.shape[0]) & (v >= 0) & (v < self.shape[1])
        cell = np.where(inside, u * self.shape[1] + v, 0).astype(np.intp)
        start = self.starts.take(cell)
        count = np.where(inside, self.starts.take(cell + 1) - start, 0)
        rays = np.repeat(np.arange(n), count)
        entries = np.repeat(start, count) + rank_within_runs(count)
        depth = self.direction @ origins - self.pad
        ahead = np.flatnonzero(self.far.take(entries) >= depth.take(rays))
        return rays.take(ahead), entries.take(ahead)
