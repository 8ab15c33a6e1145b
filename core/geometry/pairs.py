"""(ray, primitive) pairs and what they settle: the one reduction every accelerator's visits
end in (``keep_nearest``), and small helpers on batches of rays."""

from __future__ import annotations

import numpy as np

from ..rays import RayBatch
from ..runs import value_run_starts
from ..vectors import take


def keep_nearest(rays, prims, t, t_max, found, accept=None, any_hit=False, best=None):
    """Settles a visit's pairs (ray, primitive) (E,), grouped by ray, with hit distances t
    (E,) (inf: none): ``found`` (n,) set for each ray with
    a hit (any_hit: any t < inf; else nearer than its t_max (n,) float64, which is lowered to
    it), and ``accept(rays, pairs)`` told which pair (index into t) is each improved ray's new
    nearest hit, ties to the lower primitive id (the visit/accept contract of ``BVH.traverse``
    and ``OriginBins``).  A ray may meet a primitive twice in a visit (two fragments of a
    split triangle in the leaves visited, which give the same distance).

    best: (n,) each ray's nearest primitive so far, or None.  Given, a pair at exactly a
    found ray's t_max also improves on it where its primitive id is lower (rounds that may
    meet a ray's hit again, ``OriginBins.walk``), and best is kept up to date."""
    if any_hit:
        # (Any pair with a hit blocks its ray: no grouping needed.)
        found[rays[t < np.inf]] = True
        return
    group = value_run_starts(rays)
    nearest = np.minimum.reduceat(t, group)
    owner = rays.take(group)
    before = t_max.take(owner)
    hit = nearest < before
    if best is not None:
        hit |= (nearest == before) & found.take(owner)
        hit &= nearest < np.inf
    if not hit.any():
        return
    lengths = np.diff(group, append=len(t))
    # The pairs at an improved ray's minimum, then of those its lowest primitive id.
    at_min = np.flatnonzero((t == np.repeat(nearest, lengths)) & np.repeat(hit, lengths))
    first = value_run_starts(rays.take(at_min))
    tied = prims.take(at_min)
    if len(first) == len(at_min):
        winner, lowest = at_min, tied   # (no ray has two pairs at its minimum)
    else:
        lowest = np.minimum.reduceat(tied, first)
        winner = at_min[tied == np.repeat(lowest, np.diff(first, append=len(at_min)))]
        if len(winner) > len(first):
            # (A primitive met twice by a ray in one visit, in two leaves that hold
            # fragments of it, ``Triangles.fragments``: its first pair.)
            winner = winner.take(value_run_starts(rays.take(winner)))
    owner, nearest = owner[hit], nearest[hit]
    if best is not None:
        better = (nearest < before[hit]) | (lowest < best.take(owner))
        owner, nearest, winner = owner[better], nearest[better], winner[better]
        best[owner] = lowest[better]
    t_max[owner] = nearest
    found[owner] = True
    if accept is not None and len(owner):
        accept(owner, winner)


def per_ray(values, n, dtype=np.float64):
    """(n,) a scalar or per-ray values, as dtype (a broadcast view where it can be)."""
    return np.broadcast_to(np.asarray(values, dtype), (n,))


def size_of(index) -> int:
    """How many pairs an index array or a slice picks."""
    return index.stop - index.start if isinstance(index, slice) else len(index)


def subset(rays: RayBatch, keep) -> RayBatch:
    """The rays ``keep`` (k,) of a batch."""
    def pick(values):
        return values[keep] if np.ndim(values) else values

    origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, keep)
    return RayBatch(origins, take(rays.directions, keep), pick(rays.t_min), pick(rays.t_max),
                    rays.shared,
                    None if rays.exclude is None else rays.exclude[keep],
                    None if rays.source is None else rays.source[keep], rays.arrived_from)
