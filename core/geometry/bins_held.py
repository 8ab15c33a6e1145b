"""The direction bins an aggregate holds (``HeldBins``): built on first use, once per origin
(and per sun's direction), under a lock (tiles run in threads), within a bound on their
bytes, from the boxes of the tree's primitives.  Which batches they answer is ``binning``'s.
"""

from __future__ import annotations

import threading

import numpy as np

from .bins import OriginBins, ParallelBins
from .bvh_build import SLAB_PADDING_32
from .threads import PicklesWithoutLock


class HeldBins(PicklesWithoutLock):
    """The direction bins of an aggregate's tree (``tree.TreeAccelerator``) held so far:
    spheres, triangles the scene's shapes; tree_spheres (k,) the spheres the tree holds
    (ascending); policy: the ``GeometryPolicy``.  Pickled for worker processes with the
    bins built so far (the frame's, built once for every worker; bins a worker builds on
    first use are its own)."""

    def __init__(self, tree, spheres, triangles, tree_spheres, policy):
        self.tree, self.spheres, self.triangles = tree, spheres, triangles
        self.tree_spheres = tree_spheres
        self.policy = policy
        self.held = {}       # (origin bytes, mirror, depth) -> OriginBins, or None: the tree's
        self.parallel = {}   # a sun's direction (bytes) -> (ParallelBins, ids), or None
        self.bytes = 0
        self._lock = threading.Lock()   # (tiles run in threads)
        # How far from a common point mirror images' lines may pass
        # (``DirectionBins._mirror_groups``): a fraction of the boxes' typical half side, so
        # grown boxes list few more rays.
        self.mirror_slack = 0.0
        if tree.boxes is not None:
            _, low, high = tree.boxes
            half_side = float(np.median((high - low).max(axis=1))) / 2
            self.mirror_slack = policy.mirror_slack * half_side

    def bins_at(self, position, mirror: bool = False, depth: bool = False, pool=None):
        """The direction bins around ``position`` (3,) of the tree's boxes (mirror: grown by
        ``mirror_slack``, ``binning.DirectionBins._mirror_groups``), or None where they do
        not pay or the bins held are at their bound; with ``depth``, depth-ordered bins
        (``OriginBins.walk``) where id-ordered ones do not pay.  Built on first use, once
        per origin, under a lock (tiles run in threads); pool: a thread pool to build them
        on (``OriginBins.build``), or None."""
        position = np.asarray(position, np.float64)
        policy = self.policy

        def make():
            bins = None
            if self.bytes < policy.bins_max_bytes and self.tree.boxes is not None:
                ids, low, high = self.tree.boxes
                if mirror:
                    low, high = low - self.mirror_slack, high + self.mirror_slack
                bins = OriginBins.build(position, ids, low, high, pool=pool, policy=policy)
            if bins is None and depth and self.bytes < self._max_bytes():
                ids, low, high = self.boxes()
                bins = OriginBins.build(position, ids, low, high, by_depth=True,
                                        bounds=self.bounding_spheres(ids),
                                        rounding=float(np.finfo(self.spheres.dtype).eps),
                                        pool=pool, policy=policy)
            return None if bins is None else (bins, bins.nbytes)

        return self._held(self.held, (position.tobytes(), mirror, depth), make)

    def _held(self, store, key, make):
        """The bins held in ``store`` under ``key``, made on first use by ``make()``
        ((bins, bytes), or None where there are none), once, under a lock (tiles run in
        threads)."""
        held = store.get(key, False)
        if held is False:
            with self._lock:
                held = store.get(key, False)
                if held is False:
                    made = make()
                    held = store[key] = None if made is None else made[0]
                    self.bytes += 0 if made is None else made[1]
        return held

    def _max_bytes(self) -> int:
        return self.policy.bins_max_bytes + self.policy.bins_bytes_per_primitive * len(self.tree)

    def parallel_at(self, d):
        """(bins, listed): the parallel bins (``bins.ParallelBins``) of the tree's spheres
        across direction ``d`` (3,), with the sphere (global id) of each entry; or None where
        they would not pay or not fit.  Built on first use, once per direction."""

        def make():
            if self.bytes >= self._max_bytes():
                return None
            ids = self.tree.bvh.primitives()
            # The tree's own padding of its boxes, which covers the kernels' rounding (twice,
            # and the projections' own).
            pad = 2 * SLAB_PADDING_32 * self.tree.bvh.origin_reach
            arrays = self.spheres.arrays
            bins = ParallelBins.build(d, arrays.centers[ids].T, arrays.radii[ids], pad,
                                      self.policy)
            if bins is None:
                return None
            # (Each entry's sphere id: its centre is read from the scene's arrays, as fast
            # as from copies in entry order.)
            listed = ids.take(bins.entries)
            return (bins, listed), bins.nbytes + listed.nbytes

        return self._held(self.parallel, np.asarray(d, np.float64).tobytes(), make)

    def boxes(self):
        """(ids (P,), low, high (P, 3) float64) of the tree's primitives, for bins: the ones
        the tree kept (``TreeAccelerator.boxes``), or made again from the scene's arrays
        (trees of more than ``policy.bins_max_primitives`` keep none)."""
        if self.tree.boxes is not None:
            return self.tree.boxes
        lows, highs, ids = [], [], []
        if self.tree.sphere_count:
            spheres = self.tree_spheres
            c, r = self.spheres.arrays.centers[spheres], self.spheres.arrays.radii[spheres, None]
            lows.append(c - r)
            highs.append(c + r)
            ids.append(spheres)
        if self.tree.triangle_count:
            low, high = self.triangles.boxes()
            lows.append(low.T)
            highs.append(high.T)
            ids.append(np.arange(self.triangles.count) + self.spheres.count)
        return np.concatenate(ids), np.concatenate(lows), np.concatenate(highs)

    def bounding_spheres(self, ids):
        """(centres (k, 3), radii (k,)) float64 bounding spheres of primitives ``ids`` (k,)
        ascending, spheres before triangles (``boxes``' order): the spheres themselves, the
        triangles' (``Triangles.centers``, ``radii``)."""
        arrays = self.spheres.arrays
        spheres = ids[:np.searchsorted(ids, self.spheres.count)]
        triangles = ids[len(spheres):] - self.spheres.count
        centres = np.concatenate([arrays.centers[spheres],
                                  self.triangles.centers.T[triangles] if len(triangles)
                                  else np.zeros((0, 3))])
        radii = np.concatenate([arrays.radii[spheres],
                                self.triangles.radii[triangles] if len(triangles) else []])
        return centres, radii
