"""One aggregate for every shape: the only geometry the tracer sees (pbrt's ``Aggregate``).

``Aggregate.nearest(rays)`` gives each ray's nearest hit (``core.rays.Hits``: distance,
primitive and material ids, point, geometric and shading normals, which side was hit);
``Aggregate.occluded(segments)`` whether anything blocks each segment;
``Aggregate.spawn`` makes the rays that leave hit points (offset and self-exclusion rules);
``Aggregate.shared_origin(p)`` the per-primitive terms of rays that all leave p (the camera's
eye, a light sample), which make those rays cheaper and, for spheres, more accurate.

Primitives (global ids, ``core.arrays``): analytic spheres (``spheres``) and triangles
(``triangles``, watertight).  Behind the interface, which the policy (``policy``) chooses
once: spheres are culled flat (``cull``) while the scene has few of them, and go into one
binned-SAH BVH with every triangle otherwise (``tree``, ``bvh``); rays sharing an origin,
and a floor's reflections of the camera's rays, find the tree's primitives through
direction bins where those are cheaper (``binning``); a scene of four spheres builds no
tree and pays nothing for triangle support.  The accelerators hand their (ray, primitive)
pairs to the pair kernels (``kernels``), and the hits are made from what they find
(``hits``).

Two choices are made once, when the aggregate is built: the hit rules (``rules``: the
article's, or Glint's own) and the root formula for spheres (``root_formula``: 'textbook',
the article's, or 'stable').
"""

from __future__ import annotations

import numpy as np

from ..arrays import SphereArrays, TriangleArrays
from ..rays import Hits, RayBatch, RayStats, SharedOrigin, timed
from .binning import DirectionBins
from .cull import FlatSpheres, FlatTriangles
from .hits import surface_interaction
from .pairs import subset
from .policy import DEFAULT_POLICY, GeometryPolicy
from .rules import HitRules
from .spheres import OriginTerms, Spheres
from .threads import run_on, thread_pool
from .tree import TreeAccelerator
from .triangles import Triangles

#: The two ways to compute ray/sphere roots (``spheres``).
ROOT_FORMULAS = ("textbook", "stable")


class Aggregate:
    """All of a scene's geometry, in the render precision ``dtype``.

    spheres, triangles: the scene's primitives (``core.arrays``); rules: the hit rules
    (``rules.HIT_RULES``, Glint's own, or ``rules.ARTICLE_RULES``); root_formula: 'textbook'
    or 'stable' (``ROOT_FORMULAS``); threads: how many threads the tree may be built on (the
    same tree for any number); rays_per_origin: how many rays a frame traces from one shared origin
    (the eye, a light sample), as far as the caller knows (``make_context``: the pixels; 0:
    unknown), which decides whether a shared origin's depth-ordered or parallel bins pay;
    policy: the thresholds that choose the strategies (``GeometryPolicy``).
    """

    def __init__(self, spheres: SphereArrays, triangles: TriangleArrays, dtype, *,
                 rules: HitRules, root_formula: str, threads: int = 1,
                 rays_per_origin: int = 0, policy: GeometryPolicy = DEFAULT_POLICY):
        if root_formula not in ROOT_FORMULAS:
            raise ValueError(f"root_formula must be one of {ROOT_FORMULAS}, got {root_formula!r}")
        self.dtype = np.dtype(dtype)
        self.rules = rules
        self.root_formula = root_formula
        self.policy = policy
        self.spheres, self.triangles = spheres, triangles
        self.sphere_count, self.triangle_count = len(spheres), len(triangles)
        self.sphere_shape = Spheres(spheres, self.dtype, root_formula == "textbook")
        self.triangle_shape = Triangles(triangles, self.dtype, self.rules.lifts_terminator)
        flat_spheres, tree_spheres = policy.split_spheres(spheres.radii)
        self.flat_spheres = FlatSpheres(self.sphere_shape,
                                        None if len(tree_spheres) == 0 else flat_spheres,
                                        self.rules, policy, beside_tree=len(tree_spheres) > 0)
        # Every triangle goes into the tree once there are enough (the SAH build puts large
        # ones, a backdrop, in their own subtrees).  A few compact ones beside flat spheres
        # get a tree of their own and stay flat as well (``_small_tree``: ``_tree_answers``).
        flat_triangles = np.arange(self.triangle_count)
        tree_triangles = np.zeros(0, np.intp)
        self._small_tree = False
        if policy.builds_tree(0, self.triangle_count):
            flat_triangles, tree_triangles = tree_triangles, flat_triangles
        elif len(tree_spheres) == 0 and policy.builds_tree(
                0, self.triangle_count,
                self.triangle_shape.saved_tests(policy.tree_min_triangles)):
            self._small_tree = True
            tree_triangles = flat_triangles
        self.flat_triangles = FlatTriangles(self.triangle_shape, flat_triangles, self.sphere_count)
        # One tree over the rest, spheres and triangles together (global ids), and its bins.
        self.tree = self.bins = None
        if len(tree_spheres) or len(tree_triangles):
            self.tree = TreeAccelerator(self.sphere_shape, self.triangle_shape, tree_spheres,
                                        tree_triangles, self.rules, policy, threads)
            self.bins = DirectionBins(self.tree, self.sphere_shape, self.triangle_shape,
                                      tree_spheres, rays_per_origin, policy)
        self._surface_keys = None   # built on first use (adaptive anti-aliasing only)

    def __len__(self) -> int:
        return self.sphere_count + self.triangle_count

    @property
    def lifts_terminator(self) -> bool:
        """Whether hits on smooth triangles are lifted off their facets (``Hits.terminator``:
        their shadow rays leave the lifted points, ``core.terminator``)."""
        return self.triangle_shape.terminator is not None

    def surface_keys(self, primitive_per_ray: np.ndarray) -> np.ndarray:
        """(n,) uint64 key of the surface each ray hit (0: none), for adaptive anti-aliasing's
        path signatures: each sphere is a surface; triangles are grouped into surfaces by
        ``arrays.TriangleArrays.surface`` (an object, or one flat facet of it), so that the
        inner edges of a smooth mesh are not taken for edges in the picture."""
        if self._surface_keys is None:
            self._surface_keys = np.concatenate([
                np.zeros(1, np.uint64), np.arange(1, self.sphere_count + 1, dtype=np.uint64),
                (self.sphere_count + 1 + self.triangles.surface).astype(np.uint64)])
        return self._surface_keys[primitive_per_ray + 1]

    # ---- shared origins -----------------------------------------------------------------

    def shared_origin(self, position) -> SharedOrigin:
        """Terms for rays that all leave ``position`` (3,): for the spheres culled flat, and
        for every sphere when the tree holds spheres and there are not too many."""
        position = np.asarray(position, np.float64)
        tree_terms = None
        if self._tree_spheres() and self.sphere_count <= self.policy.shared_terms_limit:
            tree_terms = OriginTerms.at(position, self.spheres.centers, self.spheres.radii)
        return SharedOrigin(position, self.flat_spheres.terms_at(position), tree_terms)

    def segments_need_origin(self, count: int) -> bool:
        """Whether ``count`` segments leaving one shared origin (a light sample) are answered
        through it by ``occluded``: with its spheres' terms (``shared_origin``: extended
        precision), with the flat triangles' corners less one origin (cheaper than one per
        ray: a 14-triangle scene's area light 1.2x slower traced apart), or through its
        direction bins (batches large enough to pay for them).  Where not, the same segments
        traced with their own origins, in one batch with other origins' segments, get the
        same answers, and the batch's fixed costs are paid once."""
        if self.flat_spheres.count or (self._tree_spheres()
                                       and self.sphere_count <= self.policy.shared_terms_limit):
            return True
        if len(self.flat_triangles):
            return True
        return self.tree is not None and not self.bins.too_few(count)

    def _tree_spheres(self) -> int:
        return 0 if self.tree is None else self.tree.sphere_count

    def _tree_answers(self, rays: RayBatch) -> bool:
        """Whether the tree answers this batch.  A tree of a few triangles (kept flat as
        well) answers only rays that do not share an origin (rays leaving points: a sun's,
        the world's, reflections), whose occlusion trails start beside their own triangle;
        batches from one origin (the eye, a light sample) test the flat triangles, whose
        whole-array kernels run well on threads.  The same hits either way."""
        return self.tree is not None and not (self._small_tree and rays.shared is not None)

    def _flat_answers(self, rays: RayBatch) -> bool:
        """Whether the flat triangles answer this batch (``_tree_answers``)."""
        return bool(len(self.flat_triangles)) and not (self._small_tree
                                                       and rays.shared is None)

    # ---- nearest hits -------------------------------------------------------------------

    def intersect(self, rays: RayBatch, stats: RayStats):
        """(t (n,), primitive (n,) or -1, barycentrics (b0, b1, b2) of triangle hits (n,)
        each, or None): the nearest hit of every ray.  ``nearest`` builds the hits from it."""
        t, primitive = self.flat_spheres.nearest(rays, stats)
        barycentrics = None
        if self.triangle_count:
            barycentrics = tuple(np.zeros(len(rays), self.dtype) for _ in range(3))
        if self._tree_answers(rays):
            kernel = self.tree.nearest_pairs(rays, t, primitive, barycentrics, stats)
            self.tree.nearest(kernel, self.bins.nearest(kernel), stats)
        if self._flat_answers(rays):
            t_tri, triangle, flat_bary = self.flat_triangles.nearest(rays, t, stats)
            better = t_tri < t
            t = np.where(better, t_tri, t)
            primitive = np.where(better, triangle + self.sphere_count, primitive)
            for store, b in zip(barycentrics, flat_bary):
                store[better] = b[better]
        return t, primitive, barycentrics

    @timed("seconds_nearest")
    def nearest(self, rays: RayBatch, stats: RayStats) -> Hits:
        """The nearest hit of each ray of the batch that hits something (``Hits``)."""
        t, primitive, barycentrics = self.intersect(rays, stats)
        return surface_interaction(rays, t, primitive, barycentrics, self.sphere_shape,
                                   self.triangle_shape)

    # ---- occlusion ----------------------------------------------------------------------

    @timed("seconds_shadows")
    def occluded(self, segments: RayBatch, stats: RayStats) -> np.ndarray:
        """(n,) whether a primitive other than ``segments.exclude`` is crossed within
        (t_min, t_max) of each segment, under the hit rules (``rules``)."""
        n = len(segments)
        blocked = np.zeros(n, bool)
        if n == 0:
            return blocked
        stats.shadow_rays += n
        if self.flat_spheres.count:
            blocked |= self.flat_spheres.occluded(segments, stats)
        for occlusion in (self._occluded_in_tree if self._tree_answers(segments) else None,
                          self.flat_triangles.occluded if self._flat_answers(segments)
                          else None):
            if occlusion is None or blocked.all():
                continue
            open_ = np.flatnonzero(~blocked)
            rest = segments if len(open_) == n else subset(segments, open_)
            blocked[open_] |= occlusion(rest, stats)
        return blocked

    def _occluded_in_tree(self, segments: RayBatch, stats) -> np.ndarray:
        kernel = self.tree.occlusion_pairs(segments, stats)
        by_slot = not self.sphere_shape.textbook and self.tree.by_slot(segments)
        blocked = self.bins.occluded(kernel, by_slot)
        return self.tree.occluded(kernel, stats) if blocked is None else blocked

    # ---- rays leaving surfaces ----------------------------------------------------------

    def exclusions(self, primitive, leave_front) -> np.ndarray:
        """(m,) the primitive that rays leaving ``primitive`` (m,) on its front side
        (``leave_front`` (m,) True) or back side cannot hit again, -1 where they can: a sphere
        cannot block rays leaving its outside (it is convex), a triangle cannot block any ray
        leaving it (it is flat)."""
        return np.where(leave_front | (primitive >= self.sphere_count), primitive, -1)

    def spawn(self, points, normals, primitive, directions, leave_front,
              arrived_from=None) -> RayBatch:
        """Rays leaving m hit points (3, m) along ``directions`` (3, m), on the front side of
        their geometric ``normals`` (3, m) (front / outside) where ``leave_front`` (m,),
        offset and excluding their own primitive as the hit rules say (``HitRules.spawn``).
        arrived_from: (3,) the point the rays that arrived at the points all left, or None
        (``RayBatch.arrived_from``)."""
        if self.bins is None or not self.bins.mirror_slack > 0:
            arrived_from = None     # (no bins for mirror images: nothing to carry)
        exclusions = self.exclusions(primitive, leave_front) if self.rules.excludes else None
        return self.rules.spawn(self.sphere_count, points, normals, primitive, directions,
                                leave_front, exclusions, arrived_from)

    # ---- the frame's tables -------------------------------------------------------------

    def build_frame_tables(self, eye=None, *, bounces: bool = True, trails: bool = True,
                           threads: int = 1) -> None:
        """Build now, on up to ``threads`` threads, the tables a frame's tiles would each
        build on first use (in every worker process, before its first tile: the eye's
        depth-ordered bins of a million spheres took 2 s of each worker's CPU), for a frame
        whose camera rays share the origin ``eye`` (3,) (None: they do not), whose rays may
        leave hit points (``bounces``) and whose occlusion rays may (``trails``: a sun's,
        the world's; ``shading.traces_from_points``).  Only what those rays would use: the
        tree's traversal tables; the eye's bins where a camera batch of the frame gets
        depth-ordered ones; the occlusion trails' tables; the leaf-ordered spheres where
        rays leaving spheres read them.  They are pickled with the aggregate, so workers get
        them in the render's shared arrays (``core.workers``) and build none."""
        tree = self.tree
        if tree is None:
            return
        tree.bvh.leaf_crossings     # (which the rules below and the traversal ask for)
        leaf_rows = tree.spheres_by_slot and ((bounces and self.rules.excludes)
                                              or (trails and not self.sphere_shape.textbook))
        with thread_pool(threads) as pool:
            # (Queued first, so that they run on the pool while this thread starts the bins.)
            made = [run_on(pool, job) for job in tree.frame_jobs(leaf_rows, trails)]
            if eye is not None:
                self.bins.frame_bins(eye, pool)
            for future in made:
                future.result()
