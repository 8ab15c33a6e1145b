"""Per-hit data the input nodes read from ``ShadingPoints`` beyond its attributes: named
coordinates with the value Cycles has when the integrator gives none, and the transform of
each hit's object (``ShadingPoints``' docstring lists the names).

An object's transform comes as three coordinates holding the world-space images of its local
X, Y and Z axes (the columns of its world matrix) and one holding its location; points
without them (the world, or an integrator that gives none) are taken in world space, as
Cycles treats the background.
"""

from __future__ import annotations

import numpy as np

from ..vectors import cross, dot, safe_normalize

OBJECT_AXES = ("object_axis_x", "object_axis_y", "object_axis_z")
OBJECT_LOCATION = "object_location"


def provided(points, name: str) -> bool:
    """Whether the integrator gave the coordinate ``name`` (``ShadingPoints.coordinate``
    reads a missing one as zero, which is wrong where Cycles' own default is not zero)."""
    return name in getattr(points, "_sources", ())


def vector(points, name: str, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(3, n) coordinate ``name``, or (3, 1) ``default`` when the integrator gave none."""
    if provided(points, name):
        return points.coordinate(name)
    return np.asarray(default, points.dtype).reshape(3, 1)


def scalar(points, name: str, default: float = 0.0) -> np.ndarray:
    """(n,) the first component of coordinate ``name`` (a per-hit number stored as a
    coordinate), or 0-d ``default`` when the integrator gave none."""
    if provided(points, name):
        return points.coordinate(name)[0]
    return np.asarray(default, points.dtype)


class ObjectFrame:
    """The world matrix M (columns ``axes``, translation ``location``) of each hit's object
    and the conversions Cycles makes with it: points by M, directions by its 3 x 3 part,
    normals by that part's inverse transpose (normalised)."""

    def __init__(self, points):
        self.present = all(provided(points, name) for name in OBJECT_AXES)
        self.location = vector(points, OBJECT_LOCATION)
        if self.present:
            self.axes = [points.coordinate(name) for name in OBJECT_AXES]
            x, y, z = self.axes
            # Rows of M^-1 are (Y x Z, Z x X, X x Y) / det M.
            cofactors = [cross(y, z), cross(z, x), cross(x, y)]
            determinant = dot(x, cofactors[0])
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = np.where(determinant != 0, 1 / determinant, 0)
            self.inverse_rows = [row * scale for row in cofactors]

    def _by_columns(self, v):
        x, y, z = self.axes
        return x * v[0] + y * v[1] + z * v[2]

    def _by_rows(self, rows, v):
        return np.stack(np.broadcast_arrays(*(dot(row, v) for row in rows)))

    def to_world(self, v, kind: str):
        """Object space -> world space for kind 'POINT', 'VECTOR' or 'NORMAL'."""
        if not self.present:
            return v
        if kind == "NORMAL":
            # M^-T n: the inverse's rows taken as columns.
            rows = self.inverse_rows
            return safe_normalize(rows[0] * v[0] + rows[1] * v[1] + rows[2] * v[2])
        moved = self._by_columns(v)
        return moved + self.location if kind == "POINT" else moved

    def to_object(self, v, kind: str):
        """World space -> object space for kind 'POINT', 'VECTOR' or 'NORMAL'."""
        if not self.present:
            return v
        if kind == "NORMAL":
            return safe_normalize(self._by_rows(self.axes, v))       # M^T n
        if kind == "POINT":
            v = v - self.location
        return self._by_rows(self.inverse_rows, v)
