"""Rays that share one origin, answered by binning instead of the tree (a light buffer).

Haines and Greenberg's light buffer (1986), a rasterizer's binning: around one origin (the
camera's eye, a light sample) the directions are cut into cube-map cells (``cull
.direction_cells``: CELLS x CELLS cells on each of six faces), and every primitive of the
tree is listed in each cell its bounding box may be seen through.  A ray from that origin
can then hit only the primitives of its own cell, so a batch is answered by pairing each ray
with its cell's primitives and intersecting those pairs exactly: no box tests at all, where
the tree spends tens of them per ray.

Conservative.  A box wholly in front of a face's plane (through the origin, along the face's
axis) projects onto the face inside the range of its corners' projections: u = a / g is
monotonic in the lateral coordinate a and in the depth g > 0, so the extremes are at the
box's faces.  A box straddling the plane reaches every u on the side of its lateral range
(a / g grows without bound as g -> 0+), and a box containing the origin covers everything.
The ranges are widened by ``MARGIN`` (rays' cells come from directions rounded in the
render precision) before they are cut into cells.  Each listed primitive also keeps its
box's distance from the origin (scaled down by ``NEAR_SLACK``): a pair whose ray must stop
before it (a hit found already, a segment's end) is never intersected.

The answer is the tree's, not an approximation of it: the pairs go through the very kernels
the tree's leaves use (``BVH.traverse``'s ``visit`` and ``accept`` contract), each cell lists
its primitives in id order, and a ray's nearest hit is its least distance, ties to the lower
primitive id, as ``BVH._visit_leaves`` picks them.

Whether bins pay is decided twice.  Per origin, before anything is listed: the entries the
boxes would make are counted from their cell ranges (each cell's count by 2-D difference
arrays); an origin whose bins would exceed ``MAX_ENTRIES`` even with a quarter of the cells
a side (boxes near the origin), or whose occupied cells list more than
``MAX_MEAN_CANDIDATES`` on average (a dense field, whose cells hold columns of primitives
along depth, which the tree, front to back, stops short of), is left to the tree.  Per
batch: its rays' candidates are counted from the cell offsets, and a batch with more than
``MAX_PAIRS_PER_RAY`` on average goes to the tree.  (``core.aggregate`` adds when to try:
batches large enough, trees small enough, a bound on the bytes held.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bvh import keep_nearest
from .runs import rank_within_runs

#: Cells per cube-face side: 512 makes cells of about 3.75 pixels at 1920 pixels across a
#: 90-degree view (one face).
CELLS = 512
#: Widening of each box's projected range, in face coordinates (|u| <= 1): many times the
#: rounding of a float32 direction's u = d_a / |d_m|.
MARGIN = 4e-6
#: A box's distance from the origin is scaled by this before it bounds its pairs' hits
#: (directions are unit vectors only to within their precision's rounding).
NEAR_SLACK = 1 - 1e-6
#: Upper bound on (cell, primitive) entries of one origin's bins (12 bytes each).
MAX_ENTRIES = 1 << 21
#: Bins whose occupied cells hold more primitives than this on average are not built: the
#: tree, which stops at a ray's first hit front to back, is cheaper there.
MAX_MEAN_CANDIDATES = 16.0
#: A batch whose rays average more candidate pairs than this goes to the tree.
MAX_PAIRS_PER_RAY = 16.0
#: Cells are stored in square blocks of BLOCK x BLOCK, only where a block lists something.
BLOCK_BITS = 4
BLOCK = 1 << BLOCK_BITS
#: Upper bound on pairs intersected at once; bounds the per-pair temporaries.
BLOCK_PAIRS = 1 << 18


def face_cells(directions, cells: int):
    """(face, u, v) (n,) each: the cube-map cell of each unit direction (3, n), in
    ``cull.direction_cells``' layout (face 2 axis + (negative), u along the next axis, v along
    the one after), with the major axis picked by comparisons (a tie between two axes may pick
    either face: both list the boxes seen on their shared edge).  Whole-array selections
    rather than an argmax and a fancy gather: half the time."""
    d = directions
    size = np.abs(d)
    x = (size[0] >= size[1]) & (size[0] >= size[2])
    y = ~x & (size[1] >= size[2])
    along = np.where(x, d[0], np.where(y, d[1], d[2]))
    first = np.where(x, d[1], np.where(y, d[2], d[0]))
    second = np.where(x, d[2], np.where(y, d[0], d[1]))
    half = d.dtype.type(cells / 2)
    scale = np.abs(along)
    np.divide(half, scale, out=scale)
    face = np.where(x, 0, np.where(y, 2, 4)) + (along < 0)
    first *= scale
    first += half
    second *= scale
    second += half
    u = np.minimum(first.astype(np.intp), cells - 1)
    v = np.minimum(second.astype(np.intp), cells - 1)
    return face, u, v


def ray_cells(directions, cells: int) -> np.ndarray:
    """(n,) ``cull.direction_cells`` of unit directions (3, n), from ``face_cells``."""
    face, u, v = face_cells(directions, cells)
    return (face * cells + u) * cells + v


def _face_ranges(relative_low, relative_high, axis: int, negative: bool):
    """(shown (k,) box indices, (u low, u high, v low, v high) (k,) each) of K boxes given
    relative to the origin, (3, K) low and high corners, on the cube face of ``axis``
    (0, 1, 2) and sign: the boxes that show on that face and the range of face coordinates
    (u, v in [-1, 1], ``face_cells``) they may be seen through from the origin, widened by
    MARGIN."""
    if negative:
        depth_low, depth_high = -relative_high[axis], -relative_low[axis]
    else:
        depth_low, depth_high = relative_low[axis], relative_high[axis]
    shown = np.flatnonzero(depth_high > 0)
    near, far = depth_low[shown], depth_high[shown]
    in_front = near > 0
    near = np.where(in_front, near, 1.0)
    ranges = []
    for lateral in ((axis + 1) % 3, (axis + 2) % 3):
        a_low, a_high = relative_low[lateral, shown], relative_high[lateral, shown]
        with np.errstate(divide="ignore", invalid="ignore"):
            # In front: the corners' extremes.  Straddling the face's plane: unbounded on the
            # side the lateral range reaches past zero.
            low = np.where(in_front, np.minimum(a_low / near, a_low / far),
                           np.where(a_low >= 0, a_low / far, -np.inf))
            high = np.where(in_front, np.maximum(a_high / near, a_high / far),
                            np.where(a_high <= 0, a_high / far, np.inf))
        ranges += [np.maximum(low - MARGIN, -1.0), np.minimum(high + MARGIN, 1.0)]
    u_low, u_high, v_low, v_high = ranges
    on = (u_low <= u_high) & (v_low <= v_high)
    return shown[on], tuple(r[on] for r in ranges)


def _face_cells(ranges, cells: int):
    """(first u, last u, first v, last v) (k,) int cell ranges (``direction_cells``' layout,
    ``cells`` a side) of face coordinate ranges from ``_face_ranges``."""
    return tuple(np.clip(np.floor((r + 1) * (cells / 2)), 0, cells - 1).astype(np.intp)
                 for r in ranges)


def _cell_counts(faces, cells: int) -> np.ndarray:
    """(6 cells^2,) how many boxes each cell lists, from the boxes' cell rectangles per face
    (face, shown, ``_face_cells``' ranges) alone: 2-D difference arrays summed up, so that
    whether bins pay is known before any entry is made."""
    counts = np.zeros((6, cells, cells), np.intp)
    side = cells + 1
    for face, shown, (fu, lu, fv, lv) in faces:
        if len(shown) == 0:
            continue
        corners = np.concatenate([fu * side + fv, (lu + 1) * side + (lv + 1),
                                  fu * side + (lv + 1), (lu + 1) * side + fv])
        signs = np.repeat([1, 1, -1, -1], len(fu))
        grid = np.bincount(corners, signs, side * side).reshape(side, side)
        counts[face] = np.rint(grid.cumsum(axis=0).cumsum(axis=1)[:cells, :cells])
    return counts.ravel()


def _place(slots, face, u, v, blocks: int, empty: int) -> np.ndarray:
    """Where cells (face, u, v) (n,) each are stored (``OriginBins``): their block's slot
    times BLOCK^2 plus their place in the block; cells of empty blocks get ``empty``, the
    empty cell at the end of ``starts``."""
    # (Shifts and masks: BLOCK is a power of two, and // and % cost several times more.)
    block = face * blocks
    block += u >> BLOCK_BITS
    block *= blocks
    block += v >> BLOCK_BITS
    slot = slots.take(block)
    place = slot << (2 * BLOCK_BITS)
    place += (u & (BLOCK - 1)) << BLOCK_BITS
    place += v & (BLOCK - 1)
    return np.where(slot >= 0, place, empty)


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

    @classmethod
    def build(cls, position, ids, low, high, cells: int = None, max_entries: int = None,
              max_mean: float = None) -> "OriginBins | None":
        """Bins around ``position`` (3,) of primitives ``ids`` (K,) ascending, with bounding
        boxes low, high (K, 3), with ``cells`` cells per face side, or half or a quarter as
        many when boxes near the origin would make more than ``max_entries`` entries; None
        where they do not pay (module docstring): still too many entries, or more than
        ``max_mean`` per occupied cell.  (Defaults: CELLS, MAX_ENTRIES and
        MAX_MEAN_CANDIDATES.)"""
        cells = CELLS if cells is None else cells
        max_entries = MAX_ENTRIES if max_entries is None else max_entries
        max_mean = MAX_MEAN_CANDIDATES if max_mean is None else max_mean
        position = np.asarray(position, np.float64)
        relative_low = (np.asarray(low, np.float64) - position).T
        relative_high = (np.asarray(high, np.float64) - position).T
        ranges = [(face, *_face_ranges(relative_low, relative_high, face // 2,
                                       bool(face % 2))) for face in range(6)]
        for size in (cells, cells // 2, cells // 4):
            faces = [(face, shown, _face_cells(r, size)) for face, shown, r in ranges]
            total = sum(int(((lu - fu + 1) * (lv - fv + 1)).sum())
                        for _, _, (fu, lu, fv, lv) in faces)
            if total <= max_entries:
                break
        else:
            return None
        cells = size
        counts = _cell_counts(faces, cells)
        if total > max_mean * np.count_nonzero(counts):
            return None
        # Blocks of cells: (6, blocks, BLOCK, blocks, BLOCK) -> (6, blocks, blocks, BLOCK^2).
        blocks = cells // BLOCK
        by_block = counts.reshape(6, blocks, BLOCK, blocks, BLOCK).transpose(0, 1, 3, 2, 4)
        by_block = by_block.reshape(6 * blocks * blocks, BLOCK * BLOCK)
        stored = by_block.any(axis=1)
        slots = np.where(stored, np.cumsum(stored) - 1, -1)
        starts = np.zeros(int(stored.sum()) * BLOCK * BLOCK + 2, np.int32)
        np.cumsum(by_block[stored].ravel(), out=starts[1:-1])
        starts[-1] = starts[-2]
        # Distance from the origin to each box (0 inside it).
        gap = np.maximum(np.maximum(relative_low, -relative_high), 0.0)
        distance = np.sqrt((gap * gap).sum(axis=0)) * NEAR_SLACK
        places, owners = [], []
        for face, shown, (first_u, last_u, first_v, last_v) in faces:
            tall = last_v - first_v + 1
            area = (last_u - first_u + 1) * tall
            rank = rank_within_runs(area)
            tall = np.repeat(tall, area)
            u = np.repeat(first_u, area) + rank // tall
            v = np.repeat(first_v, area) + rank % tall
            places.append(_place(slots, face, u, v, blocks, len(starts) - 2))
            owners.append(np.repeat(shown, area))
        place = np.concatenate(places)
        # Stable: within a cell, entries keep their (ascending) primitive order.
        owner = np.concatenate(owners)[np.argsort(place, kind="stable")]
        return cls(cells, slots, starts, np.asarray(ids, np.int32)[owner], distance[owner])

    @property
    def entries(self) -> int:
        return len(self.primitives)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.slots, self.starts, self.primitives, self.near))

    def cell_entries(self, cell: int) -> np.ndarray:
        """The primitives (k,) listed in one cell (``cull.direction_cells``' numbering)."""
        face, rest = divmod(int(cell), self.cells * self.cells)
        u, v = divmod(rest, self.cells)
        place = int(_place(self.slots, face, np.array([u]), np.array([v]),
                           self.cells // BLOCK, len(self.starts) - 2)[0])
        return self.primitives[self.starts[place]:self.starts[place + 1]]

    def plan(self, directions):
        """(cell start (n,), candidates (n,)) of rays along unit ``directions`` (3, n), or
        None when the batch averages more than MAX_PAIRS_PER_RAY candidates (the tree's
        then)."""
        place = _place(self.slots, *face_cells(directions, self.cells), self.cells // BLOCK,
                       len(self.starts) - 2)
        start = self.starts.take(place)
        count = self.starts.take(place + 1) - start
        if count.sum() > MAX_PAIRS_PER_RAY * len(count):
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
        (rays that do not leave the origin itself: ``Aggregate._mirror_groups``), or None.
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
            entry = (np.repeat(start[first:stop], part_count)
                     + rank_within_runs(part_count))
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
