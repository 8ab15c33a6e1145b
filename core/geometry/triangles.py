"""Triangles: watertight ray/triangle intersection (Woop, Benthin and Wald, "Watertight
Ray/Triangle Intersection", JCGT 2(1), 2013), shape-generic like ``spheres``' kernels, and
the scene's triangles as a shape that answers its own batch tests (``Triangles``).

Each ray gets a shear that maps it to the +z axis from the origin: with kz the axis of its
direction's largest component and kx, ky the next two (swapped when d[kz] < 0, which keeps
the winding), a point p relative to the origin maps to
``(p[kx] - Sx p[kz], p[ky] - Sy p[kz], Sz p[kz])``, Sx = d[kx] / d[kz], Sy = d[ky] / d[kz],
Sz = 1 / d[kz].  The 2-D edge functions of the sheared corners decide the hit.  Two
triangles sharing an edge evaluate it on the same sheared corners with the operands
swapped, so they get exactly opposite values: a ray through a shared edge or vertex hits
at least one of them, never none (no cracks).  An edge function that rounds to exactly
zero is recomputed in extended precision (the paper's double-precision fallback), so a
ray grazing an edge is not decided by rounding alone.

The shear is kept as each ray's axes (kx, ky, kz) and factors (-Sx, -Sy, Sz) (``Shear``),
and a sheared corner is computed as the formula reads, ``p[kx] + (-Sx) p[kz]`` and so on:
for rays that share their axes, a block of (triangle, ray) pairs at once
(``watertight_axes``; a batch is cut into at most six such groups), or for explicit pairs,
gathering each pair's axes (``watertight_pairs``).  Both round alike, so a ray's hits do not
depend on which kernel found them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import TriangleArrays
from ..vectors import take


@dataclass(frozen=True)
class Shear:
    """Each ray's shear: axes (3, n) kx, ky, kz and factors (3, n) -Sx, -Sy, Sz, so that a
    point p relative to the ray's origin shears to (p[kx] - Sx p[kz], p[ky] - Sy p[kz],
    Sz p[kz])."""

    axes: np.ndarray
    factors: np.ndarray

    @classmethod
    def of(cls, directions: np.ndarray) -> "Shear":
        """The shear of each unit direction (3, n)."""
        columns = np.arange(directions.shape[1])
        kz = np.argmax(np.abs(directions), axis=0)
        kx = (kz + 1) % 3
        ky = (kx + 1) % 3
        flip = directions[kz, columns] < 0
        kx, ky = np.where(flip, ky, kx), np.where(flip, kx, ky)
        along = directions[kz, columns]
        factors = np.stack([-(directions[kx, columns] / along),
                            -(directions[ky, columns] / along), 1 / along])
        return cls(np.stack([kx, ky, kz]), factors)

    def for_pairs(self, origins, count: int) -> "PairShear":
        """What the pair kernel reads of each ray (``watertight_pairs``), against triangles
        whose corners are rows (9, ``count``), from origins (3, 1) or (3, n)."""
        if origins.shape[1] == 1:
            along = origins[:, 0].take(self.axes)
        else:
            along = np.take_along_axis(origins, self.axes, axis=0)
        return PairShear(self.axes * count, along, self.factors)


@dataclass(frozen=True)
class PairShear:
    """Each ray's shear as the pair kernel reads it, made once for a batch: bases (3, n)
    the offsets kx T, ky T, kz T of its axes' rows among a corner's (3, T) rows, origins
    (3, n) its origin's coordinates along kx, ky, kz, factors (3, n) -Sx, -Sy, Sz."""

    bases: np.ndarray
    origins: np.ndarray
    factors: np.ndarray


def watertight_axes(v0, v1, v2, origins, axes, factors, t_min, t_max):
    """(t, b0, b1, b2, valid) (k, r) each, of k triangles against r rays that share their
    shear's axes ``axes`` (kx, ky, kz) (ints).

    v0, v1, v2: (3, k, 1) corners; origins: (3, 1, r), or (3, 1, 1) for rays sharing their
    origin; factors (3, r): the rays' ``Shear.factors``; t_min, t_max: scalars or (1, r).
    b0, b1, b2 are the barycentric weights of v0, v1, v2 at the hit (they sum to 1).  A hit
    needs t_min < t < t_max; both faces count (no culling); a degenerate triangle (zero
    area seen along the ray) never hits."""
    kx, ky, kz = axes
    fx, fy, fz = (f[None, :] for f in factors)
    sheared = []
    for v in (v0, v1, v2):
        p = v - origins
        sheared += [p[kx] + fx * p[kz], p[ky] + fy * p[kz], fz * p[kz]]
    return _hit(*sheared, t_min, t_max)


def watertight_pairs(corners, triangle, shear: PairShear, rays, t_min, t_max):
    """``watertight_axes`` for E explicit (ray, triangle) pairs, with the same rounding, by
    gathering each pair's sheared axes.

    corners (9, T): corner j's axis k of every triangle in row 3 j + k; triangle, rays (E,);
    shear: the rays' ``Shear.for_pairs`` (made once for the batch, it saves every pair the
    arithmetic of its indices); t_min, t_max scalars or (E,).  Returns (t, b0, b1, b2,
    valid) (E,) each."""
    count = corners.shape[1]
    base = take(shear.bases, rays)                                        # (3, E)
    base += triangle
    o = take(shear.origins, rays)
    fx, fy, fz = take(shear.factors, rays)
    sheared = []
    for corner in range(3):
        p = corners[3 * corner:3 * corner + 3].ravel().take(base)
        p -= o
        sheared += [p[0] + fx * p[2], p[1] + fy * p[2], fz * p[2]]
    return _hit(*sheared, t_min, t_max)


def _edges(ax, ay, bx, by, cx, cy):
    return cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax


def _hit(ax, ay, az, bx, by, bz, cx, cy, cz, t_min, t_max):
    """(t, b0, b1, b2, valid) from the sheared corners a, b, c (relative to the origin)."""
    u, v, w = _edges(ax, ay, bx, by, cx, cy)
    zero = (u == 0) | (v == 0) | (w == 0)
    if zero.any():
        wide = [np.broadcast_to(q, zero.shape)[zero].astype(np.longdouble)
                for q in (ax, ay, bx, by, cx, cy)]
        u, v, w = (np.array(e, copy=True) for e in np.broadcast_arrays(u, v, w))
        for edge, exact in zip((u, v, w), _edges(*wide)):
            edge[zero] = exact.astype(edge.dtype)
    inside = ~(((u < 0) | (v < 0) | (w < 0)) & ((u > 0) | (v > 0) | (w > 0)))
    det = u + v + w
    depth = u * az + v * bz + w * cz
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1 / det
        t = depth * inverse
        valid = inside & (det != 0) & (t > t_min) & (t < t_max)
        return t, u * inverse, v * inverse, w * inverse, valid


class Triangles:
    """The scene's triangles as a shape: their arrays (``core.arrays.TriangleArrays``,
    float64), their corners as rows (9, T) in the render precision ``dtype`` (corner j's
    axis k in row 3 j + k; ``v`` their (3, T) views), geometric and corner normals in that
    precision, bounding spheres (for the flat culling's cones), and the smooth triangles'
    terminator offsets where the hit rules lift them (None otherwise)."""

    def __init__(self, arrays: TriangleArrays, dtype, lifts_terminator: bool):
        self.arrays = arrays
        self.dtype = np.dtype(dtype)
        self.count = len(arrays)
        self.material = arrays.material
        self.corners = self.v = self.normals = self.corner_normals = self.terminator = None
        if self.count == 0:
            return
        t = arrays
        cast = lambda a: np.ascontiguousarray(a, self.dtype)  # noqa: E731
        self.corners = cast(np.concatenate([t.v0, t.v1, t.v2]))
        self.v = (self.corners[0:3], self.corners[3:6], self.corners[6:9])
        self.normals = cast(t.normals)
        self.corner_normals = None if t.corner_normals is None else cast(t.corner_normals)
        # Geometry offsets of the smooth triangles' shadow rays (None: no such triangle).
        self.terminator = (None if t.terminator_offset is None or not lifts_terminator
                           else cast(t.terminator_offset))
        centre = (t.v0 + t.v1 + t.v2) / 3
        reach = np.sqrt(np.maximum.reduce([((v - centre) ** 2).sum(axis=0)
                                           for v in (t.v0, t.v1, t.v2)]))
        self.centers = centre
        self.radii = reach * (1 + 1e-9) + 1e-12 * (1 + np.abs(centre).max(axis=0))

    def boxes(self, ids=None):
        """(low, high) (3, k) float64 bounding boxes of triangles ``ids`` (k,) (None: all)."""
        t = self.arrays
        v0, v1, v2 = (t.v0, t.v1, t.v2) if ids is None else (take(v, ids) for v in (
            t.v0, t.v1, t.v2))
        return np.minimum(np.minimum(v0, v1), v2), np.maximum(np.maximum(v0, v1), v2)

    def pair_shear(self, rays):
        """The batch's ``PairShear`` (``watertight_pairs``)."""
        return Shear.of(rays.directions).for_pairs(rays.origins.astype(self.dtype, copy=False),
                                                   self.count)

    def pairs_hit(self, shear, r, triangle, t_min, t_max):
        """(t, b0, b1, b2, valid) (E,) of pairs (ray r, triangle) of a batch (local triangle
        indices), the rays' ``pair_shear`` given (``watertight_pairs``)."""
        return watertight_pairs(self.corners, triangle, shear, r, t_min, t_max)

    def saved_tests(self, up_to: int) -> float:
        """The triangle tests (of T) a tree saves a ray over testing every triangle, for at
        most ``up_to`` triangles (0 past that: their count decides): T less the tests a ray
        crossing their bounds would make in a tree, estimated as the SAH does, by the sum of
        the triangles' boxes' surface areas over their bounds'.  A floor or a wall spans the
        bounds, so every ray meets it either way; a cube's faces are small boxes."""
        if self.count == 0 or self.count > up_to:
            return 0.0

        def area(low, high):
            size = np.maximum(high - low, 0)
            return 2 * (size[0] * size[1] + size[1] * size[2] + size[2] * size[0])

        low, high = self.boxes()
        bounds = area(low.min(axis=1), high.max(axis=1))
        if not bounds > 0:
            return 0.0
        return float(self.count - area(low, high).sum() / bounds)

    def fragments(self, ids, low, high, ratio: float, levels: int, budget: float):
        """(ids (F,), low, high (3, F)): the bounding boxes low, high (3, k) of triangles
        ``ids`` (k,), a long thin one's replaced by the boxes of its fragments (Ernst and
        Greiner's early split clipping).  A fragment whose box's half area exceeds both
        ``ratio`` times its share of its triangle's area (halved at each cut) and the
        median triangle's box (a small sliver among small triangles costs no more than
        they do) is cut at the middle of its box's longest side, each half's box being the
        bounds of the triangle's part within it (``_clipped_bounds``), at most ``levels``
        cuts deep and ``budget`` x k fragments more than triangles (the worst first).  A
        triangle's fragments' boxes cover it, so a tree over them finds every hit a tree
        over the triangles finds, and far fewer rays test a sliver whose box they cross
        far from it.  (Returns the arguments themselves where nothing is cut.)"""
        share = self._areas(ids)
        size = high - low
        half = size[0] * size[1] + size[1] * size[2] + size[2] * size[0]
        typical = np.median(half) if len(half) else 0.0
        allowed = int(budget * len(ids))
        cut = np.flatnonzero((half > ratio * share) & (half > typical))
        if len(cut) == 0 or levels == 0 or allowed == 0:
            return ids, low, high
        whole = np.ones(len(ids), bool)
        whole[cut] = False
        kept_ids, kept_low, kept_high = [ids[whole]], [low[:, whole]], [high[:, whole]]
        t = self.arrays
        corners = [take(v, ids.take(cut)) for v in (t.v0, t.v1, t.v2)]
        owner = np.arange(len(cut))     # (into cut)
        low, high, share, half = low[:, cut], high[:, cut], share[cut], half[cut]
        for level in range(levels + 1):
            excess = half / np.maximum(share, 1e-300)
            split = (excess > ratio) & (half > typical) if level < levels \
                else np.zeros(len(owner), bool)
            if split.sum() > allowed:
                split = np.zeros(len(owner), bool)
                split[np.argsort(-excess)[:allowed]] = True
            kept = np.flatnonzero(~split)
            kept_ids.append(ids.take(cut.take(owner.take(kept))))
            kept_low.append(low[:, kept])
            kept_high.append(high[:, kept])
            parts = np.flatnonzero(split)
            if len(parts) == 0:
                break
            allowed -= len(parts)
            owner, low, high = owner[parts], low[:, parts], high[:, parts]
            share = share[parts] / 2
            axis = np.argmax(high - low, axis=0)
            column = np.arange(len(parts))
            middle = (low[axis, column] + high[axis, column]) / 2
            own = [take(v, owner) for v in corners]
            halves = []
            for first, last in ((low[axis, column], middle), (middle, high[axis, column])):
                part_low, part_high = _clipped_bounds(own, axis, first, last)
                np.maximum(part_low, low, out=part_low)
                np.minimum(part_high, high, out=part_high)
                part_low[axis, column] = np.maximum(part_low[axis, column], first)
                part_high[axis, column] = np.minimum(part_high[axis, column], last)
                halves.append((part_low, part_high))
            low = np.concatenate([halves[0][0], halves[1][0]], axis=1)
            high = np.concatenate([halves[0][1], halves[1][1]], axis=1)
            owner, share = np.concatenate([owner, owner]), np.concatenate([share, share])
            # (A half the triangle does not reach has no fragment.)
            real = np.flatnonzero((low <= high).all(axis=0))
            owner, low, high, share = owner[real], low[:, real], high[:, real], share[real]
            size = high - low
            half = size[0] * size[1] + size[1] * size[2] + size[2] * size[0]
        return (np.concatenate(kept_ids), np.concatenate(kept_low, axis=1),
                np.concatenate(kept_high, axis=1))

    def _areas(self, ids, chunk: int = 1 << 16):
        """(k,) the areas of triangles ``ids`` (k,), made ``chunk`` at a time (bounded
        temporaries for meshes of millions)."""
        t = self.arrays
        areas = np.empty(len(ids))
        for first in range(0, len(ids), chunk):
            part = ids[first:first + chunk]
            v0 = take(t.v0, part)
            cross = np.cross(take(t.v1, part) - v0, take(t.v2, part) - v0, axis=0)
            areas[first:first + chunk] = np.sqrt((cross * cross).sum(axis=0)) / 2
        return areas


def _clipped_bounds(corners, axis, first, last):
    """(low, high) (3, k): the bounds of the parts of k triangles (``corners``: three (3, k))
    whose coordinate ``axis`` (k,) lies within [first, last] (k,) each: of the corners
    there and of the edges' crossings of the two planes; empty (low > high) where a
    triangle does not reach its slab."""
    count = len(axis)
    column = np.arange(count)
    along = [c[axis, column] for c in corners]
    points = list(corners)
    inside = [(a >= first) & (a <= last) for a in along]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        step = along[j] - along[i]
        for plane in (first, last):
            with np.errstate(divide="ignore", invalid="ignore"):
                s = (plane - along[i]) / step
            crosses = (step != 0) & (s >= 0) & (s <= 1)
            points.append(corners[i] + np.where(crosses, s, 0) * (corners[j] - corners[i]))
            inside.append(crosses)
    low, high = np.full((3, count), np.inf), np.full((3, count), -np.inf)
    for point, within in zip(points, inside):
        np.minimum(low, np.where(within, point, np.inf), out=low)
        np.maximum(high, np.where(within, point, -np.inf), out=high)
    return low, high
