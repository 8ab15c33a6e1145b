"""The tree's traversal: rays through a bounding volume hierarchy (``bvh``: the tree and
its tables; ``bvh_build``: its build) in whole-array NumPy, behind the visit/accept contract
that the direction bins (``bins``) keep too (``traverse``).

Traversal (``traverse``) is wavefront-style over (ray, node) pairs.  From the root down
every live pair is expanded to its children at once and kept where the ray's segment meets
the child's box.  That top phase stops at depth 1 (or a few levels down in deep trees;
``BVH.sort_levels``): from there the (ray, node) pairs are sorted by entry distance and
visited front to back in rounds (the first node of each ray, then the next one, then two,
four, ...): a round descends its nodes TREELET_STEP levels, where the nodes reached are
sorted and visited front to back in rounds of their own, and so on down to the treelets,
which a round descends to their leaves, pruning by each ray's nearest hit so far; it
intersects the leaves' primitives, and a ray whose next node starts beyond its nearest hit
is finished, so a ray stops at its nearest hit; for occlusion a ray is finished at its
first blocker.  (Sorting at the upper levels too keeps a ray of a dense field from testing
every node above the treelets along its whole length.)  The *treelets* are the nodes of
about WIDTH ** TREELET_DEPTH leaves (``BVH._treelet_depth``).  Pairs are grouped by ray
before each visit, so per-ray reductions are ``reduceat``.

Occlusion rays that leave a primitive of the tree (``traverse(sources=)``) take a trail
instead (``_trail``): from the node holding their primitive's leaf up to the root, each step
meets the children of the next node up but the one already done, and descends them level by
level with no front-to-back sort, then visits the leaves it reached (only the primitives
whose own boxes the ray reaches), until the ray is blocked.  Blockers are mostly near the
ray's origin, so most rays never see the top of the tree; the steps' subtrees partition the
tree, so the same rays are blocked.

The tree (``bvh.BVH``) holds what the traversal reads besides its arrays, built once and
cached on it (pickled with it): the sort depths (``nearest_levels``, ``sort_levels``), the
trails' tables (``trail_tables``, ``sibling_tables``, ``start_nodes``), the leaves' fill.
"""

from __future__ import annotations

import numpy as np

from ..runs import rank_within_runs, value_run_starts
from .bvh_build import MAX_LEAF, WIDTH
from .pairs import keep_nearest

#: Rays traversed together: bounds the (ray, node) pairs held at once (and the rays' local
#: index fits the 16 bits of the radix sort that groups leaf pairs by ray).
RAY_CHUNK = 4096
#: Rays of a nearest-hit traversal descending a small tree unsorted (``BVH.sorts_nearest``)
#: together: nothing is sorted, and a ray holds a few pairs a level.
UNSORTED_CHUNK = 16384
#: Rays an occlusion trail (``_trail``) follows together: its pairs are never sorted,
#: and it holds one step's at a time (``bench --only cost-sphere-sets``: the dense fields).
TRAIL_CHUNK = 16384


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


def traverse(tree, origins, inverse, t_min, t_max, visit, accept=None, *, any_hit=False,
             sources=None, leaf_blocks=None, slot_visit=None, stats=None, coherent=True):
    """Visit, front to back, the primitives of ``tree`` (``bvh.BVH``) whose leaves each
    ray's segment reaches.

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
    ``coherent``: whether the rays share an origin (the eye, a light sample).  Rays
    descend the tree unsorted, level by level, where a line through it meets few leaves
    (``policy.coherent_sort_crossings``, ``incoherent_sort_crossings``: a mesh's
    surfaces; rays leaving points in all directions unless the tree is a dense field):
    sorting their pairs front to back there costs more than it saves.
    Returns (n,) bool: whether a hit (any_hit: a blocker) was found for each ray.
    """
    # (The slab tests' 0 * inf, a ray in a box's plane, is NaN and ignored there
    # (``_slabs``): one error state for the whole traversal, not one per box test
    # call, which cost about 3 % of the trails' time.)
    with np.errstate(invalid="ignore"):
        return _traverse_rays(tree, origins, inverse, t_min, t_max, visit, accept, any_hit,
                              sources, leaf_blocks, slot_visit, stats, coherent)


def _traverse_rays(tree, origins, inverse, t_min, t_max, visit, accept, any_hit, sources,
                   leaf_blocks, slot_visit, stats, coherent):
    n = inverse.shape[1]
    found = np.zeros(n, bool)
    near_origin = np.abs(origins).max(initial=0) <= tree.origin_reach
    dtype = np.float32 if near_origin else np.float64
    rows = _ray_terms(origins, inverse, dtype)
    if any_hit and sources is not None:
        starts = tree.start_nodes(sources)
        trailed = np.flatnonzero(starts >= 0)
        # (The climbing steps meet WIDTH - 1 siblings: terms spread for those.)
        climb_rows = _ray_terms(origins, inverse, dtype, WIDTH - 1) if len(trailed) else None
        for first in range(0, len(trailed), TRAIL_CHUNK):
            part = trailed[first:first + TRAIL_CHUNK]
            # (Rays with no end, a sun's or the world's, skip the slabs' bound: None.)
            bound = None if np.isposinf(t_max.take(part)).all() else t_max
            _trail(tree, part, starts.take(part), rows, climb_rows, t_min, bound, visit,
                   found, stats, leaf_blocks)
        if len(trailed) < n:
            # The rest (rays leaving no primitive of the tree) from the root.
            rest = np.flatnonzero(starts < 0)
            found[rest] = traverse(
                tree, origins if origins.shape[1] == 1 else origins[:, rest],
                inverse[:, rest], t_min if np.ndim(t_min) == 0 else t_min[rest], t_max[rest],
                lambda r, prims: visit(rest.take(r), prims), any_hit=True, stats=stats,
                coherent=coherent)
        return found
    levels = tree.sort_levels() if any_hit else tree.nearest_levels
    if tree.leaf_crossings < (tree.policy.coherent_sort_crossings if coherent
                              else tree.policy.incoherent_sort_crossings):
        levels = None
    # (Unsorted descents hold a few pairs a ray and sort nothing: larger chunks, fewer
    # calls.)
    chunk = RAY_CHUNK if levels is not None else UNSORTED_CHUNK
    for first in range(0, n, chunk):
        _traverse(tree, first, min(first + chunk, n), levels, rows, t_min, t_max,
                  visit, accept, found, any_hit, stats, slot_visit)
    return found


def _traverse(tree, first, stop, levels, rows, t_min, t_max, visit, accept, found,
              any_hit, stats, slot_visit=None):
    """Rays first .. stop - 1 from the root: front to back, sorting at ``levels``
    (``BVH.sort_levels``), or (levels None) level by level unsorted (``BVH.sorts_nearest``)."""
    rays = np.arange(first, stop)
    if levels is None:
        # (No test of the root's own box: its children's tests answer for it, which
        # saves a test a ray where nearly every ray enters the root.)
        _descend_all(tree, rays, np.zeros(len(rays), np.intp), rows, t_min, t_max, visit,
                     found, stats, accept, any_hit, slot_visit=slot_visit)
        return
    # (A copy: the slab test works in place on boxes it is given for one ray.)
    near, hit = _slabs(tree.root_box[:, None, None].copy(), rays, *rows, t_min, t_max)
    if stats is not None:
        stats.node_tests += len(rays)
    keep = hit[:, 0]
    # Items: (ray, child reference, entry distance); a reference is a node or a leaf.
    rays, refs, near = rays[keep], np.zeros(int(keep.sum()), np.intp), near[keep, 0]
    for _ in range(levels[0]):
        inner = refs >= 0
        if inner.all():
            rays, refs, near = _expand(tree, rays, refs, *rows, t_min, t_max, stats)
        else:
            r, c, e = _expand(tree, rays[inner], refs[inner], *rows, t_min, t_max, stats)
            rays, refs, near = (np.concatenate([a[~inner], b])
                                for a, b in ((rays, r), (refs, c), (near, e)))
    _rounds(tree, first, rays, refs, near, levels[1:], rows, t_min, t_max, visit, accept,
            found, any_hit, stats, slot_visit)


def _trail(tree, rays, starts, rows, climb_rows, t_min, t_max, visit, found, stats,
           leaf_blocks=None):
    """Any-hit traversal of rays (m,) (increasing) that leave primitives of the tree, from
    their leaves up.  Each ray's *home* (``starts`` (m,)) is the node whose slot holds its
    primitive's leaf.  The ray climbs from the home's parent: each step meets the children
    of the next node up but the child already done (``BVH.sibling_tables``: the slab terms
    ``climb_rows`` are spread for those), up to the root, until the ray is blocked; the
    home's own children (the ray's leaf, with its primitive's neighbours, and the leaf's
    siblings) are met after ``policy.home_after`` steps (they block few rays for their
    cost).  The subtrees met at a step are descended level by level (``_descend_all``)
    with no front-to-back sort, and their leaves visited: the steps go from near the
    ray's origin outwards, and blockers are mostly near (in a dense field most blocked
    rays' nearest blocker lies under the ray's own node a few levels up).  Every
    primitive is reached once (the home's and the steps' subtrees partition the tree).
    The home's and the root's own boxes are not tested, which can only add (ray,
    primitive) pairs: the rays blocked are exactly those the root-down traversal finds."""
    parent = tree.trail_tables[1]
    home = starts.astype(np.intp)
    # The rays still climbing, each with the node it meets next and the child of that
    # node already done (three aligned arrays, filtered together).
    node = parent.take(home).astype(np.intp)
    keep = np.flatnonzero(node >= 0)
    live, done, node = rays.take(keep), home.take(keep), node.take(keep)
    climbed, home_met = 0, False
    while True:
        if not home_met and (climbed == tree.policy.home_after or len(live) == 0):
            open_ = np.flatnonzero(~found.take(rays))
            if len(open_):
                r_pairs, refs, _ = _expand(tree, rays.take(open_), home.take(open_), *rows,
                                           t_min, t_max, stats, entries=False)
                _descend_all(tree, r_pairs, refs, rows, t_min, t_max, visit, found, stats,
                             leaf_blocks=leaf_blocks)
            home_met = True
            keep = np.flatnonzero(~found.take(live))
            live, done, node = live.take(keep), done.take(keep), node.take(keep)
        if len(live) == 0:
            return
        r_pairs, refs, _ = _expand(tree, live, done, *climb_rows, t_min, t_max, stats,
                                   entries=False, table=tree.sibling_tables)
        _descend_all(tree, r_pairs, refs, rows, t_min, t_max, visit, found, stats,
                     leaf_blocks=leaf_blocks)
        done, node = node, parent.take(node).astype(np.intp)
        keep = np.flatnonzero((node >= 0) & ~found.take(live))
        live, done, node = live.take(keep), done.take(keep), node.take(keep)
        climbed += 1


def _descend_all(tree, rays, refs, rows, t_min, t_max, visit, found, stats, accept=None,
                 any_hit=True, leaf_blocks=None, slot_visit=None):
    """Descends pairs (ray, child reference) (E,), grouped by ray, level by level,
    visiting the leaves each level reaches: for any hit, the leaves of every level in
    one visit at the end, of only their primitives whose own boxes the rays reach
    (``_visit_boxed_leaves``) when the tree has them; else level by level, for nearest
    hits told to ``accept`` (the hits found lower t_max, which prunes the levels
    below).  (One visit of a descent's leaves pays a visit's fixed costs once, not at
    every level: an occlusion trail's steps take 0.75-0.85x the time on the corpus'
    meshes and a sun over 30,000 spheres, ``bench.rays``, though a ray blocked at a
    level goes on down its other subtrees; the blocked rays are the same.)"""
    if any_hit and tree.tests_slots:
        reached_rays, reached = [], []
        while len(rays):
            leaf = refs < 0
            at = np.flatnonzero(leaf)
            if len(at):
                reached_rays.append(rays.take(at))
                reached.append(-2 - refs.take(at))
                keep = np.flatnonzero(np.logical_not(leaf, out=leaf))
                rays, refs = rays.take(keep), refs.take(keep)
                if len(rays) == 0:
                    break
            rays, refs, _ = _expand(tree, rays, refs, *rows, t_min, t_max, stats,
                                    entries=False)
        if reached:
            _visit_boxed_leaves(tree, np.concatenate(reached_rays), np.concatenate(reached),
                                rows, t_min, t_max, visit, None, found, True, stats,
                                leaf_blocks=leaf_blocks)
        return
    while len(rays):
        leaf = refs < 0
        at = np.flatnonzero(leaf)
        if len(at):
            leaf_rays, leaves = rays.take(at), -2 - refs.take(at)
            _visit_leaves(tree, leaf_rays, leaves, t_max, visit, accept, found, any_hit,
                          slot_visit)
            going_on = np.logical_not(leaf, out=leaf)
            if any_hit:
                going_on &= ~found.take(rays)
            # (One index for both arrays: cheaper than two boolean masks.)
            keep = np.flatnonzero(going_on)
            rays, refs = rays.take(keep), refs.take(keep)
            if len(rays) == 0:
                return
        rays, refs, _ = _expand(tree, rays, refs, *rows, t_min, t_max, stats,
                                entries=False)


def _slots_reached(tree, rays, leaves, rows, t_min, t_max, stats) -> np.ndarray:
    """(k,) the slots (flat indices into (m, MAX_LEAF)) of pairs (ray, leaf) (m,) whose
    primitive's own box (``leaf_boxes``) the ray's segment reaches."""
    _, hit = _slabs(tree.leaf_boxes.take(leaves, axis=1), rays, *rows, t_min, t_max)
    if stats is not None:
        stats.node_tests += int(tree.leaf_fill.take(leaves).sum())
    return hit.ravel().nonzero()[0]


def _rounds(tree, first, rays, refs, near, levels, rows, t_min, t_max, visit, accept,
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
            deeper = tree.depths.take(ref) >= levels[0]
            held_part, (r, ref) = _split(deeper, (r, ref, entry), ~deeper, (r, ref))
            held = [held_part]
        while len(r):
            r, ref, entry = _expand(tree, r, ref, *rows, t_min, t_max, stats,
                                    entries=bool(levels))
            leaf = ref < 0
            (leaf_r, leaf_ref), (r, ref, entry) = _split(leaf, (r, ref),
                                                         ~leaf, (r, ref, entry))
            leaf_rays.append(leaf_r)
            leaf_refs.append(leaf_ref)
            if levels and len(r):
                deeper = tree.depths.take(ref) >= levels[0]
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
            if tree.tests_slots:
                _visit_boxed_leaves(tree, r, -2 - ref, rows, t_min, t_max, visit, accept,
                                    found, any_hit, stats, slot_visit)
            else:
                _visit_leaves(tree, r, -2 - ref, t_max, visit, accept, found, any_hit)
        if held and sum(len(part[0]) for part in held):
            _rounds(tree, first, *(np.concatenate(parts) for parts in zip(*held)),
                    levels[1:], rows, t_min, t_max, visit, accept, found, any_hit,
                    stats, slot_visit)
        done_rank += size
        size *= 2


def _visit_boxed_leaves(tree, r, leaf, rows, t_min, t_max, visit, accept, found, any_hit,
                        stats, slot_visit=None, leaf_blocks=None):
    """``_visit_leaves`` of pairs (ray, leaf) (m,), grouped by ray, for only the
    primitives whose own boxes (``leaf_boxes``) the rays' segments reach, up to their
    nearest hits so far: a leaf's slots cost a box test each, a fraction of a primitive
    test (a 10^6-sphere set at 960x540: 69 sphere tests a camera ray, most of them
    against spheres of a leaf whose box the ray crosses but whose own boxes it misses).
    The boxes hold their primitives, so the hits (and ties) are the same.  The pairs go
    by slot to ``slot_visit`` (nearest hits) or ``leaf_blocks`` (any hit), where
    ``traverse`` was given one; else to ``visit`` by primitive."""
    pair_slot = _slots_reached(tree, r, leaf, rows, t_min, t_max, stats)
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
    prims = tree.leaves.take(leaf, axis=0).ravel().take(pair_slot)
    keep_nearest(rays, prims, visit(rays, prims), t_max, found, accept, any_hit)


def _visit_leaves(tree, r, leaf, t_max, visit, accept, found, any_hit, slot_visit=None):
    prims = tree.leaves.take(leaf, axis=0).ravel()
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


def _expand(tree, rays, nodes, origins, inverse, t_min, t_max, stats, entries=True,
            table=None):
    """The children of pairs (ray, node) (m,) that the rays' segments reach: (rays,
    child references, entry distances (None unless ``entries``)), still grouped by ray.
    table: (planes, children, counts) of k slots a node to meet instead of the node's
    children (``BVH.sibling_tables``; origins and inverse spread for k)."""
    blocks, children, counts = (tree.blocks, tree.children, tree.child_counts) \
        if table is None else table
    near, hit = _slabs(blocks.take(nodes, axis=1), rays, origins, inverse,
                       t_min, t_max)
    if stats is not None:
        stats.node_tests += int(counts.take(nodes).sum())
    pair_slot = hit.ravel().nonzero()[0]
    # (The pairs' rows of children, then the slots hit: a 32-byte row copy per pair is
    # faster than one index per slot.)
    return (rays.take(pair_slot // blocks.shape[2]),
            children.take(nodes, axis=0).ravel().take(pair_slot),
            near.ravel().take(pair_slot) if entries else None)
