"""The hit rules: which roots of a sphere count as a hit or a blocker, and how rays leave
the surfaces they hit.  Chosen once per aggregate (``Aggregate(rules=)``) and asked by the
kernels, instead of a flag every kernel tests.

``HIT_RULES`` (Glint's own): a ray hits the nearest root beyond its t_min (from inside a
sphere, the far side); a segment is blocked by any root within it; rays leave a surface
offset by ``ray_offsets`` along the geometric normal, on the side they leave, and ignore
their own primitive where they cannot hit it again.

``ARTICLE_RULES`` (docs/article.md): a sphere counts only where both roots are positive
(a ray never hits a sphere it starts inside); a shadow segment counts only the sphere's far
root (the article tests the reversed ray, from the shaded point); rays leave with the
article's fixed 1e-5 offset along the normal and ignore nothing.
"""

from __future__ import annotations

import numpy as np

from ..rays import ARTICLE_OFFSET, RayBatch, ray_offsets


class HitRules:
    """Glint's own rules (module docstring)."""

    name = "default"
    #: Whether smooth triangles' shadow rays leave their terminator lift (``core.terminator``).
    lifts_terminator = True
    #: Whether rays leaving a surface ignore their own primitive (``RayBatch.exclude``).
    excludes = True

    def first_hit(self, t_near, t_far, valid, t_min):
        """(...) the distance of the hit each (ray, sphere) pair counts, inf where none, from
        its roots t_near <= t_far (valid where the ray crosses the sphere) and the rays'
        t_min (scalar or broadcast)."""
        return np.where(valid & (t_near > t_min), t_near,
                        np.where(valid & (t_far > t_min), t_far, np.inf))

    def blocks(self, t_near, t_far, low, high):
        """Whether a sphere with (valid) roots t_near, t_far blocks a segment (low, high)."""
        return ((t_near > low) & (t_near < high)) | ((t_far > low) & (t_far < high))

    def few_nearest(self, few, b, disc, c, t_min):
        """(t, better) (n,) of one sphere's row in ``FewSpheres.nearest``: the counted hit
        and where there is one (before the t_max and exclusion tests), from the row's
        terms (``FewSpheres._terms``)."""
        t_near, t_far = few.roots(b, disc, c)
        better = t_far > t_min
        better &= disc > 0
        # The near root if beyond t_min, else the far one (never below the near one).
        return np.where(t_near > t_min, t_near, t_far), better

    def few_blocked(self, few, b, disc, c, low, high):
        """(n,) whether one sphere's row blocks each segment (``FewSpheres.blocked``), before
        the discriminant and exclusion tests."""
        t_near, t_far = few.roots(b, disc, c)
        hit = t_near > low
        hit &= t_near < high
        far = t_far > low
        far &= t_far < high
        hit |= far
        return hit

    def pairs_blocked(self, spheres, rays, r, prims, low, high):
        """(E,) whether spheres ``prims`` block the segments ``r`` (E,) of a batch: the roots
        only of the pairs that meet (``Spheres.pairs_blocked``)."""
        return spheres.pairs_blocked(rays, r, prims, low, high, self)

    def spawn(self, sphere_count, points, normals, primitive, directions, leave_front,
              exclusions, arrived_from) -> RayBatch:
        """Rays leaving hit points (``Aggregate.spawn``): offset by ``ray_offsets`` along the
        geometric normals, on the side each leaves, ignoring ``exclusions`` (m,)."""
        everywhere = bool(leave_front.all())
        # (Multiplying by a side of 1 everywhere would change nothing: skipped.)
        if everywhere:
            origins = points + ray_offsets(points) * normals
        else:
            side = np.where(leave_front, 1, -1).astype(points.dtype)
            origins = points + ray_offsets(points) * (normals * side)
        return RayBatch(origins, directions, exclude=exclusions, source=primitive,
                        arrived_from=arrived_from)


class ArticleRules(HitRules):
    """The article's rules (module docstring)."""

    name = "article"
    lifts_terminator = False
    excludes = False

    def first_hit(self, t_near, t_far, valid, t_min):
        return np.where(valid & (t_near > 0) & (t_far > 0), t_near, np.inf)

    def blocks(self, t_near, t_far, low, high):
        return (t_far < high) & (t_far > low)

    def few_nearest(self, few, b, disc, c, t_min):
        if few.textbook:
            # t_near = (-b - sqrt(disc)) / 2: NaN where disc < 0, which no test passes (the
            # far root is never below it, so it need not be formed).
            t = np.sqrt(disc, out=few.root)
            t += b
            t *= few.dtype.type(-0.5)
            better = t > 0
            better &= disc > 0
            return t, better
        t, t_far = few.roots(b, disc, c)
        better = t > 0
        better &= t_far > 0
        better &= disc > 0
        return t, better

    def few_blocked(self, few, b, disc, c, low, high):
        if few.textbook:   # t_far = (-b + sqrt(disc)) / 2
            t = np.sqrt(disc, out=few.root)
            t -= b
            t *= few.dtype.type(0.5)
        else:
            t = few.roots(b, disc, c)[1]
        hit = t < high
        hit &= t > low
        return hit

    def pairs_blocked(self, spheres, rays, r, prims, low, high):
        t_near, t_far, valid = spheres.pair_roots(rays, r, prims)
        return valid & self.blocks(t_near, t_far, low[r], high[r])

    def spawn(self, sphere_count, points, normals, primitive, directions, leave_front,
              exclusions, arrived_from) -> RayBatch:
        """The article's fixed offset along the sphere's outward normal (for a triangle, on
        the side the ray leaves); no exclusion."""
        if not leave_front.all() and (primitive >= sphere_count).any():
            side = np.where(primitive >= sphere_count,
                            np.where(leave_front, 1, -1), 1).astype(points.dtype)
            return RayBatch(points + ARTICLE_OFFSET * (normals * side), directions,
                            source=primitive, arrived_from=arrived_from)
        origins = ARTICLE_OFFSET * normals
        origins += points
        return RayBatch(origins, directions, source=primitive, arrived_from=arrived_from)


HIT_RULES = HitRules()
ARTICLE_RULES = ArticleRules()
