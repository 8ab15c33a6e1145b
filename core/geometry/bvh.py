"""The tree: a bounding volume hierarchy over a scene's primitives (``BVH``), built by
``bvh_build`` and laid out as its ``WideTree``, with the tables derived from it that its
traversal (``bvh_traverse``) reads, each made once on first use (or by the frame's
``table_jobs``) and cached on the tree, so pickled with it: the depths at which traversal
sorts (ray, node) pairs front to back (``sort_levels``, ``nearest_levels``), the occlusion
trails' tables (``trail_tables``, ``sibling_tables``), the leaves' fill, and how many leaves
a line through the tree crosses (``leaf_crossings``), which picks strategies here and in the
direction bins.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields

import numpy as np

from . import bvh_traverse
from .bvh_build import EMPTY, MAX_LEAF, WIDTH, WideTree, _half_area, build_wide
from .policy import DEFAULT_POLICY, GeometryPolicy

#: The least depth (in wide levels above a typical leaf) of the subtrees ("treelets")
#: visited front to back, and the levels between the depths at which traversal sorts
#: pairs front to back again.
TREELET_DEPTH = 2
TREELET_STEP = 3
#: At most this many treelets (the front-to-back sort is over (ray, treelet) pairs).
MAX_TREELETS = 10 ** 9


@dataclass(frozen=True)
class BVH(WideTree):
    """A WIDTH-wide tree (``bvh_build.WideTree``) that rays traverse, with the policy whose
    thresholds pick its traversal (``GeometryPolicy.sorted_from``, ``deep_sort_crossings``,
    ``home_after``)."""

    policy: GeometryPolicy = DEFAULT_POLICY

    @classmethod
    def build(cls, ids: np.ndarray, low: np.ndarray, high: np.ndarray, threads: int = 1,
              policy: GeometryPolicy = DEFAULT_POLICY) -> "BVH":
        """The tree over primitives ``ids`` (P,) with boxes low, high (P, 3)
        (``bvh_build.build_wide``), built on up to ``threads`` threads."""
        wide = build_wide(ids, low, high, threads, policy)
        return cls(**{f.name: getattr(wide, f.name) for f in fields(WideTree)}, policy=policy)

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

    def traverse(self, origins, inverse, t_min, t_max, visit, accept=None, **options):
        """Visit, front to back, the primitives whose leaves each ray's segment reaches
        (``bvh_traverse.traverse``, which tells the arguments and ``options``)."""
        return bvh_traverse.traverse(self, origins, inverse, t_min, t_max, visit, accept,
                                     **options)

    @functools.cached_property
    def sorts_nearest(self) -> bool:
        """Whether nearest-hit traversal visits (ray, node) pairs front to back
        (``bvh_traverse._rounds``), or descends every pair level by level with no sort,
        visiting leaves as it reaches them (``bvh_traverse._descend_all``): trees of fewer
        than ``policy.sorted_from`` leaves, where rays meet few leaves and the sorts and
        nested rounds cost more than the box tests they save."""
        return len(self.leaves) >= self.policy.sorted_from

    def sort_levels(self, deepest: int = None) -> list:
        """The depths at which traversal sorts (ray, node) pairs front to back: the treelets'
        (``_treelet_depth``, or ``deepest``), and every TREELET_STEP levels above it down to
        depth 1."""
        deepest = self._treelet_depth() if deepest is None else deepest
        return sorted(range(deepest, 0, -TREELET_STEP)) or [0]

    @functools.cached_property
    def leaf_crossings(self) -> float:
        """The expected number of leaf boxes a random line through the root box crosses:
        the leaves' surface areas over the root's (the SAH's probabilities).  About 2.5 for
        a terrain of triangles, 5 for 10^4 of ``bench.scenes``' random spheres, 40 for
        10^5."""
        leaf = self.children < -1
        low, high = (self.blocks[:3][:, leaf].T.astype(np.float64),
                     self.blocks[3:][:, leaf].T.astype(np.float64))
        root = self.root_box.astype(np.float64)
        whole = float(_half_area(root[:3], root[3:]))
        return float(_half_area(low, high).sum()) / whole if whole > 0 else 0.0

    @functools.cached_property
    def nearest_levels(self):
        """The sort depths of nearest-hit traversal (``sort_levels``), or None where it does not
        sort (``sorts_nearest``).  In dense fields (``leaf_crossings`` of
        ``policy.deep_sort_crossings`` or more) the last sort is at the tree's widest depth
        (the most nodes: below it nodes hold a few leaves), not at the treelets of
        WIDTH ** TREELET_DEPTH leaves: a ray then stops within a few leaves of its hit
        instead of visiting every leaf its segment meets in a treelet.  Where rays meet
        fewer leaves the sorts cost more than they save."""
        if not self.sorts_nearest:
            return None
        if self.leaf_crossings < self.policy.deep_sort_crossings:
            return self.sort_levels()
        return self.sort_levels(int(np.argmax(self._depth_counts)))

    @functools.cached_property
    def _depth_counts(self) -> np.ndarray:
        """(D,) the number of wide nodes at each depth (counted once: a traversal asks for
        its sort depths on every batch)."""
        return np.bincount(self.depths)

    # ---- occlusion trails -----------------------------------------------------------------

    @functools.cached_property
    def trail_tables(self):
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
    def sibling_tables(self):
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
        trails' (``trail_tables``, ``sibling_tables``)."""
        jobs = [lambda: (self.nearest_levels, self.leaf_fill)]
        if trails:
            jobs += [lambda: self.trail_tables, lambda: self.sibling_tables]
        return jobs

    def start_nodes(self, sources):
        """(n,) the wide node holding the leaf of each ray's source primitive (-1: none)."""
        home = self.trail_tables[0]
        sources = np.asarray(sources)
        known = (sources >= 0) & (sources < len(home))
        return np.where(known, home.take(np.where(known, sources, 0)), -1)

    @property
    def tests_slots(self) -> bool:
        """Whether leaf visits test each slot's own box first
        (``bvh_traverse._slots_reached``): the tree has ``leaf_boxes``, laid out as a node's
        slots (MAX_LEAF == WIDTH, the slab terms' spread)."""
        return self.leaf_boxes is not None and MAX_LEAF == WIDTH

    @functools.cached_property
    def leaf_fill(self):
        """(L,) the primitives of each leaf."""
        return (self.leaves >= 0).sum(axis=1)
