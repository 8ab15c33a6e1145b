"""The tree's build: a bounding volume hierarchy built in whole-array NumPy, and its layout.

Build (``build_wide``): a binned surface-area-heuristic (SAH) tree (Wald 2007; pbrt 4's
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

Layout (``WideTree``): ``blocks`` (6, M, WIDTH) each wide node's child boxes as planes (low
xyz, high xyz; a plane of a node's children is contiguous), padded with NaN boxes no ray
enters; ``children`` (M, WIDTH) each slot's child: a wide node (>= 0), a leaf ``-2 - leaf``
or EMPTY; ``leaves`` (L, MAX_LEAF) each leaf's primitive ids, padded with -1;
``leaf_boxes`` (6, L, MAX_LEAF) each leaf slot's primitive's own box, padded as the nodes'
boxes (NaN in a padding slot).  Node 0 is the root, whose own box is ``root_box``.

Boxes are padded, so culling stays conservative for rays in either precision; slab tests
run in float32 for rays that start near the origin (``ORIGIN_REACH``), else in float64.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..runs import rank_within_runs, run_starts
from .cells import morton_cells, morton_codes
from .policy import DEFAULT_POLICY, GeometryPolicy
from .threads import run_on, thread_pool

#: Most primitives in a leaf, and children per inner node.
MAX_LEAF = 4
WIDTH = 4
#: Primitives per Morton cluster of a large tree (``GeometryPolicy.cluster_from``).
CLUSTER_SIZE = 4
#: Nodes of at most this many clusters split at their Morton median, not by SAH.
CLUSTER_MEDIAN_UP_TO = 16
#: A build on a thread pool (``GeometryPolicy.parallel_from``) cuts the binary SAH build's
#: top into parts of at most 1 / threads of the boxes (plus PARALLEL_SLACK; at most
#: PARALLEL_SPLITS cuts), each built on its own thread and joined (``build_binary_sah``);
#: NumPy releases the GIL in most of a build's array operations (not in ``ufunc.at`` nor
#: ``repeat``).
PARALLEL_SLACK = 0.15
PARALLEL_SPLITS = 8
#: Bins per axis of the SAH build, and the cost of a box test relative to a primitive test
#: (pbrt's 1/2: a wide node's box tests cost about one primitive's here too).
BINS = 16
SMALL_BINS = 4
TRAVERSAL_COST = 0.5
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
#: Boxes whose planes the build makes at a time: their float64 temporaries
#: then stay in cache (the planes of 1.3 million boxes in 42 ms instead of 103).
PLANE_CHUNK = 16384
#: A slot without a child.
EMPTY = -1


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
                     median_up_to: int = 1, pool=None, threads: int = 1,
                     parallel_from: int = DEFAULT_POLICY.parallel_from) -> BinaryTree:
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

    pool: a thread pool of ``threads`` threads, or None; with one, a build of
    ``parallel_from`` boxes or more is built in parts on it (``_parallel_sah``): the same
    tree."""
    if pool is not None and threads > 1 and low.shape[1] >= parallel_from:
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



@dataclass(frozen=True)
class WideTree:
    """A WIDTH-wide tree's arrays (module docstring): root_box (6,) low xyz, high xyz;
    blocks (6, M, WIDTH); children (M, WIDTH); leaves (L, MAX_LEAF) primitive ids or -1;
    child_counts (M,) real slots of each node; depths (M,) each node's depth (root 0);
    origin_reach: float32 slabs for rays from within this of the origin; leaf_boxes
    (6, L, MAX_LEAF) float32 planes of each leaf slot's primitive's own box, padded as the
    nodes' are (NaN: an empty slot), or None."""

    root_box: np.ndarray
    blocks: np.ndarray
    children: np.ndarray
    leaves: np.ndarray
    child_counts: np.ndarray
    depths: np.ndarray
    origin_reach: float = np.inf
    leaf_boxes: np.ndarray | None = None


def build_wide(ids: np.ndarray, low: np.ndarray, high: np.ndarray, threads: int = 1,
               policy: GeometryPolicy = DEFAULT_POLICY) -> WideTree:
    """A tree over primitives ``ids`` (P,) (P >= 1) with boxes low, high (P, 3).

    Below ``policy.cluster_from`` primitives the SAH build sees every primitive; from
    there, it sees clusters of CLUSTER_SIZE primitives consecutive in Morton order (of one
    size class: their boxes' largest side within a factor of 4), which become the leaves:
    the build then costs a CLUSTER_SIZE-th, and the clusters are as tight as Morton leaves.
    threads: how many threads the build may use (from ``policy.parallel_from`` primitives:
    the primitives' planes and the leaves' are made beside the rest, the SAH build in parts;
    the same tree for any number).  (A render builds it without transparent huge pages:
    ``allocator.small_pages``.)"""
    ids = np.asarray(ids)
    # The boxes as columns (3, P): every pass below then runs over contiguous rows.
    low, high = np.ascontiguousarray(low.T), np.ascontiguousarray(high.T)
    with thread_pool(threads if low.shape[1] >= policy.parallel_from else 1) as pool:
        return _build(ids, low, high, pool, threads, policy)


def _build(ids, low, high, pool, threads, policy) -> WideTree:
    """``build_wide`` on boxes low, high (3, P), parts of it on ``pool`` (or None)."""
    count = low.shape[1]
    # Each primitive's own box as float32 planes, for the leaves' slots (``leaf_boxes``);
    # the root's box is every primitive's.
    grow = SLAB_PADDING_32 * ORIGIN_REACH * _reach(low.min(axis=1), high.max(axis=1))
    size = np.empty(count)
    planes = run_on(pool, _box_planes, low, high, grow, size)
    if count < policy.cluster_from:
        tree = build_binary_sah(low, high, pool=pool, threads=threads,
                                parallel_from=policy.parallel_from)
        leaf = tree.left < 0
        slots = _leaf_table(tree.order, tree.start[leaf], tree.count[leaf])
        return _collapsed(tree, ids, slots, planes, pool)
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
    # Cluster boundaries: every CLUSTER_SIZE primitives within a run of one size class in
    # one Morton cell (cells of about CLUSTER_SIZE primitives: a cluster never spans a jump
    # of the curve).
    run_start = morton_cells(codes.take(order), CLUSTER_SIZE)
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
                            pool=pool, threads=threads, parallel_from=policy.parallel_from)
    # Each binary leaf holds one cluster: the one at its position in the build's order.
    chosen = tree.order[tree.start[tree.left < 0]]
    slots = _leaf_table(order, firsts[chosen], counts[chosen])
    return _collapsed(tree, ids, slots, planes, pool)


def _collapsed(tree, ids, slots, planes, pool) -> WideTree:
    """The wide tree of a binary one whose leaves hold ``slots`` (L, MAX_LEAF) (indices into
    ids; -1: padding), with their primitives' planes (``planes``: a Future of the (6, P)
    planes of every primitive), made on ``pool`` beside the collapse."""
    leaf_boxes = run_on(pool, lambda: _leaf_planes(planes.result(), slots))
    leaves = _leaf_ids(ids, slots)
    wide = collapse(tree, leaves)
    boxes = leaf_boxes.result()
    _merge_repeats(leaves, boxes)
    return dataclasses.replace(wide, leaf_boxes=boxes)


def _merge_repeats(leaves, leaf_boxes) -> None:
    """A primitive held twice in one leaf (two fragments of a split triangle,
    ``Triangles.fragments``) keeps its first slot, whose box then covers both; the other
    slot becomes padding, so that a leaf's visit meets each of its primitives once."""
    for later in range(1, MAX_LEAF):
        for first in range(later):
            rows = np.flatnonzero((leaves[:, later] == leaves[:, first])
                                  & (leaves[:, later] >= 0))
            if len(rows) == 0:
                continue
            leaf_boxes[:3, rows, first] = np.minimum(leaf_boxes[:3, rows, first],
                                                     leaf_boxes[:3, rows, later])
            leaf_boxes[3:, rows, first] = np.maximum(leaf_boxes[3:, rows, first],
                                                     leaf_boxes[3:, rows, later])
            leaves[rows, later] = -1
            leaf_boxes[:, rows, later] = np.nan


def collapse(tree: BinaryTree, leaves: np.ndarray, leaf_boxes=None) -> WideTree:
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
    return WideTree(root_box, blocks, children, leaves, real.sum(axis=1),
                    tree.depth[wide] // 2, ORIGIN_REACH * reach, leaf_boxes)
