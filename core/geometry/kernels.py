"""The pair kernels of one batch: what a tree's leaves and a cell of direction bins hand
their (ray, primitive) pairs to, under the visit/accept contract (``BVH.traverse``,
``OriginBins.traverse``): ``visit`` returns each pair's hit distance (inf: none), ``accept``
learns which pair is each improved ray's nearest hit, and the kernels keep each ray's
nearest hit so far (distance, primitive, barycentrics).  The shapes answer the pairs
(``Spheres``, ``Triangles``), under the hit rules (``rules``)."""

from __future__ import annotations

import numpy as np

from ..rays import RayBatch
from .pairs import per_ray, size_of


class _Pairs:
    """What the nearest-hit and occlusion kernels share: the shapes, the rules, which kinds
    of primitive the accelerator holds (``kinds``: (spheres, triangles) bools), and the
    stats the pairs are counted in."""

    def __init__(self, rays: RayBatch, spheres, triangles, rules, kinds, stats):
        self.rays = rays
        self.spheres = spheres
        self.triangles = triangles
        self.rules = rules
        self.kinds = kinds
        self.stats = stats
        self.exclude = rays.exclude
        self.shear = triangles.pair_shear(rays) if triangles.count else None

    def _by_kind(self, prims):
        """(sphere pairs, triangle pairs): indices into a visit's pairs' primitives prims
        (E,) by kind, each counted in stats; slices (views, no gathers) when the accelerator
        holds one kind only."""
        holds_spheres, holds_triangles = self.kinds
        if not holds_triangles:
            spheres, tris = slice(0, len(prims)), slice(0, 0)
        elif not holds_spheres:
            spheres, tris = slice(0, 0), slice(0, len(prims))
        else:
            is_sphere = prims < self.spheres.count
            spheres, tris = np.flatnonzero(is_sphere), np.flatnonzero(~is_sphere)
        if self.stats is not None:
            self.stats.sphere_tests += size_of(spheres)
            self.stats.triangle_tests += size_of(tris)
        return spheres, tris


class NearestPairs(_Pairs):
    """Nearest-hit kernels of a batch, improving best_t, best (n,) and the triangle hits'
    barycentrics ((b0, b1, b2) (n,) each, or None without triangles) in place.  ``reach``
    (n,) float64: each ray's nearest hit so far (or its t_max), which accelerators lower as
    hits are found."""

    def __init__(self, rays: RayBatch, spheres, triangles, rules, kinds, best_t, best,
                 barycentrics, stats):
        super().__init__(rays, spheres, triangles, rules, kinds, stats)
        n = len(rays)
        self.dtype = spheres.dtype
        self.best_t, self.best, self.barycentrics = best_t, best, barycentrics
        self.reach = np.minimum(best_t.astype(np.float64), per_ray(rays.t_max, n))
        self.t_min = per_ray(rays.t_min, n, self.dtype)
        self._last = {}

    def visit(self, r, prims, reached=None):
        """(E,) the hit distances of pairs (ray r, primitive) (E,), grouped by ray; reached:
        (E,) the pairs' rays' reach where a group of rays keeps its own (else ``reach``)."""
        t = np.full(len(r), np.inf, self.dtype)
        limit = (self.reach[r] if reached is None else reached).astype(self.dtype)
        spheres, tris = self._by_kind(prims)
        if size_of(spheres):
            pr = r[spheres]
            t[spheres] = self.spheres.pairs_nearest(self.rays, pr, prims[spheres],
                                                    self.t_min[pr], limit[spheres], self.rules)
        bary = None
        if size_of(tris):
            pr = r[tris]
            tt, b0, b1, b2, valid = self.triangles.pairs_hit(
                self.shear, pr, prims[tris] - self.spheres.count, self.t_min[pr], limit[tris])
            t[tris] = np.where(valid, tt, np.inf)
            bary = (tris, b0, b1, b2)
        if self.exclude is not None:
            t[prims == self.exclude[r]] = np.inf
        self._last.update(prims=prims, bary=bary, t=t)
        return t

    def slot_visit(self, r, slots, table, reached=None):
        """``visit`` of pairs (ray r, slot) (E,) of a table of spheres laid out by slot
        (``Spheres.by_slot``: x, y, z, radii, ids), less the pairs of the sphere each ray
        excludes, dropped before their roots (rays leaving a sphere's outside: about one of
        two sphere tests a reflection ray makes in a field of spheres): (kept (k,) the pairs
        tested, an index into them, their primitives (k,), their distances (k,)) (the
        ``slot_visit`` of ``BVH.traverse``; the same distances as ``visit``)."""
        prims = table[4].take(slots)
        kept = np.flatnonzero(prims != self.exclude.take(r))
        r, slots, prims = r.take(kept), slots.take(kept), prims.take(kept)
        reached = self.reach.take(r) if reached is None else reached.take(kept)
        t = self.spheres.slots_nearest(self.rays, r, slots, table, self.t_min.take(r), reached,
                                       self.rules, self.stats)
        self._last.update(prims=prims, bary=None, t=t)
        return kept, prims, t

    def accept(self, owner, pair):
        """Rays ``owner`` (k,) have a new nearest hit: pair ``pair`` (k,) of the last visit."""
        prims = self._last["prims"]
        self.best[owner] = prims[pair]
        self.best_t[owner] = self._last["t"][pair]
        if self.barycentrics is None:
            return
        # A sphere's hit clears what a triangle found before it (0, as before any hit):
        # a ray's barycentrics do not depend on the order its leaves were visited in.
        bary = self._last["bary"]
        if bary is None:
            for store in self.barycentrics:
                store[owner] = 0
            return
        tris, b0, b1, b2 = bary
        slot = np.full(len(prims), -1, np.intp)
        slot[tris] = np.arange(size_of(tris))
        chosen = slot[pair]
        won = chosen >= 0
        for store, b in zip(self.barycentrics, (b0, b1, b2)):
            store[owner[won]] = b[chosen[won]]
            store[owner[~won]] = 0

    def of(self, members, local):
        """(visit, accept, slot_visit) for a group of the batch's rays ``members`` (k,)
        numbered 0 .. k - 1 that keeps its own reach ``local`` (k,) (lowered in place):
        the kernels' rays mapped back to the batch's."""
        def visit(r, prims):
            return self.visit(members.take(r), prims, local.take(r))

        def accept(owner, pair):
            self.accept(members.take(owner), pair)

        def slot_visit(r, slots, table):
            return self.slot_visit(members.take(r), slots, table, local.take(r))

        return visit, accept, slot_visit

    def state(self):
        """What the kernels hold per ray (reach, best_t, best, barycentrics), as copies."""
        return tuple(a.copy() for a in self._arrays())

    def restore(self, state, rows):
        """Rays ``rows`` back to what ``state`` held for them."""
        for store, kept in zip(self._arrays(), state):
            store[rows] = kept.take(rows)

    def _arrays(self):
        return (self.reach, self.best_t, self.best) + (self.barycentrics or ())


class OcclusionPairs(_Pairs):
    """Occlusion kernels of a batch of segments (t_min, t_max)."""

    def __init__(self, segments: RayBatch, spheres, triangles, rules, kinds, stats):
        super().__init__(segments, spheres, triangles, rules, kinds, stats)
        n = len(segments)
        self.reach = np.array(per_ray(segments.t_max, n), np.float64)
        self.low = per_ray(segments.t_min, n, spheres.dtype)
        self.high = per_ray(segments.t_max, n, spheres.dtype)

    def visit(self, r, prims):
        """(E,) 0 where a pair (ray r, primitive) blocks its segment, else inf."""
        blocked = np.zeros(len(r), bool)
        spheres, tris = self._by_kind(prims)
        if size_of(spheres):
            pr = r[spheres]
            blocked[spheres] = self.rules.pairs_blocked(self.spheres, self.rays, pr,
                                                        prims[spheres], self.low, self.high)
        if size_of(tris):
            pr = r[tris]
            blocked[tris] = self.triangles.pairs_hit(
                self.shear, pr, prims[tris] - self.spheres.count, self.low[pr],
                self.high[pr])[4]
        if self.exclude is not None:
            blocked &= prims != self.exclude[r]
        return np.where(blocked, 0.0, np.inf)

    def slot_blocks(self, r, slots, table):
        """The rays (k,) of pairs (ray r, slot) (E,) of a table of spheres by slot
        (``Spheres.slots_blocked``) whose sphere blocks them."""
        return self.spheres.slots_blocked(self.rays, r, slots, table, self.low, self.high,
                                          self.rules, self.stats)
