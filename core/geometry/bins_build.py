"""The direction bins' build (``bins``: what they are, why they are conservative, when they
pay): each box's range of face coordinates as seen from the origin (``_face_ranges``), cut
into cells (``_face_cells``), counted per cell before any entry is made (``_cell_counts``),
then listed cell by cell, in id order or (depth-ordered bins) by the least distance at
which a ray in the cell's cone can meet the primitive's bounding sphere (``_cone_near``);
and the layout the bins are stored in: cells by blocks of BLOCK x BLOCK, only where a block
lists something (``stored_place``).
"""

from __future__ import annotations

import functools

import numpy as np

from ..runs import rank_within_runs
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


def rectangle_cells(shown, first_u, last_u, first_v, last_v):
    """(u, v, owner) (E,) each: the cells of boxes ``shown`` (k,) over their cell
    rectangles (k,) each (``_face_cells``), box by box, u-major."""
    tall = last_v - first_v + 1
    area = (last_u - first_u + 1) * tall
    rank = rank_within_runs(area)
    tall = np.repeat(tall, area)
    u = np.repeat(first_u, area) + rank // tall
    v = np.repeat(first_v, area) + rank % tall
    return u, v, np.repeat(shown, area)


def stored_place(slots, face, u, v, blocks: int, empty: int) -> np.ndarray:
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


def build_origin_bins(position, ids, low, high, cells: int = None, max_entries: int = None,
                      max_mean: float = None, by_depth: bool = False, bounds=None,
                      rounding: float = 0.0, pool=None,
                      policy: GeometryPolicy = DEFAULT_POLICY):
    """The fields (cells, slots, starts, primitives, near, by_depth) of ``bins.OriginBins``
    around ``position`` (3,) of primitives ``ids`` (K,) ascending, with bounding boxes low,
    high (K, 3), with ``cells`` cells per face side, or half or a quarter as many when boxes
    near the origin would make more than ``max_entries`` entries; None where they do not
    pay (``bins``' module docstring): still too many entries, or more than ``max_mean`` per
    occupied cell.  (Defaults: CELLS and the policy's max_entries and
    max_mean_candidates.)  by_depth: each cell's entries by distance from the origin
    (``OriginBins.walk``), with down to 1/16 of ``cells`` a side to fit ``max_entries`` (default
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
        return _by_depth(cells, slots, starts, faces, ids, unit, reach, radii, pool, chunk)
    places, owners = [], []
    for face, shown, cell_ranges in faces:
        u, v, owner = rectangle_cells(shown, *cell_ranges)
        places.append(stored_place(slots, face, u, v, blocks, len(starts) - 2))
        owners.append(owner)
    place = np.concatenate(places)
    # Stable: within a cell, entries keep their (ascending) primitive order.
    owner = np.concatenate(owners)[np.argsort(place, kind="stable")]
    return cells, slots, starts, ids.astype(np.int32)[owner], distance[owner], by_depth


def _by_depth(cells, slots, starts, faces, ids, unit, reach, radii, pool, size):
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
        u, v, owner = rectangle_cells(shown[part], first_u[part], last_u[part],
                               first_v[part], last_v[part])
        near, seen = _cone_near(face, u, v, cells, unit.take(owner, axis=1),
                                reach.take(owner), radii.take(owner))
        seen = np.flatnonzero(seen)
        u, v, owner, near = u.take(seen), v.take(seen), owner.take(seen), near.take(seen)
        near /= step
        return (stored_place(slots, face, u, v, blocks, len(starts) - 2).astype(np.int32),
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
    return cells, slots, starts, ids.astype(np.int32).take(owner), near, True
