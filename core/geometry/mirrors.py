"""Mirror images: where the reflections of rays from one point (a camera's eye) off the
primitives they hit pass, so that those reflections can be answered by direction bins
around the image as rays from the eye itself are (``binning.DirectionBins._mirror_groups``).
"""

from __future__ import annotations

import numpy as np


def mirror_images(eye, source, grid, need, sphere_shape, triangle_shape):
    """(image (n,) index into points or -1, points (G, 3)): the mirror image of ``eye``
    (3,) in the tangent plane of each ray's source primitive (``source`` (n,), -1:
    none) nearest to it (a sphere's) or in its plane (a triangle's), rounded to
    multiples of ``grid``; None when no ray has a source.  sphere_shape, triangle_shape:
    the scene's shapes (``spheres.Spheres``, ``triangles.Triangles``).  Only for the spheres that
    ``need`` rays or more leave (no two spheres share an image) and every triangle
    (the triangles of a plane do); -1 for the rest."""
    sphere_count = sphere_shape.count
    counts = np.bincount(source + 1)[1:]
    ids = np.arange(len(counts))
    prims = np.flatnonzero((counts >= need) | ((ids >= sphere_count) & (counts > 0)))
    if len(prims) == 0:
        return None
    normal = np.empty((len(prims), 3))
    plane = np.empty(len(prims))        # the image is eye - 2 plane * normal
    spheres = prims < sphere_count
    # (An eye at a sphere's centre has no image: NaN, dropped below.)
    with np.errstate(invalid="ignore", divide="ignore"):
        if spheres.any():
            k = prims[spheres]
            away = eye - sphere_shape.arrays.centers[k]
            size = np.sqrt((away * away).sum(axis=1))
            normal[spheres] = away / size[:, None]
            plane[spheres] = size - sphere_shape.arrays.radii[k]
        if not spheres.all():
            k = prims[~spheres] - sphere_count
            arrays = triangle_shape.arrays
            n = arrays.normals[:, k].T
            normal[~spheres] = n
            plane[~spheres] = ((eye - arrays.v0[:, k].T) * n).sum(axis=1)
        images = np.round((eye - 2 * plane[:, None] * normal) / grid)
    points, which = np.unique(images, axis=0, return_inverse=True)
    which = which.ravel()   # (numpy 2.x keeps the axis's shape)
    # Per primitive id (and -1 for none, the last entry): its image or -1.
    image = np.full(len(counts) + 1, -1, np.intp)
    image[prims] = np.where(np.isfinite(points).all(axis=1)[which], which, -1)
    return image.take(source), points * grid
