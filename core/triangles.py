"""Watertight ray/triangle intersection (Woop, Benthin and Wald, "Watertight Ray/Triangle
Intersection", JCGT 2(1), 2013), shape-generic like ``core.intersect``.

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

The shear is kept as three rows of a per-ray 3 x 3 matrix (``Shear``): a row's dot product
with p multiplies by 1, 0 and -S, so it rounds exactly like the paper's formula.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vectors import take


@dataclass(frozen=True)
class Shear:
    """Per-ray shear rows: x, y, z (3, n) each, so that sheared p = (x.p, y.p, z.p); and the
    same shear as axes and factors for explicit (ray, triangle) pairs (``watertight_pairs``):
    axes (3, n) kx, ky, kz; factors (3, n) x[kz], y[kz], z[kz] (the rows' other entries
    are 1 at kx of x, 1 at ky of y, and 0)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    axes: np.ndarray | None = None
    factors: np.ndarray | None = None

    @classmethod
    def of(cls, directions: np.ndarray) -> "Shear":
        """The shear of each unit direction (3, n)."""
        n = directions.shape[1]
        columns = np.arange(n)
        kz = np.argmax(np.abs(directions), axis=0)
        kx = (kz + 1) % 3
        ky = (kx + 1) % 3
        flip = directions[kz, columns] < 0
        kx, ky = np.where(flip, ky, kx), np.where(flip, kx, ky)
        along = directions[kz, columns]
        x = np.zeros((3, n), directions.dtype)
        y = np.zeros((3, n), directions.dtype)
        z = np.zeros((3, n), directions.dtype)
        factors = np.stack([-(directions[kx, columns] / along),
                            -(directions[ky, columns] / along), 1 / along])
        x[kx, columns] = 1
        y[ky, columns] = 1
        x[kz, columns], y[kz, columns], z[kz, columns] = factors
        return cls(x, y, z, np.stack([kx, ky, kz]), factors)

    def take(self, index) -> "Shear":
        return Shear(take(self.x, index), take(self.y, index), take(self.z, index))


def watertight_pairs(corners, triangle, origins, shear: Shear, rays, t_min, t_max):
    """``watertight`` for E explicit (ray, triangle) pairs, with the same rounding (a shear
    row's product with p is p[kx] + x[kz] p[kz] once its 1 and 0 entries are multiplied
    out), by gathering each pair's sheared axes instead of multiplying by whole rows.

    corners (9, T): corner j's axis k of every triangle in row 3 j + k; triangle, rays (E,);
    origins (3, 1) or (3, n); shear: the rays' ``Shear``; t_min, t_max scalars or (E,).
    Returns (t, b0, b1, b2, valid) (E,) each."""
    count = corners.shape[1]
    flat = corners.ravel()
    k = take(shear.axes, rays)                                            # (3, E)
    fx, fy, fz = take(shear.factors, rays)
    if origins.shape[1] == 1:
        o = origins[:, 0].take(k)
    else:
        o = origins.ravel().take(k * origins.shape[1] + rays)
    base = k * count + triangle
    sheared = []
    for corner in range(3):
        p = flat.take(base + 3 * corner * count)
        p -= o
        sheared += [p[0] + fx * p[2], p[1] + fy * p[2], fz * p[2]]
    return _hit(*sheared, t_min, t_max)


def _apply(row, p):
    return row[0] * p[0] + row[1] * p[1] + row[2] * p[2]


def _edges(ax, ay, bx, by, cx, cy):
    return cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax


def watertight(v0, v1, v2, origins, shear: Shear, t_min, t_max):
    """(t, b0, b1, b2, valid) in the broadcast shape of the inputs.

    v0, v1, v2: (3, ...) corners; origins: (3, ...) ray origins; shear: the rays' ``Shear``
    with rows (3, ...) broadcasting likewise; t_min, t_max: scalars or broadcastable arrays.
    b0, b1, b2 are the barycentric weights of v0, v1, v2 at the hit (they sum to 1).  A hit
    needs t_min < t < t_max; both faces count (no culling); a degenerate triangle (zero
    area seen along the ray) never hits.
    """
    a, b, c = v0 - origins, v1 - origins, v2 - origins
    return _hit(_apply(shear.x, a), _apply(shear.y, a), _apply(shear.z, a),
                _apply(shear.x, b), _apply(shear.y, b), _apply(shear.z, b),
                _apply(shear.x, c), _apply(shear.y, c), _apply(shear.z, c), t_min, t_max)


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
