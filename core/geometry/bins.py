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
The ranges are widened by ``MARGIN`` (rays' cells come from directions rounded in the
render precision) before they are cut into cells.  Each listed primitive also keeps its
box's distance from the origin (scaled down by ``NEAR_SLACK``): a pair whose ray must stop
before it (a hit found already, a segment's end) is never intersected.

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
bounding sphere (``_cone_near``; entries whose cone misses the sphere are dropped), cells
list their entries nearest first, and a ray walks its cell front to back until its next
entry lies beyond its nearest hit (ties walked on, for the lower id): the same answer, the
least distance and the lower id, for the rays the walk finishes; the others are handed back
to be answered by the tree.  Shadow segments keep to the tree: from a light, a lit point's
overlapping neighbours lie in its cell's cone before it, and 39 % of the 10^6 set's segments
were still walking after the last round.

Parallel bins (``ParallelBins``) are the light buffer of a sun: its shadow rays share a
direction, not an origin, so the spheres are binned across that direction (an orthographic
projection) and a ray's candidates are its cell's spheres not wholly behind its origin.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..runs import rank_within_runs
from .cells import face_cells
from .pairs import keep_nearest
from .policy import DEFAULT_POLICY, GeometryPolicy
from .threads import map_on

#: Cells per cube-face side: 512 makes cells of about 3.75 pixels at 1920 pixels across a
#: 90-degree view (one face).
CELLS = 512
#: Widening of each box's projected range, in face coordinates (|u| <= 1): many times the
#: rounding of a float32 direction's u = d_a / |d_m|.
MARGIN = 4e-6
#: A box's distance from the origin is scaled by this before it bounds its pairs' hits
#: (directions are unit vectors only to within their precision's rounding).
NEAR_SLACK = 1 - 1e-6
#: Cells are stored in square blocks of BLOCK x BLOCK, only where a block lists something.
BLOCK_BITS = 4
BLOCK = 1 << BLOCK_BITS
#: Upper bound on pairs intersected at once; bounds the per-pair temporaries.
BLOCK_PAIRS = 1 << 18


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
    """(first u, last u, first v, last v) (k,) int cell ranges (``cells.face_cells``' layout,
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


def _rounding_slack(distance, radii, rounding: float, scale: float):
    """(K,) how much larger than spheres of ``radii`` (K,) at ``distance`` (K,) from the
    origin the kernels may find them, with machine epsilon ``rounding`` and coordinates up
    to ``scale``: the offset roots' lateral distance |f - (f.d) d| is off by a few
    epsilon of |f| (and of the coordinates f is made from), the textbook roots'
    discriminant b^2 - c by epsilon b^2, a lateral error of epsilon D^2 / 2r.  Generous:
    a little more culling lost, never a hit the tree would find."""
    if rounding == 0:
        return 0.0
    return rounding * (4 * radii + 4 * scale + 8 * distance
                       + 4 * distance * distance / np.maximum(radii, 1e-300))


@functools.lru_cache(maxsize=4)
def _cell_cones(cells: int):
    """(axis (3, cells, cells) unit vectors in face coordinates (along, u, v), cos and sin
    of the half angle (cells, cells)) of the cones around each cell of a face, the cells
    widened by MARGIN (the same for every face)."""
    centre = (np.arange(cells) + 0.5) * (2 / cells) - 1
    u, v = np.meshgrid(centre, centre, indexing="ij")
    axis = np.stack([np.ones_like(u), u, v])
    axis /= np.sqrt((axis * axis).sum(axis=0))
    half = 1 / cells + MARGIN
    cos = np.ones_like(u)
    for du in (-half, half):
        for dv in (-half, half):
            corner = np.stack([np.ones_like(u), u + du, v + dv])
            cos = np.minimum(cos, (axis * corner).sum(axis=0)
                             / np.sqrt((corner * corner).sum(axis=0)))
    # (A hair wider for the rounding of the cosines.)
    angle = np.arccos(np.clip(cos, -1, 1)) + 1e-9
    return axis, np.cos(angle), np.sin(angle)


def _cone_near(face: int, u, v, cells: int, unit, distance, radii):
    """(near (E,), seen (E,) bool) of entries of cells (face, u, v) (E,) each for spheres
    whose centres lie along ``unit`` (3, E) at ``distance`` (E,) from the origin, radii
    (E,): the least distance at which a ray within the cell's cone (``_cell_cones``) can
    meet its sphere, and whether any can.  A ray at angle psi from the centre's direction
    enters at D cos psi - sqrt(r^2 - D^2 sin^2 psi), growing with psi, and the cone holds
    none nearer to the centre than the angle to its axis less its half angle."""
    axis, cos_half, sin_half = _cell_cones(cells)
    along, negative = face // 2, face % 2
    rows = (along, (along + 1) % 3, (along + 2) % 3)
    cell = u * cells + v
    a = axis.reshape(3, -1)
    cos_t = unit[rows[0]] * (-a[0] if negative else a[0]).take(cell)
    cos_t += unit[rows[1]] * a[1].take(cell)
    cos_t += unit[rows[2]] * a[2].take(cell)
    np.clip(cos_t, -1, 1, out=cos_t)
    sin_t = cos_t * cos_t
    np.subtract(1, sin_t, out=sin_t)
    np.sqrt(sin_t, out=sin_t)
    ch, sh = cos_half.ravel().take(cell), sin_half.ravel().take(cell)
    outside = cos_t < ch                      # the centre's direction outside the cone
    cos_p = np.where(outside, cos_t * ch + sin_t * sh, 1.0)
    lateral = sin_t * ch
    lateral -= cos_t * sh
    lateral *= distance
    lateral *= outside
    inside = distance <= radii
    seen = (cos_p > 0) & (lateral < radii)
    seen |= inside
    np.multiply(lateral, lateral, out=lateral)
    np.subtract(radii * radii, lateral, out=lateral)
    np.maximum(lateral, 0, out=lateral)
    near = distance * cos_p
    near -= np.sqrt(lateral, out=lateral)
    np.maximum(near, 0.0, out=near)
    near[inside] = 0.0
    return near, seen


def _entries(shown, first_u, last_u, first_v, last_v):
    """(u, v, owner) (E,) each: the cells of boxes ``shown`` (k,) over their cell
    rectangles (k,) each (``_face_cells``), box by box, u-major."""
    tall = last_v - first_v + 1
    area = (last_u - first_u + 1) * tall
    rank = rank_within_runs(area)
    tall = np.repeat(tall, area)
    u = np.repeat(first_u, area) + rank // tall
    v = np.repeat(first_v, area) + rank % tall
    return u, v, np.repeat(shown, area)


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
    #: Cells list their primitives by ``near`` (ties by id), to be walked front to back
    #: (``walk``), instead of by id.
    by_depth: bool = False

    @classmethod
    def build(cls, position, ids, low, high, cells: int = None, max_entries: int = None,
              max_mean: float = None, by_depth: bool = False, bounds=None,
              rounding: float = 0.0, pool=None,
              policy: GeometryPolicy = DEFAULT_POLICY) -> "OriginBins | None":
        """Bins around ``position`` (3,) of primitives ``ids`` (K,) ascending, with bounding
        boxes low, high (K, 3), with ``cells`` cells per face side, or half or a quarter as
        many when boxes near the origin would make more than ``max_entries`` entries; None
        where they do not pay (module docstring): still too many entries, or more than
        ``max_mean`` per occupied cell.  (Defaults: CELLS and the policy's max_entries and
        max_mean_candidates.)  by_depth: each cell's entries by distance from the origin
        (``walk``), with down to 1/16 of ``cells`` a side to fit ``max_entries`` (default
        max_depth_entries, and max_depth_entries_per_primitive a primitive) and no bound on
        the mean.  bounds: (centres (K, 3), radii (K,))
        float64 bounding spheres of the primitives (needed by_depth), or None: a
        primitive's ``near`` is the larger of its box's and its sphere's distance, and a
        depth-ordered entry's its cell's (``_cone_near``).  rounding: the machine epsilon
        of the kernels that will intersect the pairs: the spheres are grown by what their
        roots' rounding may add (``_rounding_slack``).  pool: a thread pool the boxes'
        terms and face ranges and the depth-ordered entries are made on, bins_chunk boxes
        (of a face) a job (None: this thread), joined in the boxes' order: the same bins."""
        cells = CELLS if cells is None else cells
        if max_entries is None:
            max_entries = policy.max_depth_entries if by_depth else policy.max_entries
        # (Depth-ordered: the finest cells within max_depth_entries_per_primitive, else the
        # coarsest, within max_entries.)
        enough = min(max_entries, policy.max_depth_entries_per_primitive * len(ids)) \
            if by_depth \
            else max_entries
        max_mean = policy.max_mean_candidates if max_mean is None else max_mean
        chunk = policy.bins_chunk
        position = np.asarray(position, np.float64)
        low, high, ids = np.asarray(low, np.float64), np.asarray(high, np.float64), np.asarray(ids)
        if by_depth and bounds is None:
            raise ValueError("depth-ordered bins need the primitives' bounding spheres")
        if bounds is not None:
            centres, radii = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
            scale = np.abs(position).max() + np.abs(centres).max()

        def boxes(part):
            """(distance, reach, radii, unit, faces' (shown, ranges)) of boxes ``part`` (a
            slice): what every box gives alone, so that the parts join into the whole's."""
            relative_low = (low[part] - position).T
            relative_high = (high[part] - position).T
            # Distance from the origin to each box (0 inside it).
            gap = np.maximum(np.maximum(relative_low, -relative_high), 0.0)
            distance = np.sqrt((gap * gap).sum(axis=0))
            del gap
            reach = grown = unit = None
            if bounds is not None:
                towards = (centres[part] - position).T
                reach = np.sqrt((towards * towards).sum(axis=0))
                grown = radii[part] + _rounding_slack(reach, radii[part], rounding, scale)
                np.maximum(distance, reach - grown, out=distance)
                with np.errstate(invalid="ignore", divide="ignore"):
                    unit = towards / reach       # (a centre at the origin: NaN, inside)
            distance *= NEAR_SLACK
            return distance, reach, grown, unit, [
                _face_ranges(relative_low, relative_high, face // 2, bool(face % 2))
                for face in range(6)]

        firsts = range(0, max(len(ids), 1), chunk)
        parts = map_on(pool, boxes, [slice(at, at + chunk) for at in firsts])
        distance = np.concatenate([part[0] for part in parts])
        if bounds is not None:
            reach, radii = (np.concatenate([part[k] for part in parts]) for k in (1, 2))
            unit = np.concatenate([part[3] for part in parts], axis=1)
        ranges = []
        for face in range(6):
            shown = [part[4][face][0] + at for at, part in zip(firsts, parts)]
            ranges.append((face, np.concatenate(shown), tuple(
                np.concatenate([part[4][face][1][k] for part in parts]) for k in range(4))))
        del parts
        sizes = [cells >> k for k in range(5 if by_depth else 3) if cells >> k >= BLOCK]
        for size in sizes:
            faces = map_on(pool, lambda face: (face[0], face[1], _face_cells(face[2], size)),
                           ranges)
            total = sum(int(((lu - fu + 1) * (lv - fv + 1)).sum())
                        for _, _, (fu, lu, fv, lv) in faces)
            if total <= enough or (size == sizes[-1] and total <= max_entries):
                break
        else:
            return None
        del ranges
        cells = size
        counts = _cell_counts(faces, cells)
        if not by_depth and total > max_mean * np.count_nonzero(counts):
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
        if by_depth:
            return cls._by_depth(cells, slots, starts, faces, ids, unit, reach, radii, pool,
                                 chunk)
        places, owners = [], []
        for face, shown, cell_ranges in faces:
            u, v, owner = _entries(shown, *cell_ranges)
            places.append(_place(slots, face, u, v, blocks, len(starts) - 2))
            owners.append(owner)
        place = np.concatenate(places)
        # Stable: within a cell, entries keep their (ascending) primitive order.
        owner = np.concatenate(owners)[np.argsort(place, kind="stable")]
        return cls(cells, slots, starts, ids.astype(np.int32)[owner], distance[owner],
                   by_depth)

    @classmethod
    def _by_depth(cls, cells, slots, starts, faces, ids, unit, reach, radii, pool, size):
        """``build``'s depth-ordered entries: each entry's near is its own cell's
        (``_cone_near``), rounded down to 2^-30 of the farthest centre, entries whose cone
        misses the sphere are dropped (the offsets are counted again), and the rest sorted
        by (cell, near).  Made ``size`` boxes at a time, so that the temporaries stay a
        few tens of MB while the entries run to millions (a chunk a job on ``pool``)."""
        blocks = cells // BLOCK
        step = max(float(reach.max(initial=0.0)), 1e-300) / 2 ** 30
        _cell_cones(cells)      # (made once, before the jobs ask for it)

        def chunk(job):
            """(place, owner, level) (e,) int32: the entries of ``size`` of a face's boxes
            from the ``at``-th, each with its cell's place, its box and its near level."""
            face, shown, (first_u, last_u, first_v, last_v), at = job
            part = slice(at, at + size)
            u, v, owner = _entries(shown[part], first_u[part], last_u[part],
                                   first_v[part], last_v[part])
            near, seen = _cone_near(face, u, v, cells, unit.take(owner, axis=1),
                                    reach.take(owner), radii.take(owner))
            seen = np.flatnonzero(seen)
            u, v, owner, near = u.take(seen), v.take(seen), owner.take(seen), near.take(seen)
            near /= step
            return (_place(slots, face, u, v, blocks, len(starts) - 2).astype(np.int32),
                    owner.astype(np.int32), np.floor(near, out=near).astype(np.int32))

        parts = map_on(pool, chunk, [(*face, at) for face in faces
                                     for at in range(0, len(face[1]), size)])
        place = np.concatenate([p[0] for p in parts])
        level = np.concatenate([p[2] for p in parts])
        owners = [p[1] for p in parts]
        del parts
        key = place.astype(np.int64) << 31
        key |= level
        order = np.argsort(key)
        del key
        counts = np.bincount(place, minlength=len(starts) - 1)
        np.cumsum(counts, out=starts[1:])
        owner = np.concatenate(owners).take(order)
        near = level.take(order) * (step * NEAR_SLACK)
        return cls(cells, slots, starts, ids.astype(np.int32).take(owner), near, True)

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
        place = int(_place(self.slots, face, np.array([u]), np.array([v]),
                           self.cells // BLOCK, len(self.starts) - 2)[0])
        return self.primitives[self.starts[place]:self.starts[place + 1]]

    def plan(self, directions, max_pairs_per_ray: float = DEFAULT_POLICY.max_pairs_per_ray):
        """(cell start (n,), candidates (n,)) of rays along unit ``directions`` (3, n), or
        None when the batch averages more than ``max_pairs_per_ray`` candidates (the tree's
        then)."""
        place = _place(self.slots, *face_cells(directions, self.cells), self.cells // BLOCK,
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
        cell_u, cell_v, sphere = _entries(np.arange(len(radii)), first_u,
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
