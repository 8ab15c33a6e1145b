"""Shadow rays off smooth-shaded triangles leave from the smooth surface, as in Cycles.

A coarse mesh shaded smooth (a 32-segment UV sphere, a cylinder) lights each facet by its
interpolated corner normals, but its shadow rays leave the flat facet: near the terminator a
facet tilted away from the light shadows itself (its rays run into the mesh) where the
smooth normal still faces the light, and the facets show as dark steps.  Cycles' answer
(Hanika, "Hacking the Shadow Terminator", Ray Tracing Gems II, 2021; Cycles'
``shadow_ray_smooth_surface_offset`` and ``shadow_ray_offset``, the object's Shadow
Terminator > Geometry Offset, 0.1 by default) moves the origin of those shadow rays up to a
smooth surface over the facet:

* the lift: over a triangle with corners V_i and unit corner normals N_i, at barycentrics
  (u, v, w) of V_0, V_1, V_2, the height of the parabolic patch
  h = a u (u - 1) + (a + b + c) u v + b v (v - 1), a = (N_2 - N_0).(V_0 - V_2),
  b = (N_2 - N_1).(V_1 - V_2), c = (N_1 - N_0).(V_1 - V_0), bounded below by the linear
  envelope of the corners' tangent planes (on the viewer's side of the facet; mirrored on
  the other), along the interpolated normal n = u N_0 + v N_1 + w N_2 (not normalised);
* the amount, per shadow ray towards L, with cutoff o (the geometry offset), N.L and Ng.L
  the shading and geometric normals' cosines on the viewer's side: clamp(2 - (Ng.L + N.L)
  / o, 0, 1) where N.L < o, else clamp(1 - Ng.L / o, 0, 1): only grazing rays move (10-20 %
  of them at o = 0.1, Cycles' comment says), smoothly;
* a ray that moved ignores its own triangle only where Ng.L > 0 (where the light is below
  the facet's plane, the facet is meant to shadow it).

Shadow rays towards light from behind the shading normal (light a translucent surface passes
through) keep their origins: the opaque lobes get nothing from there.  World-space corner
normals stand in for Cycles' object-space ones, which only differs under non-uniform scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vectors import dot, take

#: Blender's default Shadow Terminator > Geometry Offset (``Object.shadow_terminator_geometry_offset``).
DEFAULT_GEOMETRY_OFFSET = 0.1


def smooth_surface_lift(corners, corner_normals, barycentrics, geometric):
    """(3, m) the offset n h of m points on triangles (``TerminatorLift`` module docstring):
    corners (V_0, V_1, V_2) and corner_normals (N_0, N_1, N_2) each (3, m) (normals unit),
    barycentrics (u, v, w) of the corners (m,) each, geometric (3, m) the facets' normals on
    the viewer's side."""
    v0, v1, v2 = corners
    n0, n1, n2 = corner_normals
    u, v, w = barycentrics
    point = u * v0 + v * v1 + w * v2
    n = u * n0 + v * n1 + w * n2
    # The parabolic approximation of the smooth surface over the facet.
    a = dot(n2 - n0, v0 - v2)
    b = dot(n2 - n1, v1 - v2)
    c = dot(n1 - n0, v1 - v0)
    h = a * u * (u - 1) + (a + b + c) * u * v + b * v * (v - 1)
    # The local linear envelope: each corner's tangent plane over the facet, on the side the
    # interpolated normal shows (the viewer's side, or its mirror for flipped normals).
    outward = dot(n, geometric) > 0
    side = np.where(outward, 1, -1).astype(h.dtype)
    heights = []
    for corner, normal, others in ((v0, n0, (v1, v2)), (v1, n1, (v0, v2)),
                                   (v2, n2, (v0, v1))):
        reach = np.maximum(np.maximum(side * dot(others[0] - corner, normal),
                                      side * dot(others[1] - corner, normal)), 0)
        heights.append(np.maximum(side * dot(corner - point, normal) + reach, 0))
    envelope = np.minimum(np.minimum(heights[0], heights[1]), heights[2])
    h = np.where(outward, np.maximum(envelope, h * 0.5), np.minimum(-envelope, h * 0.5))
    return n * h


@dataclass(frozen=True)
class TerminatorLift:
    """Where the shadow rays of m shaded points leave (module docstring): lift (3, m) the
    smooth surface's offset n h (0 off smooth triangles), cutoff (m,) the geometry offset of
    each point's mesh (0: none), geometric and shading (3, m) the unit normals on the
    viewer's side."""

    lift: np.ndarray
    cutoff: np.ndarray
    geometric: np.ndarray
    shading: np.ndarray

    def take(self, index) -> "TerminatorLift":
        """The lift of points ``index`` (k,)."""
        return TerminatorLift(take(self.lift, index), self.cutoff.take(index),
                              take(self.geometric, index), take(self.shading, index))

    def flipped(self) -> "TerminatorLift":
        """The same points seen from the other side (the shading normal negated)."""
        return TerminatorLift(self.lift, self.cutoff, -self.geometric, -self.shading)

    def origins(self, points, towards, exclude):
        """For shadow rays from these points (3, m) along unit ``towards`` (3, m), ignoring
        ``exclude`` (m,): (moved (k,) the rays that leave elsewhere, their origins (3, k),
        what they ignore (k,): their own triangle only where the light is above its
        plane)."""
        n_l = dot(self.shading, towards)
        ng_l = dot(self.geometric, towards)
        cutoff = self.cutoff
        with np.errstate(divide="ignore", invalid="ignore"):
            amount = np.where(n_l < cutoff, 2 - (ng_l + n_l) / cutoff, 1 - ng_l / cutoff)
        amount = np.where((cutoff > 0) & (n_l > 0), np.clip(amount, 0, 1), 0)
        moved = np.flatnonzero(amount > 0)
        origins = take(points, moved)
        origins += take(self.lift, moved) * amount[moved].astype(points.dtype)
        ignored = np.where(ng_l[moved] > 0, exclude[moved], -1)
        return moved, origins, ignored
