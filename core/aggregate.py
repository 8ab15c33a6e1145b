"""One aggregate for every shape: the only geometry the tracer sees (pbrt's ``Aggregate``).

``Aggregate.nearest(rays)`` gives each ray's nearest hit (``core.rays.Hits``: distance,
primitive and material ids, point, geometric and shading normals, which side was hit);
``Aggregate.occluded(segments)`` whether anything blocks each segment;
``Aggregate.spawn`` makes the rays that leave hit points (offset and self-exclusion rules);
``Aggregate.shared_origin(p)`` the per-primitive terms of rays that all leave p (the camera's
eye, a light sample), which make those rays cheaper and, for spheres, more accurate.

Primitives (global ids, ``core.arrays``): analytic spheres (``core.intersect``) and
triangles (``core.triangles``, watertight).  Behind the interface, spheres are found by
cone culling over Morton clusters with coherent packets (``core.cull``) while the scene has
few of them, and through a BVH with every triangle otherwise (``core.bvh``); a scene of
four spheres builds no tree and pays nothing for triangle support.

Two choices are made once, when the aggregate is built: the hit rules (``article``: the
article's, where a sphere counts only if both roots are positive, a shadow segment counts
only the sphere's far root, and rays leave with its fixed 1e-5 offset; otherwise the nearest
root beyond t_min, any root inside a segment, scaled offsets and self-exclusion) and the
root formula for spheres (``root_formula``: 'textbook', the article's, or 'stable').
"""

from __future__ import annotations

import numpy as np

from .arrays import SphereArrays, TriangleArrays
from .cull import (DENSE_CANDIDATES, REFLECTION_CELLS, SHADOW_CELLS, candidate_roots, cones,
                   cluster_spheres, direction_cells, reachable)
from .intersect import OriginTerms, first_hit_distance
from .rays import ARTICLE_OFFSET, Hits, RayBatch, RayStats, SharedOrigin, ray_offsets
from .triangles import Shear, watertight
from .vectors import dot, take

#: The two ways to compute ray/sphere roots (``core.intersect``).
ROOT_FORMULAS = ("textbook", "stable")
#: Upper bound on (ray, triangle) pairs intersected at once; bounds the (k, n) temporaries.
TRIANGLE_BLOCK_PAIRS = 1 << 18


def _per_ray(values, n, dtype=np.float64):
    return np.broadcast_to(np.asarray(values, dtype), (n,))


class Aggregate:
    """All of a scene's geometry, in the render precision ``dtype``.

    spheres, triangles: the scene's primitives (``core.arrays``); article: the article's hit
    rules; root_formula: 'textbook' or 'stable' (``ROOT_FORMULAS``).
    """

    def __init__(self, spheres: SphereArrays, triangles: TriangleArrays, dtype, *,
                 article: bool, root_formula: str):
        if root_formula not in ROOT_FORMULAS:
            raise ValueError(f"root_formula must be one of {ROOT_FORMULAS}, got {root_formula!r}")
        self.dtype = np.dtype(dtype)
        self.article = article
        self.root_formula = root_formula
        self._textbook = root_formula == "textbook"
        self.spheres = spheres
        self.triangles = triangles
        self.sphere_count = len(spheres)
        self.triangle_count = len(triangles)
        cast = lambda a: np.ascontiguousarray(a, self.dtype)  # noqa: E731
        self._centers_t = cast(spheres.centers.T)
        self._sphere_material = spheres.material
        self._clusters = cluster_spheres(spheres.centers, spheres.radii)
        if self.triangle_count:
            t = triangles
            self._v = (cast(t.v0), cast(t.v1), cast(t.v2))
            self._tri_normals = cast(t.normals)
            self._tri_corner_normals = (None if t.corner_normals is None
                                        else cast(t.corner_normals))
            # Bounding spheres of the triangles, for the bundle's cone test.
            centre = (t.v0 + t.v1 + t.v2) / 3
            reach = np.sqrt(np.maximum.reduce([((v - centre) ** 2).sum(axis=0)
                                               for v in (t.v0, t.v1, t.v2)]))
            self._tri_centers = centre
            self._tri_radii = reach * (1 + 1e-9) + 1e-12 * (1 + np.abs(centre).max(axis=0))
            self._tri_material = t.material

    def __len__(self) -> int:
        return self.sphere_count + self.triangle_count

    # ---- shared origins -----------------------------------------------------------------

    def shared_origin(self, position) -> SharedOrigin:
        """Terms for rays that all leave ``position`` (3,)."""
        position = np.asarray(position, np.float64)
        terms = None
        if self.sphere_count:
            terms = OriginTerms.at(position, self.spheres.centers, self.spheres.radii)
        return SharedOrigin(position, terms)

    # ---- nearest hits -------------------------------------------------------------------

    def intersect(self, rays: RayBatch, stats: RayStats):
        """(t (n,), primitive (n,) or -1, barycentrics (b0, b1, b2) of triangle hits (n,)
        each, or None): the nearest hit of every ray.  ``nearest`` builds the hits from it."""
        t, primitive = self._nearest_spheres(rays, stats)
        barycentrics = None
        if self.triangle_count:
            t_tri, triangle, barycentrics = self._nearest_triangles(rays, t, stats)
            better = t_tri < t
            t = np.where(better, t_tri, t)
            primitive = np.where(better, triangle + self.sphere_count, primitive)
        return t, primitive, barycentrics

    def nearest(self, rays: RayBatch, stats: RayStats) -> Hits:
        """The nearest hit of each ray of the batch that hits something (``Hits``)."""
        t, primitive, barycentrics = self.intersect(rays, stats)
        keep = np.flatnonzero(primitive >= 0)
        origins, directions = rays.origins, rays.directions
        if len(keep) < len(primitive):
            t, hit_primitive = t[keep], primitive[keep]
            directions = take(directions, keep)
            origins = origins if origins.shape[1] == 1 else take(origins, keep)
        else:
            hit_primitive = primitive
        is_triangle = hit_primitive >= self.sphere_count
        if not is_triangle.any():
            points = origins + t * directions
            normals = points - take(self._centers_t, hit_primitive)
            normals *= 1 / np.sqrt(dot(normals, normals))
            shading = normals
            material = self._sphere_material.take(hit_primitive)
        else:
            points = np.empty((3, len(keep)), self.dtype)
            normals = np.empty_like(points)
            material = np.empty(len(keep), np.intp)
            spheres = np.flatnonzero(~is_triangle)
            if len(spheres):
                sphere = hit_primitive[spheres]
                p = (origins if origins.shape[1] == 1 else take(origins, spheres)) \
                    + t[spheres] * take(directions, spheres)
                n = p - take(self._centers_t, sphere)
                n *= 1 / np.sqrt(dot(n, n))
                points[:, spheres], normals[:, spheres] = p, n
                material[spheres] = self._sphere_material.take(sphere)
            tris = np.flatnonzero(is_triangle)
            triangle = hit_primitive[tris] - self.sphere_count
            rows = keep[tris]
            b0, b1, b2 = (b[rows].astype(self.dtype) for b in barycentrics)
            v0, v1, v2 = (take(v, triangle) for v in self._v)
            # The point from the barycentrics: its error scales with the corners, not with
            # the distance travelled (pbrt's choice).
            points[:, tris] = b0 * v0 + b1 * v1 + b2 * v2
            normals[:, tris] = take(self._tri_normals, triangle)
            material[tris] = self._tri_material.take(triangle)
            shading = normals
            if self._tri_corner_normals is not None:
                shading = normals.copy()
                corner = self._tri_corner_normals
                smooth = (b0 * take(corner[0], triangle) + b1 * take(corner[1], triangle)
                          + b2 * take(corner[2], triangle))
                shading[:, tris] = smooth * (1 / np.sqrt(dot(smooth, smooth)))
        front = dot(directions, normals) < 0
        return Hits(keep, primitive, t, hit_primitive, material, points, directions, normals,
                    shading, front)

    def _nearest_spheres(self, rays: RayBatch, stats):
        n = len(rays)
        best_t = np.full(n, np.inf, rays.directions.dtype)
        best = np.full(n, -1, np.intp)
        if not self.sphere_count:
            return best_t, best
        terms = rays.shared.sphere_terms if rays.shared is not None else None
        key = None
        if rays.source is not None and self.sphere_count > DENSE_CANDIDATES:
            # Rays leaving one primitive in one direction cell cull well together.
            key = (rays.source * (6 * REFLECTION_CELLS ** 2)
                   + direction_cells(rays.directions, REFLECTION_CELLS))
        t_min, t_max, exclude = rays.t_min, rays.t_max, rays.exclude
        for block in candidate_roots(self.spheres.centers, self.spheres.radii, self._clusters,
                                     rays.origins, rays.directions, t_max, terms,
                                     textbook=self._textbook, stats=stats, key=key):
            distances = first_hit_distance(block.t_near, block.t_far, block.valid,
                                           block.per_pair(t_min), article=self.article)
            distances[~(distances < block.per_pair(t_max))] = np.inf
            if exclude is not None:
                distances[block.spheres == block.per_pair(exclude)] = np.inf
            t, sphere = block.nearest(distances)
            # Strictly nearer only: on a tie the earlier block (earlier in scene order) keeps it.
            better = t < best_t[block.rays]
            best_t[block.rays] = np.where(better, t, best_t[block.rays])
            best[block.rays] = np.where(better, sphere, best[block.rays])
        return best_t, best

    def _triangle_candidates(self, rays: RayBatch, reach):
        """Triangles the batch's bounding cone can reach within ``reach`` (scalar)."""
        apex, spread, axis, half = cones(rays.origins[:, None, :], rays.directions[:, None, :])
        return np.flatnonzero(reachable(self._tri_centers, self._tri_radii, apex, spread,
                                        axis, half, reach))

    def _triangle_blocks(self, rays: RayBatch, t_max, stats):
        """Yields (triangles (k,), t, b0, b1, b2, valid (k, n)) over candidate triangles."""
        n = len(rays)
        reach = _per_ray(t_max, n)
        finite = reach[np.isfinite(reach)]
        limit = np.inf if len(finite) < n else (finite.max() if n else 0.0)
        candidates = self._triangle_candidates(rays, limit)
        if len(candidates) == 0 or n == 0:
            return
        shear = Shear.of(rays.directions)
        rows = (shear.x[:, None, :], shear.y[:, None, :], shear.z[:, None, :])
        origins = rays.origins.astype(self.dtype, copy=False)[:, None, :]
        t_min = np.asarray(rays.t_min, self.dtype)
        t_min = t_min[None, :] if t_min.ndim else t_min
        chunk = max(1, TRIANGLE_BLOCK_PAIRS // n)
        for first in range(0, len(candidates), chunk):
            triangles = candidates[first:first + chunk]
            if stats is not None:
                stats.triangle_tests += n * len(triangles)
            v0, v1, v2 = (v[:, triangles][:, :, None] for v in self._v)
            limit_now = np.asarray(t_max, self.dtype)
            limit_now = limit_now[None, :] if limit_now.ndim else limit_now
            t, b0, b1, b2, valid = watertight(v0, v1, v2, origins, Shear(*rows), t_min,
                                              limit_now)
            if rays.exclude is not None:
                valid &= (triangles + self.sphere_count)[:, None] != rays.exclude[None, :]
            yield triangles, t, b0, b1, b2, valid

    def _nearest_triangles(self, rays: RayBatch, t_max_now, stats):
        """(t (n,), triangle (n,) local index or -1, (b0, b1, b2) (n,) each) of the nearest
        triangle hit nearer than ``t_max_now`` (n,) and the batch's own t_max."""
        n = len(rays)
        # Hits must beat this; it shrinks as hits are found (the blocks read it each time).
        limit = np.minimum(np.asarray(t_max_now, self.dtype), _per_ray(rays.t_max, n, self.dtype))
        found_t = np.full(n, np.inf, self.dtype)
        best = np.full(n, -1, np.intp)
        bary = [np.zeros(n, self.dtype) for _ in range(3)]
        columns = np.arange(n)
        for triangles, t, b0, b1, b2, valid in self._triangle_blocks(rays, limit, stats):
            t = np.where(valid, t, np.inf)
            row = np.argmin(t, axis=0)
            nearest = t[row, columns]
            better = nearest < limit
            found_t[better] = nearest[better]
            best[better] = triangles[row[better]]
            for store, b in zip(bary, (b0, b1, b2)):
                store[better] = b[row[better], columns[better]]
            np.minimum(limit, found_t, out=limit)
        return found_t, best, tuple(bary)

    # ---- occlusion ----------------------------------------------------------------------

    def occluded(self, segments: RayBatch, stats: RayStats) -> np.ndarray:
        """(n,) whether a primitive other than ``segments.exclude`` is crossed within
        (t_min, t_max) of each segment.  Article rules: a sphere blocks when its far root
        lies there (the article tests the reversed ray, from the shaded point)."""
        n = len(segments)
        blocked = np.zeros(n, bool)
        if n == 0:
            return blocked
        stats.shadow_rays += n
        if self.sphere_count:
            blocked |= self._sphere_occlusion(segments, stats)
        if self.triangle_count and not blocked.all():
            open_ = np.flatnonzero(~blocked)
            rest = segments if len(open_) == n else _subset(segments, open_)
            for triangles, t, b0, b1, b2, valid in self._triangle_blocks(rest, rest.t_max,
                                                                         stats):
                blocked[open_] |= valid.any(axis=0)
        return blocked

    def _sphere_occlusion(self, segments: RayBatch, stats):
        n = len(segments)
        blocked = np.zeros(n, bool)
        shared = segments.shared
        terms = shared.sphere_terms if shared is not None else None
        # Segments from one light sample: packing them by direction makes narrow cones.
        key = (direction_cells(segments.directions, SHADOW_CELLS)
               if shared is not None and self.sphere_count > DENSE_CANDIDATES else None)
        t_min, t_max, exclude = segments.t_min, segments.t_max, segments.exclude
        for block in candidate_roots(self.spheres.centers, self.spheres.radii, self._clusters,
                                     segments.origins, segments.directions, t_max, terms,
                                     textbook=self._textbook, stats=stats, key=key):
            t_near, t_far, valid = block.t_near, block.t_far, block.valid
            low, high = block.per_pair(t_min), block.per_pair(t_max)
            if self.article:
                hit = valid & (t_far < high) & (t_far > low)
            else:
                hit = valid & (((t_near > low) & (t_near < high))
                               | ((t_far > low) & (t_far < high)))
                if exclude is not None:
                    hit &= block.spheres != block.per_pair(exclude)
            blocked[block.rays] |= block.any(hit)
        return blocked

    # ---- rays leaving surfaces ----------------------------------------------------------

    def exclusions(self, primitive, leave_front) -> np.ndarray:
        """(m,) the primitive that rays leaving ``primitive`` (m,) on its front side
        (``leave_front`` (m,) True) or back side cannot hit again, -1 where they can: a sphere
        cannot block rays leaving its outside (it is convex), a triangle cannot block any ray
        leaving it (it is flat)."""
        return np.where(leave_front | (primitive >= self.sphere_count), primitive, -1)

    def spawn(self, points, normals, primitive, directions, leave_front) -> RayBatch:
        """Rays leaving m hit points (3, m) along ``directions`` (3, m), on the front side of
        their geometric ``normals`` (3, m) (front / outside) where ``leave_front`` (m,).

        Default rules: the origin moves off the surface by ``ray_offsets`` (scaled to the
        point's magnitude) along the geometric normal, on the side the ray leaves, and the
        ray ignores its own primitive where it cannot hit it again (``exclusions``).
        Article rules: the article's fixed offset along the sphere's outward normal (for a
        triangle, on the side the ray leaves), no exclusion."""
        side = np.where(leave_front, 1, -1).astype(self.dtype)
        if self.article:
            if self.triangle_count:
                side = np.where(primitive >= self.sphere_count, side, 1).astype(self.dtype)
                return RayBatch(points + ARTICLE_OFFSET * (normals * side), directions,
                                source=primitive)
            return RayBatch(points + ARTICLE_OFFSET * normals, directions, source=primitive)
        origins = points + ray_offsets(points) * (normals * side)
        return RayBatch(origins, directions, exclude=self.exclusions(primitive, leave_front),
                        source=primitive)


def _subset(rays: RayBatch, keep) -> RayBatch:
    """The rays ``keep`` (k,) of a batch."""
    def pick(values):
        return values[keep] if np.ndim(values) else values

    origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, keep)
    return RayBatch(origins, take(rays.directions, keep), pick(rays.t_min), pick(rays.t_max),
                    rays.shared,
                    None if rays.exclude is None else rays.exclude[keep],
                    None if rays.source is None else rays.source[keep])
