"""Choosing the floating-point precision a scene needs.

float32 carries about 7 digits.  A hit point is computed with an absolute error of roughly
eps * (the size of the coordinates involved), so what matters is the ratio between the
scene's extent (the largest coordinate or radius any ray deals with: sphere centres plus
radii, camera, lights) and its smallest feature (the smallest radius, and the smallest
distance a shadow must resolve, which is at least that).  float32 is chosen when

    extent / smallest_radius <= FLOAT32_MAX_SCALE_RATIO

i.e. when the float32 error, eps32 * extent ~ 1.2e-7 * extent, stays below ~1e-4 of the
smallest sphere.  The article's floor sphere (radius 8999.3 next to spheres of 0.1) gives a
ratio near 1e5 and so float64, which is what keeps it free of shadow acne; a small scene of
ordinary spheres (extent 10, radii >= 0.1) runs in float32.
"""

from __future__ import annotations

import numpy as np

from .camera import eye_position
from .frame import sphere_groups
from .scene import Scene

FLOAT32_MAX_SCALE_RATIO = 500.0


def scale_ratio(scene: Scene) -> float:
    """extent / smallest radius, as described in the module docstring (inf with no spheres,
    and with triangle meshes, which have no radius to compare: they render in float64)."""
    if scene.meshes or not (scene.spheres or any(len(s) for s in scene.sphere_sets)):
        return float("inf")
    # (max over spheres of (max |c| + r) as a max over axes: adding r keeps the order, so
    # the same value, without (N, 3) temporaries: 0.04 -> 0.01 s for a million spheres)
    extent = float(np.abs(eye_position(scene.camera)).max())
    smallest = np.inf
    for centers, radii in sphere_groups(scene):
        if len(radii):
            smallest = min(smallest, float(radii.min()))
            extent = max(extent, max(float((np.abs(centers[:, axis]) + radii).max())
                                     for axis in range(3)))
    for light in scene.lights:
        extent = max(extent, max(abs(c) for c in light.position) + light.radius)
    return extent / smallest


def choose_precision(scene: Scene, requested: str) -> np.dtype:
    """The dtype to render in: the requested one, or for 'auto' the one the scene needs."""
    if requested == "float64":
        return np.dtype(np.float64)
    if requested == "float32":
        return np.dtype(np.float32)
    ratio = scale_ratio(scene)
    return np.dtype(np.float32 if ratio <= FLOAT32_MAX_SCALE_RATIO else np.float64)
