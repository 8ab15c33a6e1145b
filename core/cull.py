"""Conservative culling: which spheres a bundle of rays can possibly hit.

A bundle's rays start within a ball (centre, radius rb) and point within a cone (unit axis,
half angle).  A ray from o, |o - centre| <= rb, that hits sphere (c, r) passes within
r + rb of c when moved to start at the centre, so it suffices to test the grown sphere
(c, r + rb) against the cone from the centre: the sphere is reachable only if the angle
between the axis and (c - centre) is at most half + asin((r + rb) / |c - centre|).  Spheres
that contain the apex always pass.  A small angular margin keeps the test conservative under
rounding.  Rays of a tile of a perspective camera share their origin (rb = 0), so the test is
exactly "can this sphere appear in this tile".
"""

from __future__ import annotations

import numpy as np

_ANGLE_MARGIN = 1e-6  # radians


def bundle_cone(origins, directions, apex=None):
    """(apex (3,), spread rb, axis (3,), half angle) bounding a bundle of rays.

    origins: (3, n) or (3, 1), or None with ``apex`` (3,) when every ray starts there;
    directions: (3, n) unit.  rb is the half diagonal of the origins' bounding box.
    """
    if apex is not None:
        spread = 0.0
    elif origins.shape[1] == 1:
        apex, spread = origins[:, 0].astype(np.float64), 0.0
    else:
        low = origins.min(axis=1).astype(np.float64)
        high = origins.max(axis=1).astype(np.float64)
        apex, spread = (low + high) / 2, float(np.linalg.norm(high - low) / 2)
    mean = directions.sum(axis=1, dtype=np.float64)
    norm = np.linalg.norm(mean)
    if norm < 1e-9 * directions.shape[1]:
        return apex, spread, np.array([0.0, 0.0, 1.0]), np.pi
    axis = mean / norm
    cos_half = float(np.clip((axis.astype(directions.dtype) @ directions).min(), -1.0, 1.0))
    # The dot products were rounded in the render precision: widen by its epsilon.
    half = np.arccos(cos_half) + 4 * np.sqrt(np.finfo(directions.dtype).eps)
    return apex, spread, axis, float(min(half, np.pi))


def reachable(centers: np.ndarray, radii: np.ndarray, apex, spread, axis, half_angle,
              max_distance: float = np.inf) -> np.ndarray:
    """Boolean mask (N,) of spheres that rays of the bundle may hit within max_distance."""
    if half_angle >= np.pi / 2 - _ANGLE_MARGIN and not np.isfinite(max_distance):
        return np.ones(len(radii), bool)
    to_center = centers - apex
    distance = np.sqrt(np.einsum("nc,nc->n", to_center, to_center))
    grown = radii + spread
    contains = distance <= grown
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_angle = np.clip((to_center @ axis) / distance, -1.0, 1.0)
        angular_radius = np.arcsin(np.clip(grown / distance, 0.0, 1.0))
    allowed = half_angle + angular_radius + _ANGLE_MARGIN
    within_cone = (allowed >= np.pi) | (np.arccos(cos_angle) <= allowed)
    near_enough = distance - grown <= max_distance + spread
    return contains | (within_cone & near_enough)
