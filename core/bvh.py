"""A bounding volume hierarchy built and traversed in whole-array NumPy.

Build (``BVH.build``): a binned surface-area-heuristic (SAH) tree (Wald 2007; pbrt 4's
``BVHAggregate``), built level by level over every node of a level at once: each node's
primitives are put into BINS bins along the longest axis of their box centres, the bins'
counts and boxes come from ``bincount`` and ``minimum.at`` / ``maximum.at``, and the node is
split at the bin boundary of least SAH cost (the children's surface areas times their
primitive counts; the children's boxes come from the bins too), or kept as a leaf of at
most MAX_LEAF primitives when that costs less than any split (or when all its centres
coincide and it is small).  Large primitives (a backdrop's triangles) among small ones (a
mesh's) thus end in their own subtrees instead of inflating the small ones' boxes, which a
Morton-order tree cannot avoid.  The binary tree is then collapsed into a WIDTH-wide one: a
node's children are its binary grandchildren (a binary child that is a leaf stays one
child).

Layout: ``blocks`` (6, M, WIDTH) each wide node's child boxes as planes (low xyz, high
xyz; a plane of a node's children is contiguous), padded with NaN boxes no ray enters; ``children`` (M, WIDTH) each slot's child: a wide
node (>= 0), a leaf ``-2 - leaf`` or EMPTY; ``leaves`` (L, MAX_LEAF) each leaf's primitive
ids, padded with -1; ``leaf_boxes`` (6, L, MAX_LEAF) each leaf slot's primitive's own box,
padded as the nodes' boxes (NaN in a padding slot).  Node 0 is the root, whose own box is ``root_box``.

Traversal (``BVH.traverse``) is wavefront-style over (ray, node) pairs.  From the root down
every live pair is expanded to its children at once and kept where the ray's segment meets
the child's box.  That top phase stops at depth 1 (or a few levels down in deep trees;
``_levels``): from there the
(ray, node) pairs are sorted by entry distance and visited front to back in rounds (the
first node of each ray, then the next one, then two, four, ...): a round descends its nodes
TREELET_STEP levels, where the nodes reached are sorted and visited front to back in
rounds of their own, and so on down to the treelets, which a round descends to their
leaves, pruning by each ray's nearest hit so far; it intersects the leaves' primitives, and
a ray whose next node starts beyond its nearest hit is finished, so a ray stops at its
nearest hit; for occlusion a ray is finished at its first blocker.  (Sorting only at the
treelets made a ray of a million-sphere field test every node above them along its whole
length: 255 box tests a camera ray, against 107.)  The *treelets* are the nodes of about
WIDTH ** TREELET_DEPTH leaves (``_treelet_depth``).  Pairs are grouped by ray before each
visit, so per-ray reductions are ``reduceat``.

Occlusion rays that leave a primitive of the tree (``traverse(sources=)``) take a trail
instead (``_trail``): from the node holding their primitive's leaf up to the root, each step
meets the children of the next node up but the one already done, and descends them level by
level with no front-to-back sort, visiting leaves as it reaches them (only the primitives
whose own boxes the ray reaches), until the ray is blocked.  Blockers are mostly near the
ray's origin, so most rays never see the top of the tree; the steps' subtrees partition the
tree, so the same rays are blocked.

Boxes are padded, so culling stays conservative for rays in either precision; slab tests
run in float32 for rays that start near the origin (``ORIGIN_REACH``), else in float64.
"""

from __future__ import annotations

import dataclasses
import functools
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from .runs import rank_within_runs, run_starts, value_run_starts

#: Most primitives in a leaf, children per inner node, and the least depth (in wide levels
#: above a typical leaf) of the subtrees ("treelets") visited front to back.
MAX_LEAF = 4
WIDTH = 4
TREELET_DEPTH = 2
#: Levels between the depths at which traversal sorts pairs front to back again.
TREELET_STEP = 3
#: At most this many treelets (the front-to-back sort is over (ray, treelet) pairs).
MAX_TREELETS = 10 ** 9
#: Trees of CLUSTER_FROM primitives or more are built over Morton clusters of CLUSTER_SIZE
#: (``BVH.build``).
CLUSTER_FROM = 50_000
CLUSTER_SIZE = 4
#: Nodes of at most this many clusters split at their Morton median, not by SAH.
CLUSTER_MEDIAN_UP_TO = 16
#: Builds of at least PARALLEL_FROM primitives asked for more than one thread run parts of
#: the build on a thread pool (``BVH.build``): the binary SAH build of PARALLEL_FROM boxes or
#: more is cut at its top into parts of at most 1 / threads of the boxes (plus
#: PARALLEL_SLACK; at most PARALLEL_SPLITS cuts), each built on its own thread and joined
#: (``build_binary_sah``); NumPy releases the GIL in most of a build's array operations (not
#: in ``ufunc.at`` nor ``repeat``).  Below 50,000 the gain is a few ms and the threads'
#: cost shows on a loaded machine (the lead's 10^5 instances, 27,894 clusters: the SAH
#: build's critical path 0.031 -> 0.020 s of thread CPU, but the context 0.086-0.093 ->
#: 0.097-0.103 s wall at load 3-4; the 10^6 points' 0.90-0.96 -> 0.70-0.75 s there).
PARALLEL_FROM = 50_000
PARALLEL_SLACK = 0.15
PARALLEL_SPLITS = 8
#: Bins per axis of the SAH build, and the cost of a box test relative to a primitive test
#: (pbrt's 1/2: a wide node's box tests cost about one primitive's here too).
BINS = 16
SMALL_BINS = 4
TRAVERSAL_COST = 0.5
#: Rays traversed together: bounds the (ray, node) pairs held at once (and the rays' local
#: index fits the 16 bits of the radix sort that groups leaf pairs by ray).
RAY_CHUNK = 4096
#: Rays of a nearest-hit traversal descending a small tree unsorted (``sorts_nearest``)
#: together: nothing is sorted, and a ray holds a few pairs a level.
UNSORTED_CHUNK = 16384
#: Rays an occlusion trail (``BVH._trail``) follows together: its (ray, node) pairs are never
#: sorted, and it holds only one step's at a time (the 10^6-sphere field of issue 9: 4,096
#: rays 2.05 s, 8,192 1.87 s, 16,384 1.78 s; the 10^5 field 1.64, 1.44, 1.45 s).
TRAIL_CHUNK = 16384
#: Climbing steps a trail takes before meeting the children of the ray's home node (its leaf
#: and the leaf's siblings), which block few rays for their cost (first: 13 % of the blocked
#: rays for 18 % of the time; after 4 steps the 10^6 and 10^5 fields' replays took 0.93-0.95x).
HOME_AFTER = 4
#: Relative padding of every box (conservative culling under rounding).
BOX_PADDING = 1e-7
#: The slab tests run in float32 for rays whose origins lie within ORIGIN_REACH times the
#: tree's reach R (its largest coordinate) of the origin (the camera's eye, in the canonical
#: frame), on boxes grown by SLAB_PADDING_32 * ORIGIN_REACH * R: a slab distance's float32
#: error (rounding the box, the origin, their difference and the product with 1 / d) is
#: about 4 eps (|b| + |o| + |b - o|) / |d_axis| <= 4 eps * 2 (1 + ORIGIN_REACH) R / |d_axis|,
#: and growing a box by g moves its planes by g / |d_axis| along the ray, so every entry
#: stays at or before the float64 box's and every exit after it.  Other rays use float64.
ORIGIN_REACH = 4.0
SLAB_PADDING_32 = 16 * float(np.finfo(np.float32).eps)
#: Boxes whose planes (or Morton codes) the build makes at a time: their float64 temporaries
#: then stay in cache (the planes of 1.3 million boxes in 42 ms instead of 103).
PLANE_CHUNK = 16384
#: A slot without a child.
EMPTY = -1
#: Nearest-hit traversal sorts front to back in trees of at least this many leaves
#: (``BVH.sorts_nearest``).
SORTED_FROM = 2048
#: ... and down to the tree's widest depth where a line through the root crosses at least
#: this many leaf boxes on average (``BVH._nearest_levels``).
DEEP_SORT_CROSSINGS = 32.0


def _spread_table():
    """(2048,) uint64: each 11-bit value with two zero bits inserted after each bit."""
    v = np.arange(2048, dtype=np.uint64)
    spread = np.zeros(2048, np.uint64)
    for bit in range(11):
        spread |= ((v >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit)
    return spread


#: ``_spread_table()``, shifted for the x, y and z bits of a Morton code.
_SPREAD = tuple(_spread_table() << np.uint64(axis) for axis in range(3))


def morton_codes(points: np.ndarray) -> np.ndarray:
    """(N,) uint64 63-bit Morton codes of points (3, N) over their bounding box (a cube of
    its largest side, so that a code prefix is a cubic cell): each coordinate's 21 bits,
    spread by table 11 bits at a time."""
    low = points.min(axis=1)
    extent = (points.max(axis=1) - low).max()
    codes = np.zeros(points.shape[1], np.uint64)
    for first in range(0, points.shape[1], PLANE_CHUNK):    # (temporaries in cache)
        part = slice(first, first + PLANE_CHUNK)
        for axis in range(3):
            cells = ((points[axis, part] - low[axis]) / (extent if extent > 0 else 1)
                     * (2 ** 21 - 1)).astype(np.intp)
            codes[part] |= _SPREAD[axis].take(cells & 2047)
            codes[part] |= _SPREAD[axis].take((cells >> 11) & 1023) << np.uint64(33)
    return codes


def _cells(sorted_codes: np.ndarray, per_cell: int) -> np.ndarray:
    """(N,) bool: where a new cell starts in sorted Morton codes, for the finest cells
    (code prefixes, 3 bits a level) that hold on average at least per_cell points.  (A cell
    of prefix shift s starts where consecutive codes differ in a bit at s or above; the
    number of cells falls with s, so the shift is found by bisection.)"""
    differ = sorted_codes[1:] ^ sorted_codes[:-1]

    def cells(shift):
        return 1 + np.count_nonzero(differ >= np.uint64(1 << shift))

    shifts = list(range(0, 64, 3))
    low, high = 0, len(shifts) - 1         # the answer: the first that fits, else the last
    while low < high:
        middle = (low + high) // 2
        if cells(shifts[middle]) * per_cell <= len(sorted_codes):
            high = middle
        else:
            low = middle + 1
    return np.r_[True, differ >= np.uint64(1 << shifts[low])]


def _row_max(a):
    """(N,) the largest of each column of a (3, N)."""
    return np.maximum(np.maximum(a[0], a[1]), a[2])


def _half_area(low, high, axis=-1):
    """(...) half the surface area of boxes low, high (their xyz along ``axis``); 0 for
    empty boxes."""
    d = np.moveaxis(np.maximum(high - low, 0), axis, 0)
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0]


@dataclass(frozen=True)
class BinaryTree:
    """The SAH build's binary tree, nodes in breadth-first order (children of a node are
    consecutive: ``left`` and ``left + 1``).  low, high (3, K) node boxes; left (K,) first
    child or -1 for a leaf; start, count (K,) the node's primitives ``order[start:start +
    count]``; depth (K,); order (P,) primitive indices (into the build's input)."""

    low: np.ndarray
    high: np.ndarray
    left: np.ndarray
    start: np.ndarray
    count: np.ndarray
    depth: np.ndarray
    order: np.ndarray


def _leaf_table(ordered_ids, firsts, counts):
    """(L, MAX_LEAF) leaf rows: ordered_ids[firsts[i]:firsts[i] + counts[i]], padded with -1."""
    table = np.full((len(counts), MAX_LEAF), -1, np.intp)
    within = rank_within_runs(counts)
    table[np.repeat(np.arange(len(counts)), counts), within] = \
        ordered_ids[np.repeat(firsts, counts) + within]
    return table


def _leaf_ids(ids, slots):
    """(L, MAX_LEAF) the ids (P,) of a leaf table's slots (indices into them; -1 padding)."""
    table = np.full(slots.shape, -1, np.intp)
    held = slots >= 0
    table[held] = ids.take(slots[held])
    return table


def _box_planes(low, high, grow, sides=None):
    """(6, K) float32 planes (low xyz, high xyz) of boxes low, high (3, K): each padded by
    BOX_PADDING of its own magnitude and extent, which grow with the box (so a box's padding
    covers its primitives', and parents still hold children), then grown by ``grow`` for
    the float32 slabs (module docstring).  sides (K,), if given, is filled with each box's
    largest side."""
    planes = np.empty((6, low.shape[1]), np.float32)
    for first in range(0, low.shape[1], PLANE_CHUNK):
        part = slice(first, first + PLANE_CHUNK)
        lo, hi = low[:, part], high[:, part]
        side = _row_max(hi - lo)
        if sides is not None:
            sides[part] = side
        pad = BOX_PADDING * (2 * _row_max(np.maximum(np.abs(lo), np.abs(hi))) + side) + 1e-300
        planes[:3, part] = lo - pad - grow
        planes[3:, part] = hi + pad + grow
    return planes


def _reach(root_low, root_high) -> float:
    """The largest coordinate of a root box root_low, root_high (3,) (R, module docstring)."""
    return max(float(np.abs(root_low).max()), float(np.abs(root_high).max()))


def _leaf_planes(planes, slots):
    """(6, L, MAX_LEAF) the planes (6, P) of a leaf table's slots (L, MAX_LEAF) (indices into
    them; -1: padding, whose planes are NaN: no ray enters)."""
    pad = slots < 0
    out = planes.take(np.where(pad, 0, slots), axis=1)
    out[:, pad] = np.nan
    return out


#: Segments at least this long on average are reduced by ``reduceat``, shorter ones by
#: ``ufunc.at`` (reduceat costs about 12 ns a segment and row, ``at`` 2 ns an element).
REDUCEAT_FROM = 16


def _segment_reduce(ufunc, values, starts, segment):
    """(3, k) ``ufunc`` (minimum or maximum) of each of k segments of values (3, E), laid
    end to end (``starts`` (k,) the first of each, ``segment`` (E,) each element's; every
    segment non-empty)."""
    if values.shape[1] >= REDUCEAT_FROM * len(starts):
        return ufunc.reduceat(values, starts, axis=1)
    out = np.full((3, len(starts)), np.inf if ufunc is np.minimum else -np.inf)
    for axis in range(3):
        ufunc.at(out[axis], segment, values[axis])
    return out


def _binned_splits(c, lo, hi, segment, counts, starts, bins):
    """The best split of each of k nodes whose primitives (E,) (centres c, boxes lo, hi
    (3, E), grouped by node: ``segment`` (E,) their node, counts, starts (k,)) are put into
    ``bins`` bins along the longest axis of the node's centres (pbrt's choice): the least
    sum of the two sides' box areas times their counts.  Returns (cost (k,), inf where no
    plane separates two primitives; go_left (E,) which side each primitive goes to;
    n_left (k,) the primitives going left; the sides' boxes: left low, high, right low,
    high (3, k), from the bins' boxes)."""
    k = len(counts)
    c_low = _segment_reduce(np.minimum, c, starts, segment)
    extent = _segment_reduce(np.maximum, c, starts, segment) - c_low
    axis = np.argmax(extent, axis=0)
    rows = np.arange(k)
    length = extent[axis, rows]
    scale = np.where(length > 0, bins / np.where(length > 0, length, 1), 0)
    e = c.shape[1]
    along = c.ravel().take(axis.take(segment) * e + np.arange(e)) \
        - c_low[axis, rows].take(segment)
    index = np.minimum((along * scale.take(segment)).astype(np.intp), bins - 1)
    key = segment * bins + index
    n_bin = np.bincount(key, minlength=k * bins).reshape(k, bins)
    b_low = np.full((3, k * bins), np.inf)
    b_high = np.full((3, k * bins), -np.inf)
    for j in range(3):
        np.minimum.at(b_low[j], key, lo[j])
        np.maximum.at(b_high[j], key, hi[j])
    b_low = b_low.reshape(3, k, bins)
    b_high = b_high.reshape(3, k, bins)
    n_left = np.cumsum(n_bin, axis=1)[:, :-1]
    n_right = counts[:, None] - n_left
    left_low = np.minimum.accumulate(b_low, axis=2)
    left_high = np.maximum.accumulate(b_high, axis=2)
    right_low = np.minimum.accumulate(b_low[..., ::-1], axis=2)[..., ::-1]
    right_high = np.maximum.accumulate(b_high[..., ::-1], axis=2)[..., ::-1]
    a_left = _half_area(left_low, left_high, axis=0)[:, :-1]
    a_right = _half_area(right_low, right_high, axis=0)[:, 1:]
    cost = np.where((n_left > 0) & (n_right > 0), a_left * n_left + a_right * n_right, np.inf)
    best = np.argmin(cost, axis=1)
    return (cost[rows, best], index <= best.take(segment), n_left[rows, best],
            left_low[:, rows, best], left_high[:, rows, best],
            right_low[:, rows, best + 1], right_high[:, rows, best + 1])


def build_binary_sah(low: np.ndarray, high: np.ndarray, max_leaf: int = MAX_LEAF,
                     median_up_to: int = 1, pool=None, threads: int = 1) -> BinaryTree:
    """A binned SAH tree over boxes low, high (3, P), P >= 1, built a level at a time, with
    leaves of at most ``max_leaf`` of them.  Nodes of at most ``median_up_to`` boxes split
    at the median of their order instead (for boxes given in Morton order, which the
    stable partitions keep within every node: a cheap split, as good for small nodes).

    Each level works on the primitives of its nodes, held in order (grouped by node) as
    columns of ``data`` (low, high: (6, E); centres are made where binned) beside ``prims``
    (``_sah_level``); a level's partition moves the columns of the nodes that split on to
    the next level (``_partition``).  A node split by SAH gets its children's boxes from
    its bins; one split at the median, by reducing its children's columns.  A node of at
    most ``median_up_to`` boxes is *parked*: its subtree (halves of its order, down to
    leaves) follows from its count alone, so its columns drop out, and its subtree's boxes
    are made bottom up at the end (``_parked_boxes``).

    pool: a thread pool of ``threads`` threads, or None; with one, a build of PARALLEL_FROM
    boxes or more is built in parts on it (``_parallel_sah``): the same tree."""
    if pool is not None and threads > 1 and low.shape[1] >= PARALLEL_FROM:
        return _parallel_sah(low, high, max_leaf, median_up_to, pool, threads)
    count_all = low.shape[1]
    order = np.arange(count_all)
    data = np.concatenate([low, high])
    prims = np.arange(count_all)
    # Per level: the nodes' boxes, first child (-1: leaf), first primitive, count, depth,
    # parked.
    outs = tuple([] for _ in range(7))
    level_low, level_high = low.min(axis=1)[:, None], high.max(axis=1)[:, None]
    starts, counts = np.zeros(1, np.intp), np.array([count_all])
    parked = counts <= median_up_to
    total, depth = 1, 0
    while True:
        k = len(counts)
        lefts = np.full(k, -1, np.intp)
        for out, part in zip(outs, (level_low, level_high, lefts, starts, counts,
                                    np.full(k, depth, np.intp), parked)):
            out.append(part)
        active = np.flatnonzero(~parked)
        if len(active):
            # The active nodes' columns: their node (among the active).
            counts_a = counts.take(active)
            local_starts = run_starts(counts_a)
            segment = np.repeat(np.arange(len(active)), counts_a)
            runs = (active, counts_a, local_starts, segment)
            splits, n_left, by_sah, sides, go_left = _sah_level(
                data, counts, runs, level_low, level_high, max_leaf, median_up_to)
        else:       # (parked nodes only: halves)
            splits, n_left = counts > max_leaf, counts // 2
        parents = np.flatnonzero(splits)
        if len(parents) == 0:
            break
        # The children, in order (those of parked nodes too), and which of them are parked.
        m = len(parents)
        lefts[parents] = total + 2 * np.arange(m)
        first = starts.take(parents)
        n = n_left.take(parents)
        child_starts = np.column_stack([first, first + n]).ravel()
        child_counts = np.column_stack([n, counts.take(parents) - n]).ravel()
        child_parked = child_counts <= median_up_to
        level_low, level_high = np.full((3, 2 * m), np.nan), np.full((3, 2 * m), np.nan)
        if len(active):
            source = _partition(order, prims, go_left, starts, runs, splits, n_left, parents,
                                child_parked)
            prims = prims.take(source)
            data = data.take(source, axis=1)
            # The children's boxes: from the bins of nodes split by SAH; from their columns
            # for nodes split at the median; those of parked children are made at the end.
            from_bins = by_sah.take(parents)
            binned = parents[from_bins]
            for side in range(2):
                level_low[:, side::2][:, from_bins] = sides[2 * side][:, binned]
                level_high[:, side::2][:, from_bins] = sides[2 * side + 1][:, binned]
            reduced = ~np.repeat(from_bins, 2) & ~child_parked
            if reduced.any():
                counts_on = child_counts[~child_parked]
                columns = data if reduced[~child_parked].all() else np.compress(
                    np.repeat(reduced[~child_parked], counts_on), data, axis=1)
                child_first = run_starts(child_counts[reduced])
                segment = np.repeat(np.arange(len(child_first)), child_counts[reduced])
                level_low[:, reduced] = _segment_reduce(np.minimum, columns[:3], child_first,
                                                        segment)
                level_high[:, reduced] = _segment_reduce(np.maximum, columns[3:], child_first,
                                                         segment)
        starts, counts, parked = child_starts, child_counts, child_parked
        total += 2 * m
        depth += 1
    tree_low, tree_high, left, start, count, depths, parked = (
        np.concatenate(parts, axis=-1) for parts in outs)
    if parked.any():
        _parked_boxes(tree_low, tree_high, left, start, count, parked,
                      np.cumsum([0] + [len(part) for part in outs[2]]), low, high, order)
    return BinaryTree(tree_low, tree_high, left, start, count, depths, order)


def _parallel_sah(low, high, max_leaf, median_up_to, pool, threads) -> BinaryTree:
    """``build_binary_sah``'s tree, built in parts on ``pool``.  The root is split (as the
    build's first level splits it, ``_root_split``), then the largest part again, until
    every part holds at most 1 / threads of the boxes (plus PARALLEL_SLACK) or PARALLEL_SPLITS
    cuts are made; the parts are built apart, the largest first, and joined under the nodes
    that were cut (``_joined``).  A node's subtree depends on its boxes alone (their order
    within it is the order the stable partitions leave, and its box is their exact bounds),
    so the joined tree is the one a single build makes."""
    # Parts: (columns (into low, high), their low, high); cuts: part -> (its root box, its
    # children's parts, and their columns within it).
    parts = {0: (np.arange(low.shape[1]), low, high)}
    cuts = {}
    target = low.shape[1] / threads * (1 + PARALLEL_SLACK)
    while len(cuts) < PARALLEL_SPLITS:
        largest = max((key for key in parts if key not in cuts), key=lambda k: len(parts[k][0]))
        columns, lo, hi = parts[largest]
        if len(columns) <= max(target, max_leaf, median_up_to):
            break
        box, halves = _root_split(lo, hi, max_leaf, median_up_to)
        children = []
        for half in halves:
            children.append(len(parts))
            parts[len(parts)] = (half, lo.take(half, axis=1), hi.take(half, axis=1))
        cuts[largest] = (box, children, halves)
    built = {}
    for key in sorted((k for k in parts if k not in cuts), key=lambda k: -len(parts[k][0])):
        built[key] = pool.submit(build_binary_sah, parts[key][1], parts[key][2], max_leaf,
                                 median_up_to)

    def tree(key):
        if key not in cuts:
            return built[key].result()
        box, (left, right), halves = cuts[key]
        return _joined(box, tree(left), tree(right), *halves)

    return tree(0)


def _root_split(low, high, max_leaf, median_up_to):
    """(root box (low, high (3,)), (left, right)): the columns (increasing) of the two
    children that ``build_binary_sah``'s first level splits boxes low, high (3, P) into
    (P > max_leaf and P > median_up_to: the root splits, by SAH or at its median)."""
    count = low.shape[1]
    counts, first = np.array([count]), np.zeros(1, np.intp)
    box = low.min(axis=1), high.max(axis=1)
    runs = (first, counts, first, np.zeros(count, np.intp))
    go_left = _sah_level(np.concatenate([low, high]), counts, runs, box[0][:, None],
                         box[1][:, None], max_leaf, median_up_to)[4]
    return box, (np.flatnonzero(go_left), np.flatnonzero(~go_left))


def _joined(box, a: BinaryTree, b: BinaryTree, a_columns, b_columns) -> BinaryTree:
    """The binary tree of a root (box: low, high (3,)) whose children's subtrees a and b
    were built apart over its columns a_columns and b_columns, in the order one build makes:
    breadth first, level d + 1 holding a's level d, then b's, children of a node
    consecutive.  (A subtree's level is one stretch of nodes there: copied a level at a
    time.)"""
    levels = max(a.depth[-1], b.depth[-1]) + 1
    sizes = np.zeros((2, levels), np.intp)
    for row, part in enumerate((a, b)):
        sizes[row, :part.depth[-1] + 1] = np.bincount(part.depth)
    # Where each subtree's level l starts in the joined tree (its level l + 1), and in the
    # subtree itself.
    joined_first = (1 + run_starts(sizes.sum(axis=0)) + np.stack([np.zeros(levels, np.intp),
                                                                   sizes[0]])).tolist()
    own_first = np.stack([run_starts(sizes[0]), run_starts(sizes[1])]).tolist()
    total = 1 + len(a.depth) + len(b.depth)
    low, high = np.empty((3, total)), np.empty((3, total))
    left, start, count, depth = (np.empty(total, np.intp) for _ in range(4))
    low[:, 0], high[:, 0] = box
    left[0], start[0], count[0], depth[0] = 1, 0, len(a.order) + len(b.order), 0
    for row, part, offset in ((0, a, 0), (1, b, len(a.order))):
        for level, size in enumerate(sizes[row].tolist()):
            if size == 0:
                break
            own = slice(own_first[row][level], own_first[row][level] + size)
            there = slice(joined_first[row][level], joined_first[row][level] + size)
            low[:, there], high[:, there] = part.low[:, own], part.high[:, own]
            np.add(part.start[own], offset, out=start[there])
            count[there] = part.count[own]
            depth[there] = level + 1
            # (Children are on the next level, which moves by its own shift.)
            children = part.left[own]
            if level + 1 < levels:
                shift = joined_first[row][level + 1] - own_first[row][level + 1]
                np.copyto(left[there], np.where(children >= 0, children + shift, -1))
            else:
                left[there] = children
    order = np.concatenate([a_columns.take(a.order), b_columns.take(b.order)])
    return BinaryTree(low, high, left, start, count, depth, order)


def _sah_level(data, counts, runs, level_low, level_high, max_leaf, median_up_to):
    """A level's splits: its nodes (k,) (counts; boxes level_low, level_high (3, k)), of
    which the active ones (``runs``: active (a,), their counts and first columns (a,), each
    column's node among them (E,)) have their columns data (6, E).
    Returns (splits (k,) whether each node splits, n_left (k,) the primitives of its left
    child, by_sah (k,) split at an SAH plane, sides (4, 3, k) the boxes of those nodes'
    children (left low, high, right low, high), go_left (E,) each column's side; True for
    every column of a node that stays a leaf, so that its order stays)."""
    active, counts_a, local_starts, segment = runs
    k = len(counts)
    # SAH costs per size class (bins per axis: BINS, or SMALL_BINS for small nodes, so
    # the bins' work stays within the primitives'); nodes of one primitive are leaves.
    best_cost = np.full(k, np.inf)
    go_left = np.zeros(data.shape[1], bool)
    n_left = counts // 2
    sides = np.full((4, 3, k), np.nan)
    for bins, members in ((BINS, counts_a > max(BINS, median_up_to)),
                          (SMALL_BINS, (counts_a > median_up_to) & (counts_a <= BINS))):
        nodes = np.flatnonzero(members)
        if len(nodes) == 0:
            continue
        if len(nodes) == len(active):
            mine, local, local_first = data, segment, local_starts
        else:
            mine = np.compress(np.repeat(members, counts_a), data, axis=1)
            local = np.repeat(np.arange(len(nodes)), counts_a[nodes])
            local_first = run_starts(counts_a[nodes])
        binned = active.take(nodes)
        best_cost[binned], left, n_left[binned], *boxes = _binned_splits(
            (mine[:3] + mine[3:]) / 2, mine[:3], mine[3:], local, counts_a[nodes], local_first,
            bins)
        sides[:, :, binned] = boxes
        if len(nodes) == len(active):
            go_left = left
        else:
            go_left[np.repeat(members, counts_a)] = left
    area = _half_area(level_low, level_high, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        split_cost = TRAVERSAL_COST + best_cost / area
    # A split is taken when it costs less than a leaf of N primitives (cost N), and always
    # for a node too big for a leaf: at the median of its order when no plane separates its
    # primitives (all centres in one bin: coincident primitives), or when it is small (the
    # parked nodes, whose boxes are not known yet, among them: their cost is inf).
    median = ~np.isfinite(split_cost)
    splits = (counts > max_leaf) | (~median & (split_cost < counts))
    n_left = np.where(median, counts // 2, n_left)
    median_a, splits_a = median.take(active), splits.take(active)
    if median_a.any():
        rank = np.arange(len(go_left)) - np.repeat(local_starts, counts_a)
        go_left = np.where(np.repeat(median_a, counts_a),
                           rank < np.repeat(n_left.take(active), counts_a), go_left)
    if not splits_a.all():
        go_left |= np.repeat(~splits_a, counts_a)
    return splits, n_left, splits & ~median, sides, go_left


def _partition(order, prims, go_left, starts, runs, splits, n_left, parents, child_parked):
    """The stable partition of a level's columns (``_sah_level``): each splitting node's
    primitives, its lefts first, written into ``order`` at its starts (k,); returns the
    columns (E',) that go on to the next level, in its order: those of the children
    (2 * len(parents),) that are not parked (``child_parked``)."""
    active, counts_a, local_starts, segment = runs
    splits_a = splits.take(active)
    n_left_a = np.where(splits_a, n_left.take(active), counts_a)    # a leaf: all left
    # Where each column goes with every node's lefts, then rights, packed: a left one to
    # its node's first column + the lefts before it in the node; a right one to its own
    # column + its node's lefts not before it (b: the lefts before each column, b0 before
    # each node's first).
    column = np.arange(len(go_left))
    before = np.cumsum(go_left) - go_left
    b0 = before.take(local_starts)
    dest = np.where(go_left, before + np.repeat(local_starts - b0, counts_a),
                    column - before + np.repeat(n_left_a + b0, counts_a))
    order[dest + np.repeat(starts.take(active) - local_starts, counts_a)] = prims
    # Then without the parts that do not go on (leaves, parked children).
    parent_rank = np.zeros(len(splits), np.intp)
    parent_rank[parents] = np.arange(len(parents))
    child = 2 * parent_rank.take(active)
    keep = np.column_stack([splits_a & ~child_parked.take(child),
                            splits_a & ~child_parked.take(child + 1)]).ravel()
    if keep.all():
        source = np.empty_like(dest)
        source[dest] = column
        return source
    dropped = np.where(keep, 0, np.column_stack([n_left_a, counts_a - n_left_a]).ravel())
    shift = np.cumsum(dropped) - dropped
    part = 2 * segment + ~go_left
    rows = np.flatnonzero(keep.take(part))
    source = np.empty_like(rows)
    source[dest.take(rows) - shift.take(part.take(rows))] = rows
    return source


def _parked_boxes(tree_low, tree_high, left, start, count, parked, level_starts, low, high,
                  order):
    """Fill in the boxes (3, K) of the parked nodes of a binary tree (``build_binary_sah``;
    level_starts: the first node of each level, and the node count): a leaf's from its
    primitives' boxes low, high (3, P) (``order[start:start + count]``), an inner node's
    from its children's, the deepest level first (children of a parked node are parked)."""
    leaf = np.flatnonzero(parked & (left < 0))
    n = count.take(leaf)
    members = order.take(np.repeat(start.take(leaf), n) + rank_within_runs(n))
    if (n == 1).all():
        tree_low[:, leaf], tree_high[:, leaf] = low.take(members, axis=1), high.take(members,
                                                                                     axis=1)
    else:
        first, segment = run_starts(n), np.repeat(np.arange(len(leaf)), n)
        for boxes, ufunc, source in ((tree_low, np.minimum, low), (tree_high, np.maximum, high)):
            boxes[:, leaf] = _segment_reduce(ufunc, source.take(members, axis=1), first, segment)
    for level in range(len(level_starts) - 2, -1, -1):
        span = slice(level_starts[level], level_starts[level + 1])
        inner = span.start + np.flatnonzero(parked[span] & (left[span] >= 0))
        if len(inner) == 0:
            continue
        pair = left.take(inner)
        for boxes, ufunc in ((tree_low, np.minimum), (tree_high, np.maximum)):
            boxes[:, inner] = ufunc(boxes.take(pair, axis=1), boxes.take(pair + 1, axis=1))


def _spread(values, dtype, k=WIDTH):
    """(..., k) values (...) as dtype, each repeated k times (for k = 1: values itself, in
    dtype): per-ray terms laid out as the (..., m, WIDTH) slots of m nodes."""
    values = values.astype(dtype, copy=False)   # (cast once, not in each of the k copies)
    if k == 1:
        return values[..., None]
    out = np.empty(values.shape + (k,), dtype)
    for slot in range(k):
        out[..., slot] = values
    return out


def _ray_terms(origins, inverse, dtype, k=WIDTH):
    """The rays' terms of the slab tests, in dtype: origins (3, 1) (a shared origin) or
    (3, n, k), inverse (3, n, k) (``_spread``: each ray's value once per slot, so that
    a node's (6, m, k) child planes meet them element for element)."""
    if origins.shape[1] == 1:
        return origins.astype(dtype), _spread(inverse, dtype, k)
    return _spread(origins, dtype, k), _spread(inverse, dtype, k)


def _split(*masks_and_arrays):
    """For each (mask (E,), arrays) given in turn: the arrays' elements where the mask holds,
    in order (None stays None), through one index per mask (cheaper than a boolean
    mask applied to each array)."""
    parts = []
    for mask, arrays in zip(masks_and_arrays[::2], masks_and_arrays[1::2]):
        at = np.flatnonzero(mask)
        parts.append(tuple(None if a is None else a.take(at) for a in arrays))
    return parts


#: Bits of a packed sort key (``front_to_back``): a pair's ray within its chunk, its entry
#: distance (float32 bits, made monotonic), its position.
_RAY_BITS, _NEAR_BITS, _POSITION_BITS = 12, 32, 20
assert RAY_CHUNK <= 1 << _RAY_BITS and _RAY_BITS + _NEAR_BITS + _POSITION_BITS == 64


def front_to_back(local, near) -> np.ndarray:
    """(E,) the order of pairs (E,) by ray (``local``: each pair's ray within its chunk, in
    0 .. RAY_CHUNK - 1) and, within a ray, by entry distance ``near`` (E,), nearest first.

    float32 entries (the slabs' precision near the origin) and fewer than 2 ** 20 pairs:
    one sort of packed 64-bit keys (ray, the entry's bits made monotonic, the pair's
    position: all keys distinct, so equal entries keep their order), a value sort, several
    times cheaper than the argsorts it replaces (a float argsort, then a stable one by ray).
    Otherwise those argsorts (equal entries in the quicksort's order)."""
    count = len(near)
    if near.dtype == np.float32 and count < 1 << _POSITION_BITS:
        # Floats as unsigned integers in the same order: the sign bit set on positives,
        # every bit flipped on negatives (-0.0 made 0.0 first: the two are equal).
        bits = (near + np.float32(0)).view(np.uint32)
        flip = np.where(bits >= np.uint32(1 << 31), np.uint32(0xFFFFFFFF),
                        np.uint32(1 << 31))
        key = local.astype(np.uint64) << np.uint64(_NEAR_BITS + _POSITION_BITS)
        key |= (bits ^ flip).astype(np.uint64) << np.uint64(_POSITION_BITS)
        key |= np.arange(count, dtype=np.uint64)
        key.sort()
        return (key & np.uint64((1 << _POSITION_BITS) - 1)).astype(np.intp)
    order = np.argsort(near)
    return order.take(np.argsort(local.take(order).astype(np.uint16), kind="stable"))


def keep_nearest(rays, prims, t, t_max, found, accept, any_hit):
    """Settles a visit's pairs (ray, primitive) (E,), grouped by ray, each primitive at most
    once per ray, with hit distances t (E,) (inf: none): ``found`` (n,) set for each ray with
    a hit (any_hit: any t < inf; else nearer than its t_max (n,) float64, which is lowered to
    it), and ``accept(rays, pairs)`` told which pair (index into t) is each improved ray's new
    nearest hit, ties to the lower primitive id (``BVH.traverse``'s contract; the direction
    bins, ``core.bins``, keep it too)."""
    if any_hit:
        # (Any pair with a hit blocks its ray: no grouping needed.)
        found[rays[t < np.inf]] = True
        return
    group = value_run_starts(rays)
    nearest = np.minimum.reduceat(t, group)
    owner = rays.take(group)
    hit = nearest < t_max.take(owner)
    found[owner[hit]] = True
    if not hit.any():
        return
    lengths = np.diff(group, append=len(t))
    # The pairs at an improved ray's minimum, then of those its lowest primitive id.
    at_min = np.flatnonzero((t == np.repeat(nearest, lengths)) & np.repeat(hit, lengths))
    first = value_run_starts(rays.take(at_min))
    if len(first) == len(at_min):
        winner = at_min     # (no ray has two pairs at its minimum: nothing to break)
    else:
        tied = prims.take(at_min)
        lowest = np.minimum.reduceat(tied, first)
        winner = at_min[tied == np.repeat(lowest, np.diff(first, append=len(at_min)))]
    t_max[owner[hit]] = nearest[hit]
    if accept is not None:
        accept(owner[hit], winner)


@contextmanager
def thread_pool(threads: int):
    """A pool of ``threads`` threads for the duration of a build, or None for one thread."""
    if threads <= 1:
        yield None
        return
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="glint-build") as pool:
        yield pool


def run_on(pool, function, *args) -> Future:
    """function(*args) on ``pool``, or now where there is none: its Future."""
    if pool is not None:
        return pool.submit(function, *args)
    done = Future()
    done.set_result(function(*args))
    return done


def map_on(pool, function, items) -> list:
    """[function(item) for item in items], on ``pool`` where there is one (in order)."""
    if pool is None:
        return [function(item) for item in items]
    return list(pool.map(function, items))


@dataclass(frozen=True)
class BVH:
    """A WIDTH-wide tree (module docstring): root_box (6,) low xyz, high xyz; blocks
    (6, M, WIDTH); children (M, WIDTH); leaves (L, MAX_LEAF) primitive ids or -1;
    child_counts (M,) real slots of each node; depths (M,) each node's depth (root 0);
    leaf_boxes (6, L, MAX_LEAF) or None (below)."""

    root_box: np.ndarray
    blocks: np.ndarray
    children: np.ndarray
    leaves: np.ndarray
    child_counts: np.ndarray
    depths: np.ndarray
    origin_reach: float = np.inf     # float32 slabs for rays from within this of the origin
    #: (6, L, MAX_LEAF) float32 planes of each leaf slot's primitive's own box, padded as the
    #: nodes' are (NaN: an empty slot), or None: occlusion trails cull a leaf's primitives
    #: by these before visiting them (``_descend_all``).
    leaf_boxes: np.ndarray | None = None

    @classmethod
    def build(cls, ids: np.ndarray, low: np.ndarray, high: np.ndarray,
              threads: int = 1) -> "BVH":
        """A tree over primitives ``ids`` (P,) (P >= 1) with boxes low, high (P, 3).

        Up to CLUSTER_FROM primitives the SAH build sees every primitive; above, it sees
        clusters of CLUSTER_SIZE primitives consecutive in Morton order (of one size class:
        their boxes' largest side within a factor of 4), which become the leaves: the build
        then costs a CLUSTER_SIZE-th, and the clusters are as tight as Morton leaves.
        threads: how many threads the build may use (from PARALLEL_FROM primitives: the
        primitives' planes and the leaves' are made beside the rest, the SAH build in parts;
        the same tree for any number).  (A render builds it without transparent huge pages:
        ``allocator.small_pages``.)"""
        ids = np.asarray(ids)
        # The boxes as columns (3, P): every pass below then runs over contiguous rows.
        low, high = np.ascontiguousarray(low.T), np.ascontiguousarray(high.T)
        with thread_pool(threads if low.shape[1] >= PARALLEL_FROM else 1) as pool:
            return cls._build(ids, low, high, pool, threads)

    @classmethod
    def _build(cls, ids, low, high, pool, threads) -> "BVH":
        """``build`` on boxes low, high (3, P), parts of it on ``pool`` (or None)."""
        count = low.shape[1]
        # Each primitive's own box as float32 planes, for the leaves' slots (``leaf_boxes``);
        # the root's box is every primitive's.
        grow = SLAB_PADDING_32 * ORIGIN_REACH * _reach(low.min(axis=1), high.max(axis=1))
        size = np.empty(count)
        planes = run_on(pool, _box_planes, low, high, grow, size)
        if count < CLUSTER_FROM:
            tree = build_binary_sah(low, high, pool=pool, threads=threads)
            leaf = tree.left < 0
            slots = _leaf_table(tree.order, tree.start[leaf], tree.count[leaf])
            return cls._collapsed(tree, ids, slots, planes, pool)
        codes = morton_codes((low + high) / 2)
        order = np.argsort(codes)
        planes.result()     # (which fills size)
        np.maximum(size, 1e-300, out=size)
        # One size class when the largest box is under 2 ** 1.5 times the smallest (every
        # log2 then within 2 of the least: floor 0 below), as for a cloud of equal spheres.
        mixed = np.log2(size.max()) - np.log2(size.min()) >= 1.5
        if mixed:       # (a stable sort of one class would keep the order)
            size = np.log2(size)
            size_class = np.floor((size - size.min()) / 2).astype(np.intp).take(order)
            by_class = np.argsort(np.minimum(size_class, np.iinfo(np.uint16).max)
                                  .astype(np.uint16), kind="stable")
            order, size_class = order.take(by_class), size_class.take(by_class)
            mixed = size_class.min() < size_class.max()
        # Cluster boundaries: every CLUSTER_SIZE primitives within a run of one size class
        # in one Morton cell (cells of about CLUSTER_SIZE primitives: a cluster never
        # spans a jump of the curve).
        run_start = _cells(codes.take(order), CLUSTER_SIZE)
        if mixed:
            run_start[1:] |= size_class[1:] != size_class[:-1]
        run = np.flatnonzero(run_start)
        per_run = -(-np.diff(np.r_[run, count]) // CLUSTER_SIZE)
        firsts = np.repeat(run, per_run) + CLUSTER_SIZE * rank_within_runs(per_run)
        counts = np.diff(np.r_[firsts, count])
        # The clusters' boxes, reduced from the primitives where they are (cheaper than
        # gathering them in Morton order first).
        cluster = np.empty(count, np.intp)
        cluster[order] = np.repeat(np.arange(len(firsts)), counts)
        c_low, c_high = np.full((3, len(firsts)), np.inf), np.full((3, len(firsts)), -np.inf)
        for axis in range(3):
            np.minimum.at(c_low[axis], cluster, low[axis])
            np.maximum.at(c_high[axis], cluster, high[axis])
        del codes, size, run_start, run, per_run, cluster, low, high
        tree = build_binary_sah(c_low, c_high, max_leaf=1, median_up_to=CLUSTER_MEDIAN_UP_TO,
                                pool=pool, threads=threads)
        # Each binary leaf holds one cluster: the one at its position in the build's order.
        chosen = tree.order[tree.start[tree.left < 0]]
        slots = _leaf_table(order, firsts[chosen], counts[chosen])
        return cls._collapsed(tree, ids, slots, planes, pool)

    @classmethod
    def _collapsed(cls, tree, ids, slots, planes, pool) -> "BVH":
        """The wide tree of a binary one whose leaves hold ``slots`` (L, MAX_LEAF) (indices
        into ids; -1: padding), with their primitives' planes (``planes``: a Future of the
        (6, P) planes of every primitive), made on ``pool`` beside the collapse."""
        leaf_boxes = run_on(pool, lambda: _leaf_planes(planes.result(), slots))
        wide = cls.collapse(tree, _leaf_ids(ids, slots))
        return dataclasses.replace(wide, leaf_boxes=leaf_boxes.result())

    @classmethod
    def collapse(cls, tree: BinaryTree, leaves: np.ndarray, leaf_boxes=None) -> "BVH":
        """The WIDTH-wide tree of a binary one; leaves (L, MAX_LEAF): the primitives of its
        leaves (in node order), padded with -1; leaf_boxes (6, L, MAX_LEAF): their own boxes'
        planes (``_leaf_planes``; grown as the tree's), or None."""
        inner = tree.left >= 0
        leaf_nodes = np.flatnonzero(~inner)
        leaf_index = np.full(len(tree.left), -1, np.intp)
        leaf_index[leaf_nodes] = np.arange(len(leaf_nodes))
        if not inner[0]:
            # A single leaf: a root with one child.
            wide = np.zeros(1, np.intp)
            slots = np.full((1, WIDTH), -1, np.intp)
            slots[0, 0] = 0
        else:
            # Wide nodes: the binary inner nodes at even depth; each one's slots are its
            # children, opened once more where a child is inner.
            wide = np.flatnonzero(inner & (tree.depth % 2 == 0))
            first = tree.left[wide]
            pair = np.stack([first, first + 1], axis=1)                       # (M, 2)
            grand = tree.left[pair]                                           # (M, 2)
            slots = np.full((len(wide), 2, 2), -1, np.intp)
            opened = grand >= 0
            slots[..., 0] = np.where(opened, grand, pair)
            slots[..., 1] = np.where(opened, grand + 1, -1)
            slots = slots.reshape(-1, WIDTH)
        wide_index = np.full(len(tree.left), -1, np.intp)
        wide_index[wide] = np.arange(len(wide))
        real = slots >= 0
        safe = np.where(real, slots, 0)
        # Each binary node's reference: a wide node, or a leaf.
        reference = np.where(inner, wide_index, -2 - leaf_index)
        children = np.where(real, reference.take(safe), EMPTY)
        # float32 boxes, grown by SLAB_PADDING_32 of the tree's reach (module docstring); a
        # padding slot's box is NaN.
        reach = _reach(tree.low[:, 0], tree.high[:, 0])
        grow = SLAB_PADDING_32 * ORIGIN_REACH * reach
        every = safe.ravel()
        blocks = _box_planes(tree.low.take(every, axis=1), tree.high.take(every, axis=1),
                             grow).reshape((6,) + slots.shape)
        blocks[:, ~real] = np.nan
        low, high = tree.low[:, 0], tree.high[:, 0]
        pad = BOX_PADDING * (2 * max(np.abs(low).max(), np.abs(high).max())
                             + (high - low).max()) + 1e-300
        root_box = np.concatenate([low - pad - grow, high + pad + grow]).astype(np.float32)
        return cls(root_box, blocks, children, leaves, real.sum(axis=1),
                   tree.depth[wide] // 2, ORIGIN_REACH * reach, leaf_boxes)

    @property
    def node_count(self) -> int:
        return len(self.children)

    def primitives(self) -> np.ndarray:
        """(P,) every primitive id the leaves hold, in leaf order."""
        return self.leaves[self.leaves >= 0]

    def _treelet_depth(self) -> int:
        """The depth of the treelets: the deepest whose nodes, each holding about
        WIDTH ** TREELET_DEPTH leaves, are at most MAX_TREELETS."""
        per_depth = self._depth_counts
        fit = (per_depth * WIDTH ** TREELET_DEPTH <= len(self.leaves)) \
            & (per_depth <= MAX_TREELETS)
        fit[0] = True
        return int(np.argmin(np.r_[fit, False])) - 1

    # ---- traversal ----------------------------------------------------------------------

    def traverse(self, origins, inverse, t_min, t_max, visit, accept=None, *, any_hit=False,
                 sources=None, leaf_blocks=None, slot_visit=None, stats=None):
        """Visit, front to back, the primitives whose leaves each ray's segment reaches.

        origins (3, n) or (3, 1) and inverse (3, n) (1 / direction) float64; t_min scalar
        or (n,), t_max (n,) float64, updated in place as hits are found.
        ``visit(rays, prims)`` gets (ray, primitive) pairs (E,) grouped by ray and returns
        each pair's hit distance (inf for none; with ``any_hit`` any value < inf blocks).
        ``accept(rays, pairs)`` is told, after each visit, which pair (index into that
        visit's pairs) is each improved ray's new nearest hit (ties: the lower primitive id).
        ``sources`` (n,) (any_hit only): the primitive each ray leaves (-1: none); a ray
        leaving a primitive of the tree follows its trail (``_trail``) instead of coming
        down from the root.
        ``leaf_blocks(rays, slots)`` (with sources; optional): the trails' visit by leaf
        slot instead of by primitive: given (ray, slot) pairs (E,) (a slot indexes
        ``leaves.ravel()``), the rays (k,) (repeats allowed) whose slot's primitive blocks
        them, as ``visit`` would say.
        ``slot_visit(rays, slots)`` (nearest hits; optional): the sorted traversal's leaf
        visit by slot (``_visit_boxed_leaves``): given (ray, slot) pairs (E,) grouped by
        ray, (kept (k,) the pairs it tested, an index into them (the rest cannot hit),
        their primitives (k,), their hit distances (k,) as ``visit`` gives them); ``accept``
        is then told pairs as indices into the kept ones.
        Returns (n,) bool: whether a hit (any_hit: a blocker) was found for each ray.
        """
        # (The slab tests' 0 * inf, a ray in a box's plane, is NaN and ignored there
        # (``_slabs``): one error state for the whole traversal, not one per box test
        # call, which cost about 3 % of the trails' time.)
        with np.errstate(invalid="ignore"):
            return self._traverse_rays(origins, inverse, t_min, t_max, visit, accept,
                                       any_hit, sources, leaf_blocks, slot_visit, stats)

    def _traverse_rays(self, origins, inverse, t_min, t_max, visit, accept, any_hit, sources,
                       leaf_blocks, slot_visit, stats):
        n = inverse.shape[1]
        found = np.zeros(n, bool)
        near_origin = np.abs(origins).max(initial=0) <= self.origin_reach
        dtype = np.float32 if near_origin else np.float64
        rows = _ray_terms(origins, inverse, dtype)
        if any_hit and sources is not None:
            starts = self._start_nodes(sources)
            trailed = np.flatnonzero(starts >= 0)
            # (The climbing steps meet WIDTH - 1 siblings: terms spread for those.)
            climb_rows = _ray_terms(origins, inverse, dtype, WIDTH - 1) if len(trailed) else None
            for first in range(0, len(trailed), TRAIL_CHUNK):
                part = trailed[first:first + TRAIL_CHUNK]
                # (Rays with no end, a sun's or the world's, skip the slabs' bound: None.)
                bound = None if np.isposinf(t_max.take(part)).all() else t_max
                self._trail(part, starts.take(part), rows, climb_rows, t_min, bound, visit,
                            found, stats, leaf_blocks)
            if len(trailed) < n:
                # The rest (rays leaving no primitive of the tree) from the root.
                rest = np.flatnonzero(starts < 0)
                found[rest] = self.traverse(
                    origins if origins.shape[1] == 1 else origins[:, rest], inverse[:, rest],
                    t_min if np.ndim(t_min) == 0 else t_min[rest], t_max[rest],
                    lambda r, prims: visit(rest.take(r), prims), any_hit=True, stats=stats)
            return found
        levels = self._levels() if any_hit else self._nearest_levels
        # (Unsorted descents hold a few pairs a ray and sort nothing: larger chunks, fewer
        # calls.)
        chunk = RAY_CHUNK if levels is not None else UNSORTED_CHUNK
        for first in range(0, n, chunk):
            self._traverse(first, min(first + chunk, n), levels, rows, t_min, t_max,
                           visit, accept, found, any_hit, stats, slot_visit)
        return found

    @functools.cached_property
    def sorts_nearest(self) -> bool:
        """Whether nearest-hit traversal visits (ray, node) pairs front to back
        (``_rounds``), or descends every pair level by level with no sort, visiting leaves as
        it reaches them (``_descend_all``): trees of fewer than SORTED_FROM leaves, where
        rays meet few leaves (issue 9's 1,000 spheres: 1.6 a reflection ray) and the sorts
        and nested rounds cost more than the box tests they save (its reflection rays'
        nearest hits replayed: 0.89-0.91x the time with 8 % more box tests; a 10^4-sphere
        set's rays: 1.4-1.8x, 3,000 spheres: even)."""
        return len(self.leaves) >= SORTED_FROM

    def _levels(self, deepest: int = None) -> list:
        """The depths at which traversal sorts (ray, node) pairs front to back: the treelets'
        (``_treelet_depth``, or ``deepest``), and every TREELET_STEP levels above it down to
        depth 1."""
        deepest = self._treelet_depth() if deepest is None else deepest
        return sorted(range(deepest, 0, -TREELET_STEP)) or [0]

    @functools.cached_property
    def leaf_crossings(self) -> float:
        """The expected number of leaf boxes a random line through the root box crosses:
        the leaves' surface areas over the root's (the SAH's probabilities).  About 2.5 for
        a terrain of triangles, 5 for 10^4 of issue 9's random spheres, 40 for 10^5."""
        leaf = self.children < -1
        low, high = (self.blocks[:3][:, leaf].T.astype(np.float64),
                     self.blocks[3:][:, leaf].T.astype(np.float64))
        root = self.root_box.astype(np.float64)
        whole = float(_half_area(root[:3], root[3:]))
        return float(_half_area(low, high).sum()) / whole if whole > 0 else 0.0

    @functools.cached_property
    def _nearest_levels(self):
        """The sort depths of nearest-hit traversal (``_levels``), or None where it does not
        sort (``sorts_nearest``).  In dense fields (``leaf_crossings`` of DEEP_SORT_CROSSINGS
        or more) the last sort is at the tree's widest depth (the most nodes: below it nodes
        hold a few leaves), not at the treelets of WIDTH ** TREELET_DEPTH leaves: a ray then
        stops within a few leaves of its hit instead of visiting every leaf its segment
        meets in a treelet.  (Every nearest-hit batch of a 640x360 frame replayed, issue 9's
        sphere sets: 10^5 spheres, 39 crossings, 0.59-0.66x the time, sphere tests halved;
        10^6, 276 crossings, 0.73-0.78x; the lead's 10^6 point cloud, 64 crossings, even.
        Where rays meet fewer leaves the sorts cost more than they save: its 10^5 GN
        instances (24.2) 1.05-1.17x, 3 x 10^4 spheres (15.6) 1.06-1.10x, 10^4 (5.4) 1.05x,
        a 320,000-triangle terrain (2.5) 1.3x.)"""
        if not self.sorts_nearest:
            return None
        if self.leaf_crossings < DEEP_SORT_CROSSINGS:
            return self._levels()
        return self._levels(int(np.argmax(self._depth_counts)))

    @functools.cached_property
    def _depth_counts(self) -> np.ndarray:
        """(D,) the number of wide nodes at each depth (counted once: a traversal asks for
        its sort depths on every batch)."""
        return np.bincount(self.depths)

    def _traverse(self, first, stop, levels, rows, t_min, t_max, visit, accept, found,
                  any_hit, stats, slot_visit=None):
        """Rays first .. stop - 1 from the root: front to back, sorting at ``levels``
        (``_levels``), or (levels None) level by level unsorted (``sorts_nearest``)."""
        rays = np.arange(first, stop)
        if levels is None:
            # (No test of the root's own box: its children's tests answer for it, which
            # saves a test a ray where nearly every ray enters the root: issue 9's 1,000
            # spheres' reflection rays replayed 0.92-0.96x.)
            self._descend_all(rays, np.zeros(len(rays), np.intp), rows, t_min, t_max, visit,
                              found, stats, accept, any_hit, slot_visit=slot_visit)
            return
        # (A copy: the slab test works in place on boxes it is given for one ray.)
        near, hit = self._slabs(self.root_box[:, None, None].copy(), rays, *rows, t_min, t_max)
        if stats is not None:
            stats.node_tests += len(rays)
        keep = hit[:, 0]
        # Items: (ray, child reference, entry distance); a reference is a node or a leaf.
        rays, refs, near = rays[keep], np.zeros(int(keep.sum()), np.intp), near[keep, 0]
        for _ in range(levels[0]):
            inner = refs >= 0
            if inner.all():
                rays, refs, near = self._expand(rays, refs, *rows, t_min, t_max, stats)
            else:
                r, c, e = self._expand(rays[inner], refs[inner], *rows, t_min, t_max, stats)
                rays, refs, near = (np.concatenate([a[~inner], b])
                                    for a, b in ((rays, r), (refs, c), (near, e)))
        self._rounds(first, rays, refs, near, levels[1:], rows, t_min, t_max, visit, accept,
                     found, any_hit, stats, slot_visit)

    # ---- occlusion trails -----------------------------------------------------------------

    @functools.cached_property
    def _trail_tables(self):
        """(home (P,), parent (M,)) int32: the wide node whose slot holds each primitive's
        leaf (P: the largest primitive id + 1; -1 for ids not in the tree), and each wide
        node's parent (-1 for the root).  Built on the first occlusion query with sources:
        4 bytes a primitive and a node (about 4.5 MB for a million spheres)."""
        real = self.children != EMPTY
        rows = np.broadcast_to(np.arange(self.node_count)[:, None], self.children.shape)[real]
        refs = self.children[real]
        parent = np.full(self.node_count, -1, np.int32)
        inner = refs >= 0
        parent[refs[inner]] = rows[inner]
        leaf_home = np.empty(len(self.leaves), np.int32)
        leaf_home[-2 - refs[~inner]] = rows[~inner]
        held = self.leaves >= 0
        home = np.full(int(self.leaves.max(initial=-1)) + 1, -1, np.int32)
        home[self.leaves[held]] = np.broadcast_to(leaf_home[:, None], self.leaves.shape)[held]
        return home, parent

    @functools.cached_property
    def _sibling_tables(self):
        """(planes (6, M, WIDTH - 1) float32, children (M, WIDTH - 1), counts (M,)): for each
        wide node, the boxes and references of its parent's other slots, in slot order (the
        root's: none, NaN boxes no ray enters), which a trail's climbing step from the node
        meets.  Built on the first trail: 104 bytes a node (13 MiB for a million spheres)."""
        rows, slots = np.nonzero(self.children >= 0)      # each inner child's parent, slot
        child = self.children[rows, slots]
        others = np.sort((slots[:, None] + np.arange(1, WIDTH)) % WIDTH, axis=1)
        planes = np.full((6, self.node_count, WIDTH - 1), np.nan, np.float32)
        planes[:, child] = self.blocks[:, rows[:, None], others]
        children = np.full((self.node_count, WIDTH - 1), EMPTY, self.children.dtype)
        children[child] = self.children[rows[:, None], others]
        return planes, children, (children != EMPTY).sum(axis=1)

    def table_jobs(self, trails: bool) -> list:
        """Callables, each making tables a traversal would otherwise make on first use
        (cached on the tree, so pickled with it: ``Aggregate.build_frame_tables``): the sort
        depths and leaf fills every traversal reads, and with ``trails`` the occlusion
        trails' (``_trail_tables``, ``_sibling_tables``)."""
        jobs = [lambda: (self._nearest_levels, self._leaf_fill)]
        if trails:
            jobs += [lambda: self._trail_tables, lambda: self._sibling_tables]
        return jobs

    def _start_nodes(self, sources):
        """(n,) the wide node holding the leaf of each ray's source primitive (-1: none)."""
        home = self._trail_tables[0]
        sources = np.asarray(sources)
        known = (sources >= 0) & (sources < len(home))
        return np.where(known, home.take(np.where(known, sources, 0)), -1)

    def _trail(self, rays, starts, rows, climb_rows, t_min, t_max, visit, found, stats,
               leaf_blocks=None):
        """Any-hit traversal of rays (m,) (increasing) that leave primitives of the tree, from
        their leaves up.  Each ray's *home* (``starts`` (m,)) is the node whose slot holds its
        primitive's leaf.  The ray climbs from the home's parent: each step meets the children
        of the next node up but the child already done (``_sibling_tables``: the slab terms
        ``climb_rows`` are spread for those), up to the root, until the ray is blocked; the
        home's own children (the ray's leaf, with its primitive's neighbours,
        and the leaf's siblings) are met after HOME_AFTER steps.  The subtrees met at a step
        are descended level by level (``_descend_all``) with no front-to-back sort: the
        steps go from near the ray's origin outwards, and blockers are mostly near (the
        10^6-sphere slab of issue 9: 62 % of occlusion rays blocked; the nearest blocker of
        62 % of those lies under the ray's own node at depth 5, one of 1,024 there).  Every
        primitive is reached once (the home's and the steps' subtrees partition the tree).
        The home's and the root's own boxes are not tested, which can only add (ray,
        primitive) pairs: the rays blocked are exactly those the root-down traversal finds."""
        parent = self._trail_tables[1]
        home = starts.astype(np.intp)
        # The rays still climbing, each with the node it meets next and the child of that
        # node already done (three aligned arrays, filtered together).
        node = parent.take(home).astype(np.intp)
        keep = np.flatnonzero(node >= 0)
        live, done, node = rays.take(keep), home.take(keep), node.take(keep)
        climbed, home_met = 0, False
        while True:
            if not home_met and (climbed == HOME_AFTER or len(live) == 0):
                open_ = np.flatnonzero(~found.take(rays))
                if len(open_):
                    r_pairs, refs, _ = self._expand(rays.take(open_), home.take(open_), *rows,
                                                    t_min, t_max, stats, entries=False)
                    self._descend_all(r_pairs, refs, rows, t_min, t_max, visit, found, stats,
                                      leaf_blocks=leaf_blocks)
                home_met = True
                keep = np.flatnonzero(~found.take(live))
                live, done, node = live.take(keep), done.take(keep), node.take(keep)
            if len(live) == 0:
                return
            r_pairs, refs, _ = self._expand(live, done, *climb_rows, t_min, t_max, stats,
                                            entries=False, table=self._sibling_tables)
            self._descend_all(r_pairs, refs, rows, t_min, t_max, visit, found, stats,
                              leaf_blocks=leaf_blocks)
            done, node = node, parent.take(node).astype(np.intp)
            keep = np.flatnonzero((node >= 0) & ~found.take(live))
            live, done, node = live.take(keep), done.take(keep), node.take(keep)
            climbed += 1

    def _descend_all(self, rays, refs, rows, t_min, t_max, visit, found, stats, accept=None,
                     any_hit=True, leaf_blocks=None, slot_visit=None):
        """Descends pairs (ray, child reference) (E,), grouped by ray, level by level,
        visiting the leaves each level reaches: for any hit (a blocked ray goes no deeper),
        only their primitives whose own boxes the rays reach (``_visit_boxed_leaves``) when
        the tree has them; or (not any_hit) for nearest hits, told to ``accept`` (the hits found lower
        t_max, which prunes the levels below)."""
        while len(rays):
            leaf = refs < 0
            at = np.flatnonzero(leaf)
            if len(at):
                leaf_rays, leaves = rays.take(at), -2 - refs.take(at)
                if any_hit and self._tests_slots:
                    self._visit_boxed_leaves(leaf_rays, leaves, rows, t_min, t_max, visit,
                                             None, found, True, stats,
                                             leaf_blocks=leaf_blocks)
                else:
                    self._visit_leaves(leaf_rays, leaves, t_max, visit, accept, found,
                                       any_hit, slot_visit)
                going_on = np.logical_not(leaf, out=leaf)
                if any_hit:
                    going_on &= ~found.take(rays)
                # (One index for both arrays: cheaper than two boolean masks.)
                keep = np.flatnonzero(going_on)
                rays, refs = rays.take(keep), refs.take(keep)
                if len(rays) == 0:
                    return
            rays, refs, _ = self._expand(rays, refs, *rows, t_min, t_max, stats,
                                         entries=False)

    def _slots_reached(self, rays, leaves, rows, t_min, t_max, stats) -> np.ndarray:
        """(k,) the slots (flat indices into (m, MAX_LEAF)) of pairs (ray, leaf) (m,) whose
        primitive's own box (``leaf_boxes``) the ray's segment reaches."""
        _, hit = self._slabs(self.leaf_boxes.take(leaves, axis=1), rays, *rows, t_min, t_max)
        if stats is not None:
            stats.node_tests += int(self._leaf_fill.take(leaves).sum())
        return hit.ravel().nonzero()[0]

    @property
    def _tests_slots(self) -> bool:
        """Whether leaf visits test each slot's own box first (``_slots_reached``): the tree
        has ``leaf_boxes``, laid out as a node's slots (MAX_LEAF == WIDTH, the slab terms'
        spread)."""
        return self.leaf_boxes is not None and MAX_LEAF == WIDTH

    @functools.cached_property
    def _leaf_fill(self):
        """(L,) the primitives of each leaf."""
        return (self.leaves >= 0).sum(axis=1)

    def _rounds(self, first, rays, refs, near, levels, rows, t_min, t_max, visit, accept,
                found, any_hit, stats, slot_visit=None):
        """Visit items (ray, reference, entry distance) front to back in rounds (the first
        item of each ray, then the next one, then two, four, ...); a round descends its
        nodes to the next of ``levels`` (depths), whose nodes are visited front to back in
        rounds of their own, or, past the last level, to the leaves."""
        if len(rays) == 0:
            return
        # Each ray's items front to back (rank 0 nearest), then all items by rank, so that
        # a round (ranks done .. done + size) is one slice, grouped by ray.
        # (Sorts: one of packed (ray, entry) keys, ``front_to_back``, then a radix sort of
        # the ranks' 16-bit keys.)
        order = front_to_back(rays - first, near)
        rays, refs, near = rays.take(order), refs.take(order), near.take(order)
        starts = value_run_starts(rays)
        rank = rank_within_runs(np.diff(np.r_[starts, len(rays)]))
        order = np.argsort(rank.astype(np.uint16) if rank.max() < 1 << 16 else rank,
                           kind="stable")
        rays, refs, near = rays.take(order), refs.take(order), near.take(order)
        bounds = np.searchsorted(rank.take(order), np.arange(rank.max() + 2))
        done_rank, size = 0, 1
        while done_rank < len(bounds) - 1:
            pick = slice(bounds[done_rank], bounds[min(done_rank + size, len(bounds) - 1)])
            r, ref, entry = rays[pick], refs[pick], near[pick]
            if size > 1:
                grouped = np.argsort((r - first).astype(np.uint16), kind="stable")
                r, ref, entry = r.take(grouped), ref.take(grouped), entry.take(grouped)
            live = entry <= t_max.take(r)
            if any_hit:
                live &= ~found.take(r)
            leaf = ref < 0
            (leaf_r, leaf_ref), (r, ref, entry) = _split(live & leaf, (r, ref),
                                                         live & ~leaf, (r, ref, entry))
            leaf_rays, leaf_refs = [leaf_r], [leaf_ref]
            # Nodes at the next level, kept (with their entries) for rounds of their own;
            # past the last level no entry is needed.
            held = []
            if levels and len(r):
                deeper = self.depths.take(ref) >= levels[0]
                held_part, (r, ref) = _split(deeper, (r, ref, entry), ~deeper, (r, ref))
                held = [held_part]
            while len(r):
                r, ref, entry = self._expand(r, ref, *rows, t_min, t_max, stats,
                                             entries=bool(levels))
                leaf = ref < 0
                (leaf_r, leaf_ref), (r, ref, entry) = _split(leaf, (r, ref),
                                                             ~leaf, (r, ref, entry))
                leaf_rays.append(leaf_r)
                leaf_refs.append(leaf_ref)
                if levels and len(r):
                    deeper = self.depths.take(ref) >= levels[0]
                    held_part, (r, ref) = _split(deeper, (r, ref, entry), ~deeper, (r, ref))
                    held.append(held_part)
            reached = [i for i, part in enumerate(leaf_rays) if len(part)]
            r, ref = np.concatenate(leaf_rays), np.concatenate(leaf_refs)
            if len(reached) > 1:
                # Leaves reached at different depths: grouped by ray again (a radix sort
                # of the rays' 16-bit index within the chunk).
                grouped = np.argsort((r - first).astype(np.uint16), kind="stable")
                r, ref = r[grouped], ref[grouped]
            if len(r):
                if self._tests_slots:
                    self._visit_boxed_leaves(r, -2 - ref, rows, t_min, t_max, visit, accept,
                                             found, any_hit, stats, slot_visit)
                else:
                    self._visit_leaves(r, -2 - ref, t_max, visit, accept, found, any_hit)
            if held and sum(len(part[0]) for part in held):
                self._rounds(first, *(np.concatenate(parts) for parts in zip(*held)),
                             levels[1:], rows, t_min, t_max, visit, accept, found, any_hit,
                             stats, slot_visit)
            done_rank += size
            size *= 2

    def _visit_boxed_leaves(self, r, leaf, rows, t_min, t_max, visit, accept, found, any_hit,
                            stats, slot_visit=None, leaf_blocks=None):
        """``_visit_leaves`` of pairs (ray, leaf) (m,), grouped by ray, for only the
        primitives whose own boxes (``leaf_boxes``) the rays' segments reach, up to their
        nearest hits so far: a leaf's slots cost a box test each, a fraction of a primitive
        test (a 10^6-sphere set at 960x540: 69 sphere tests a camera ray, most of them
        against spheres of a leaf whose box the ray crosses but whose own boxes it misses).
        The boxes hold their primitives, so the hits (and ties) are the same.  The pairs go
        by slot to ``slot_visit`` (nearest hits) or ``leaf_blocks`` (any hit), where
        ``traverse`` was given one; else to ``visit`` by primitive."""
        pair_slot = self._slots_reached(r, leaf, rows, t_min, t_max, stats)
        if len(pair_slot) == 0:
            return
        pair = pair_slot // MAX_LEAF
        rays = r.take(pair)
        if slot_visit is not None or leaf_blocks is not None:
            # (Slot pair_slot % MAX_LEAF of leaf leaf[pair], as an index of leaves.ravel().)
            slots = pair_slot + (leaf.take(pair) - pair) * MAX_LEAF
            if leaf_blocks is not None:
                found[leaf_blocks(rays, slots)] = True
                return
            kept, prims, t = slot_visit(rays, slots)
            if len(kept):
                keep_nearest(rays.take(kept), prims, t, t_max, found, accept, any_hit)
            return
        prims = self.leaves.take(leaf, axis=0).ravel().take(pair_slot)
        keep_nearest(rays, prims, visit(rays, prims), t_max, found, accept, any_hit)

    def _visit_leaves(self, r, leaf, t_max, visit, accept, found, any_hit, slot_visit=None):
        prims = self.leaves.take(leaf, axis=0).ravel()
        real = np.flatnonzero(prims >= 0)
        if slot_visit is not None:
            pair = real // MAX_LEAF
            leaf_rays = r.take(pair)
            kept, prims, t = slot_visit(leaf_rays, real + (leaf.take(pair) - pair) * MAX_LEAF)
            if len(kept):
                keep_nearest(leaf_rays.take(kept), prims, t, t_max, found, accept, any_hit)
            return
        leaf_rays, prims = r.take(real // MAX_LEAF), prims.take(real)
        # (A primitive is in one leaf, visited once per ray and round: unique per ray.)
        keep_nearest(leaf_rays, prims, visit(leaf_rays, prims), t_max, found, accept, any_hit)

    @staticmethod
    def _slabs(planes, rays, origins, inverse, t_min, t_max):
        """(entry distance (m, k), hit (m, k)) of rays (m,) against boxes given as planes
        (6, m, k) (low xyz, high xyz; k = WIDTH), or against one box (6, 1, 1), for
        segments from t_min (scalar or (n,)) to t_max (n,) (None: every ray unbounded).

        origins, inverse: the rays' terms (``_ray_terms``: (3, n, WIDTH), origins possibly
        (3, 1)).  Every operation runs over whole (3, m * k) planes, element for element: a
        ray's terms broadcast over a node's WIDTH slots would run NumPy's inner loop over
        WIDTH elements at a time, several times slower.  A NaN box (an empty slot) is never
        hit.  (Gathers are ``take``, called as methods: several times faster than fancy
        indexing on these layouts, and without ``np.take``'s Python-level dispatch.)"""
        m, k = len(rays), planes.shape[2]
        dtype = inverse.dtype

        def per_pair(terms):
            # (3, m * k); terms[..., :k] is terms itself (a contiguous array) when k = WIDTH.
            return terms[..., :k].take(rays, axis=1).reshape(3, m * k)

        t = planes.reshape(2, 3, -1)
        o = origins if origins.shape[1] == 1 else per_pair(origins)
        if t.shape[2] == m * k:
            if t.dtype != dtype:
                t = t.astype(dtype)
            t -= o                # a gathered copy: worked on in place
        else:
            t = t.astype(dtype) - o
        # (0 * inf is NaN: ``traverse`` runs every slab test with invalid values ignored.)
        if t.shape[2] == m * k:
            t *= per_pair(inverse)
        else:       # one box against rays sharing their origin
            t = t * per_pair(inverse)
        # fmin / fmax: a 0 * inf (a ray in a box's plane) is NaN and is ignored.
        # (A reduce over the axes: one call, and no temporary, for the three.)
        near = np.fmax.reduce(np.fmin(t[0], t[1]), axis=0)
        far = np.fmin.reduce(np.fmax(t[0], t[1]), axis=0)
        # maximum / minimum propagate an empty slot's NaN, which then fails near <= far.
        # (Rounding the bounds to the slabs' precision first gives the same results:
        # rounding is monotonic and leaves the slabs' own values as they are.)
        if getattr(t_min, "ndim", 0):
            np.maximum(near, _spread(t_min.take(rays), dtype, k).ravel(), out=near)
        else:
            np.maximum(near, t_min, out=near)
        if t_max is not None:
            np.minimum(far, _spread(t_max.take(rays), dtype, k).ravel(), out=far)
        return near.reshape(m, k), (near <= far).reshape(m, k)

    def _expand(self, rays, nodes, origins, inverse, t_min, t_max, stats, entries=True,
                table=None):
        """The children of pairs (ray, node) (m,) that the rays' segments reach: (rays,
        child references, entry distances (None unless ``entries``)), still grouped by ray.
        table: (planes, children, counts) of k slots a node to meet instead of the node's
        children (``_sibling_tables``; origins and inverse spread for k)."""
        blocks, children, counts = (self.blocks, self.children, self.child_counts) \
            if table is None else table
        near, hit = self._slabs(blocks.take(nodes, axis=1), rays, origins, inverse,
                                t_min, t_max)
        if stats is not None:
            stats.node_tests += int(counts.take(nodes).sum())
        pair_slot = hit.ravel().nonzero()[0]
        # (The pairs' rows of children, then the slots hit: a 32-byte row copy per pair is
        # faster than one index per slot.)
        return (rays.take(pair_slot // blocks.shape[2]),
                children.take(nodes, axis=0).ravel().take(pair_slot),
                near.ravel().take(pair_slot) if entries else None)
