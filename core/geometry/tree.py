"""The tree as an accelerator: a BVH (``bvh``) over the primitives the aggregate gives it
(spheres and triangles together, global ids), and its glue to the pair kernels
(``kernels``): the rays' box terms, the kernels handed to ``BVH.traverse``, and the tree's
spheres in leaf order, which the leaves' pairs read by slot instead of scattered over the
scene's arrays."""

from __future__ import annotations

import threading

import numpy as np

from ..rays import RayBatch
from ..vectors import take
from .bvh import BVH
from .kernels import NearestPairs, OcclusionPairs
from .threads import PicklesWithoutLock


class TreeAccelerator(PicklesWithoutLock):
    """A tree over spheres ``sphere_ids`` (k,) and triangles ``triangle_ids`` (t,) (indices
    into the shapes ``spheres``, ``triangles``; triangles take global ids after every
    sphere), whose pairs count hits under ``rules``, built on up to ``threads`` threads
    under ``policy``.  ``boxes`` keeps the
    primitives' (ids, low, high (P, 3)) while there are at most
    ``policy.bins_max_primitives`` of them, for direction bins (``binning``); else None."""

    def __init__(self, spheres, triangles, sphere_ids, triangle_ids, rules, policy, threads=1):
        self.spheres, self.triangles, self.rules = spheres, triangles, rules
        self.sphere_count, self.triangle_count = len(sphere_ids), len(triangle_ids)
        # The boxes as columns (3, P), which the build works on (passed as their (P, 3) views).
        lows, highs = [], []
        if len(sphere_ids):
            every = len(sphere_ids) == spheres.count     # (then sphere_ids is 0 .. N-1)
            for part, box in zip((lows, highs), spheres.boxes(None if every else sphere_ids)):
                part.append(box)
        if len(triangle_ids):
            for part, box in zip((lows, highs), triangles.boxes(triangle_ids)):
                part.append(box)
        ids = np.concatenate([sphere_ids, triangle_ids + spheres.count])
        # (One kind only: its boxes as they are, no concatenated copy held beside them.)
        low = (lows[0] if len(lows) == 1 else np.concatenate(lows, axis=1)).T
        high = (highs[0] if len(highs) == 1 else np.concatenate(highs, axis=1)).T
        del lows, highs
        # The tree holds long thin triangles as fragments (``Triangles.fragments``); the
        # bins list each primitive's own box.
        held = ids, low, high
        if len(triangle_ids):
            k = len(sphere_ids)
            fragments, f_low, f_high = triangles.fragments(
                triangle_ids, low[k:].T, high[k:].T, policy.split_ratio, policy.split_levels,
                policy.split_budget)
            if len(fragments) > len(triangle_ids):
                held = (np.concatenate([sphere_ids, fragments + spheres.count]),
                        np.concatenate([low[:k], f_low.T]), np.concatenate([high[:k], f_high.T]))
        self.bvh = BVH.build(*held, threads, policy)
        del held
        self.boxes = (ids, low, high) if len(ids) <= policy.bins_max_primitives else None
        self.kinds = (bool(self.sphere_count), bool(self.triangle_count))
        # A tree of spheres alone: rays that exclude a sphere (the default rules' rays
        # leaving one) visit its leaves by slot, on the leaf-ordered spheres (``leaf_spheres``).
        self.spheres_by_slot = bool(self.sphere_count) and not self.triangle_count
        self._leaf_rows = None
        self._lock = threading.Lock()   # (tiles run in threads)

    def __len__(self) -> int:
        return self.sphere_count + self.triangle_count

    # ---- kernels --------------------------------------------------------------------------

    def nearest_pairs(self, rays: RayBatch, best_t, best, barycentrics, stats) -> NearestPairs:
        return NearestPairs(rays, self.spheres, self.triangles, self.rules, self.kinds, best_t,
                            best, barycentrics, stats)

    def occlusion_pairs(self, segments: RayBatch, stats) -> OcclusionPairs:
        return OcclusionPairs(segments, self.spheres, self.triangles, self.rules, self.kinds,
                              stats)

    def by_slot(self, rays: RayBatch) -> bool:
        """Whether the batch's sphere pairs can be visited by leaf slot: a tree of spheres
        alone, whose pairs take no shared per-sphere terms."""
        return self.spheres_by_slot and (rays.shared is None or rays.shared.tree_terms is None)

    def leaf_spheres(self):
        """(x, y, z, radii, ids) (L * MAX_LEAF,): the tree's spheres in leaf-slot order (leaf
        i's slots at i * MAX_LEAF ...; ``Spheres.by_slot``).  Built for the frame
        (``frame_jobs``) or on first use."""
        rows = self._leaf_rows
        if rows is None:
            with self._lock:
                rows = self._leaf_rows
                if rows is None:
                    rows = self._leaf_rows = self.spheres.by_slot(self.bvh.leaves.ravel())
        # (The ids are the tree's leaves themselves: not held, nor pickled, twice.)
        return (*rows, self.bvh.leaves.ravel())

    @property
    def holds_leaf_spheres(self) -> bool:
        """Whether the leaf-ordered spheres are built (``leaf_spheres``)."""
        return self._leaf_rows is not None

    def frame_jobs(self, leaf_rows: bool, trails: bool) -> list:
        """Callables making what a frame's traversals would make on first use (``BVH
        .table_jobs``; with ``leaf_rows``, the leaf-ordered spheres)."""
        jobs = list(self.bvh.table_jobs(trails))
        if leaf_rows and self._leaf_rows is None:
            jobs.append(lambda: setattr(self, "_leaf_rows",
                                        self.spheres.by_slot(self.bvh.leaves.ravel())))
        return jobs

    # ---- queries ----------------------------------------------------------------------------

    def nearest(self, kernel: NearestPairs, rest=None, stats=None) -> None:
        """The nearest hits of the kernel's batch (of its rays ``rest`` (k,), None: all),
        into the kernel."""
        rays = kernel.rays
        table = self.leaf_spheres() if kernel.exclude is not None and self.by_slot(rays) \
            else None
        box_t_min = _box_start(rays.t_min)
        if rest is None:
            slot_visit = None if table is None else (
                lambda r, slots: kernel.slot_visit(r, slots, table))
            self.bvh.traverse(*_box_terms(rays), box_t_min, kernel.reach, kernel.visit,
                              kernel.accept, slot_visit=slot_visit, stats=stats,
                              coherent=rays.shared is not None)
            return
        if len(rest) == 0:
            return
        local = kernel.reach.take(rest)
        visit, accept, slot_visit = kernel.of(rest, local)
        self.bvh.traverse(*_box_terms(rays, rest), box_t_min, local, visit, accept,
                          slot_visit=None if table is None else (
                              lambda r, slots: slot_visit(r, slots, table)), stats=stats,
                          coherent=rays.shared is not None)

    def occluded(self, kernel: OcclusionPairs, stats=None) -> np.ndarray:
        """(n,) whether each segment of the kernel's batch is blocked.  Rays leaving a
        primitive start at its leaf (``bvh_traverse._trail``): most blockers are near; a tree
        of spheres alone is visited by leaf slot there (``OcclusionPairs.slot_blocks``) when
        its spheres take the stable roots."""
        segments = kernel.rays
        leaf_blocks = None
        if not self.spheres.textbook and self.by_slot(segments):
            table = self.leaf_spheres()

            def leaf_blocks(r, slots):
                return kernel.slot_blocks(r, slots, table)

        return self.bvh.traverse(*_box_terms(segments), max(_box_start(segments.t_min), 0.0),
                                 kernel.reach, kernel.visit, any_hit=True,
                                 sources=segments.source, leaf_blocks=leaf_blocks, stats=stats,
                                 coherent=segments.shared is not None)


def _box_terms(rays: RayBatch, keep=None):
    """The tree's box tests' terms of the batch's rays (of rays ``keep`` (k,), None: all):
    float64 origins and inverse directions (only where the tree is traversed: rays answered
    by bins need neither)."""
    directions = rays.directions if keep is None else take(rays.directions, keep)
    origins = rays.origins if keep is None or rays.origins.shape[1] == 1 \
        else take(rays.origins, keep)
    with np.errstate(divide="ignore"):
        inverse = 1 / directions.astype(np.float64)
    return origins.astype(np.float64, copy=False), inverse


def _box_start(t_min) -> float:
    """Where the tree's box tests start along a batch's rays: the least of their t_min.  A
    scalar keeps a per-pair gather out of every box test; the rays' own t_min (offsets off
    surfaces, at most a shadow segment's start) still bounds their primitive tests, so the
    hits are the same and a box is at worst entered a little early."""
    return float(np.min(t_min)) if np.size(t_min) else 0.0
