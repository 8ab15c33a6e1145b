"""Direction bins as an accelerator: which batches bins answer instead of the tree, and their
glue to the pair kernels (``kernels``); the bins an aggregate holds (built on first use,
once per origin, within a bound on their bytes) are ``bins_held``'s.

Three kinds (``bins``): id-ordered bins around a shared origin (the eye, a light sample),
where a batch's candidate pairs are few; depth-ordered ones, walked front to back, for
dense fields seen by many rays; and a sun's parallel bins, for its shadow rays through a
tree of spheres.  A floor's reflections of the camera's rays are answered by bins around
the eye's mirror image (``_mirror_groups``)."""

from __future__ import annotations

import numpy as np

from ..rays import RayBatch
from ..vectors import dot, take
from .bins_held import HeldBins
from .kernels import NearestPairs, OcclusionPairs
from .mirrors import mirror_images


class DirectionBins:
    """The direction bins of an aggregate's tree (``tree.TreeAccelerator``): spheres,
    triangles the scene's shapes; tree_spheres (k,) the spheres the tree holds (ascending);
    rays_per_origin: how many rays a frame traces from one shared origin (the eye, a light
    sample), as far as the caller knows (0: unknown), which decides whether depth-ordered
    or parallel bins pay; policy: the ``GeometryPolicy``.  Which batches bins answer, and how;
    the bins themselves are its ``store``'s (``bins_held.HeldBins``)."""

    def __init__(self, tree, spheres, triangles, tree_spheres, rays_per_origin: int, policy):
        self.tree, self.spheres, self.triangles = tree, spheres, triangles
        self.rays_per_origin = int(rays_per_origin)
        self.policy = policy
        self.store = HeldBins(tree, spheres, triangles, tree_spheres, policy)

    @property
    def mirror_slack(self) -> float:
        """How far from a common point mirror images' lines may pass (``_mirror_groups``;
        ``HeldBins.mirror_slack``)."""
        return self.store.mirror_slack

    # ---- which batches --------------------------------------------------------------------

    def too_few(self, count: int) -> bool:
        """Whether a batch of ``count`` rays from one origin is too small for id-ordered
        bins (``policy.bins_primitives_per_ray``), or the tree too large for any."""
        return (self.tree.boxes is None
                or count * self.policy.bins_primitives_per_ray < len(self.tree.boxes[0]))

    def depth_pays(self) -> bool:
        """Whether an origin whose id-ordered bins do not pay gets depth-ordered ones
        (``policy.depth_rays_per_primitive``, ``depth_bins_crossings``)."""
        return (self.rays_per_origin >= self.policy.depth_rays_per_primitive * len(self.tree)
                and self.tree.bvh.leaf_crossings >= self.policy.depth_bins_crossings)

    # ---- queries ----------------------------------------------------------------------------

    def nearest(self, kernel: NearestPairs):
        """Answer what bins answer of the kernel's batch: None where they answer nothing (the
        tree answers every ray), else (k,) the rays left to the tree, ascending."""
        rays = kernel.rays
        n = len(rays)
        bins, plan = self._origin_plan(rays)
        if plan is not None and not bins.by_depth:
            bins.traverse(plan, kernel.reach, kernel.visit, kernel.accept, exclude=kernel.exclude)
            return np.zeros(0, np.intp)
        rest = None     # the rays the tree answers (None: all of them)
        if plan is not None:
            # Front to back through the cells; the rays still walking after the last round
            # are the tree's, from what they had before (``OriginBins.walk``).
            before = kernel.state()
            _, walking = bins.walk(plan, kernel.reach, kernel.visit, kernel.accept,
                                   exclude=kernel.exclude, rounds=self.policy.walk_rounds)
            kernel.restore(before, walking)
            return walking
        exclude = kernel.exclude
        for members, bins, plan, shift in self._mirror_groups(rays):
            local = kernel.reach.take(members)
            visit, accept, _ = kernel.of(members, local)
            bins.traverse(plan, local, visit, accept,
                          exclude=None if exclude is None else exclude.take(members),
                          reach_shift=shift)
            rest = np.ones(n, bool) if rest is None else rest
            rest[members] = False
        return None if rest is None else np.flatnonzero(rest)

    def occluded(self, kernel: OcclusionPairs, by_slot: bool):
        """(n,) whether each segment of the kernel's batch is blocked, where bins answer it,
        else None: id-ordered bins around a shared origin, or (with ``by_slot``: a tree of
        spheres visited by slot) a sun's parallel bins."""
        segments = kernel.rays
        bins, plan = self._origin_plan(segments, depth=False)
        if plan is not None:
            return bins.traverse(plan, kernel.reach, kernel.visit, any_hit=True,
                                 exclude=kernel.exclude)
        if not by_slot:
            return None
        parallel = self.parallel_spheres(segments)
        if parallel is None:
            return None
        bins, listed = parallel
        blocked = np.zeros(len(segments), bool)
        r, entries = bins.pairs(segments.origins)
        table = (*self.spheres.centers_t, self.spheres.radii, None)
        blocked[kernel.slot_blocks(r, listed.take(entries), table)] = True
        return blocked

    def frame_bins(self, eye, pool=None) -> None:
        """The eye's depth-ordered bins, where a camera batch of the frame gets them."""
        if self.depth_pays():
            self.store.bins_at(eye, depth=True, pool=pool)

    # ---- the bins asked for ---------------------------------------------------------------

    def _origin_plan(self, rays: RayBatch, depth: bool = True):
        """(bins, plan): the direction bins of the batch's shared origin and the batch's
        plan over them (``OriginBins.plan``), or (None, None) where the tree answers instead
        (no shared origin, too few rays to pay for bins, bins that would not pay there, or
        too many candidates for this batch)."""
        if rays.shared is None:
            return None, None
        depth = depth and self.depth_pays()
        few = self.too_few(len(rays))
        if few and not depth:
            return None, None
        bins = self.store.bins_at(rays.shared.position, depth=depth)
        if bins is None or (few and not bins.by_depth):
            return None, None
        plan = bins.plan(rays.directions, self.policy.max_pairs_per_ray)
        return (bins, plan) if plan is not None else (None, None)

    def parallel_spheres(self, segments: RayBatch):
        """(bins, listed): the parallel bins (``bins.ParallelBins``) of segments that all
        leave along one direction unbounded from t_min >= 0 (a sun's shadow rays), with the
        sphere (global id) of each entry; or None where the tree answers (other segments,
        a frame of too few rays per tree sphere, ``policy.parallel_rays_per_primitive``,
        bins that would not pay or not fit).  Built on first use, once per direction."""
        d = segments.directions
        if (self.rays_per_origin < self.policy.parallel_rays_per_primitive * len(self.tree)
                or len(segments) == 0 or not np.isposinf(segments.t_max).all()
                or np.min(segments.t_min) < 0 or not (d == d[:, :1]).all()):
            return None

        return self.store.parallel_at(d[:, 0])

    # ---- mirror images ------------------------------------------------------------------------

    def _mirror_groups(self, rays: RayBatch):
        """[(members (k,), bins, plan, reach shift (k,))]: groups of the batch's rays whose
        lines pass within ``mirror_slack`` (per axis) of one point q behind their origins,
        enough of them to pay for bins (``policy.bins_primitives_per_ray``), and the
        direction bins around q of the tree's boxes grown by that much.

        A flat mirror's reflections of rays from one point E (``RayBatch.arrived_from``: a
        camera's eye) all pass through E's mirror image in its plane, and a large sphere's
        (the article's floor) near the image of E in its tangent plane nearest to E: the
        first bounce's rays off a floor, which cross the whole field, are answered as if
        they left q, as camera rays are.  q is that image for each ray's source primitive
        (rounded to a grid of a quarter of the slack, so that the triangles of one plane
        share it), and each ray is checked.  Exact: a ray o + t d (t >= 0) whose line passes
        within e of q, with q behind o (tau = (q - o).d / |d|^2 <= 0), is q + e + s d with
        s = t - tau >= 0, so every box it meets, grown by |e| per axis, is met by the ray
        from q along d, and listed in d's cell; and a grown box at a distance D from q is
        met by the ray at t >= D + tau (so ``reach_shift`` = -tau)."""
        eye = rays.arrived_from
        if (eye is None or rays.source is None or self.tree.boxes is None
                or not self.mirror_slack > 0):
            return []
        need = len(self.tree.boxes[0]) * self.policy.bins_primitives_per_ray
        if len(rays) < need:
            return []
        grid = self.mirror_slack / 4
        images = mirror_images(np.asarray(eye, np.float64), rays.source, grid, need,
                               self.spheres, self.triangles)
        if images is None:
            return []
        cell, points = images
        groups = []
        for key in np.flatnonzero(np.bincount(cell + 1)[1:] >= need):
            members = np.flatnonzero(cell == key)
            point = points[key]
            towards = point[:, None] - take(rays.origins, members)
            directions = take(rays.directions, members).astype(np.float64)
            tau = dot(towards, directions) / dot(directions, directions)
            towards -= tau * directions
            miss = np.abs(towards).max(axis=0)
            near = np.flatnonzero((miss <= self.mirror_slack * (1 - 1e-6)) & (tau <= 0))
            if len(near) < need:
                continue
            members = members.take(near)
            bins = self.store.bins_at(point, mirror=True)
            plan = None if bins is None else bins.plan(take(rays.directions, members),
                                                       self.policy.max_pairs_per_ray)
            if plan is not None:
                groups.append((members, bins, plan, -tau.take(near)))
        return groups
