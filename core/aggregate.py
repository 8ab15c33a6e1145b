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
few of them, and through a binned-SAH BVH with every triangle otherwise (``core.bvh``), whose
primitives rays sharing an origin find through direction bins where those are cheaper
(``core.bins``), as do a floor's reflections of the camera's rays, around the eye's mirror
image (``Aggregate._mirror_groups``); a scene of four spheres builds no tree and pays
nothing for triangle support.

Two choices are made once, when the aggregate is built: the hit rules (``article``: the
article's, where a sphere counts only if both roots are positive, a shadow segment counts
only the sphere's far root, and rays leave with its fixed 1e-5 offset; otherwise the nearest
root beyond t_min, any root inside a segment, scaled offsets and self-exclusion) and the
root formula for spheres (``root_formula``: 'textbook', the article's, or 'stable').
"""

from __future__ import annotations

import threading

import numpy as np

from .arrays import SphereArrays, TriangleArrays
from .bins import OriginBins, ParallelBins
from .bvh import BVH, MAX_LEAF, SLAB_PADDING_32, run_on, thread_pool
from .cull import (DENSE_CANDIDATES, REFLECTION_CELLS, SHADOW_CELLS, bundle_candidates,
                   candidate_roots, cones,
                   cluster_spheres, direction_cells, reachable)
from .intersect import (FewSpheres, OriginTerms, first_hit_distance, offset_discriminants,
                        offset_press_roots, offset_roots, origin_roots)
from .rays import ARTICLE_OFFSET, Hits, RayBatch, RayStats, SharedOrigin, ray_offsets, timed
from .terminator import TerminatorLift, smooth_surface_lift
from .triangles import Shear, watertight_axes, watertight_pairs
from .vectors import dot, facing, take

#: The two ways to compute ray/sphere roots (``core.intersect``).
ROOT_FORMULAS = ("textbook", "stable")
#: Upper bound on (ray, triangle) pairs intersected at once; bounds the (k, n) temporaries.
TRIANGLE_BLOCK_PAIRS = 1 << 18
#: Scenes with at most this many spheres cull them flat (``core.cull``), with no tree.
#: Measured at stop 24 on ``bench.scenes.random_sphere_set_scene`` (its floor beside the
#: tree), one thread, the tree against flat culling in article semantics and in default
#: semantics under a sun with and without the world's occlusion rays and under a hard
#: point light, same images: at 320x180 with adaptive AA 1.59-2.43x at 3-5 spheres,
#: 1.05-1.32x at 8-10, 0.81-0.97x at 16, 0.72-0.77x at 24, 0.66-0.67x at 50 and
#: 0.14-0.21x at 250; at 640x360 without AA 1.07-1.23x at 10, 1.02-1.05x at 16, 0.91-0.94x
#: at 32 and 0.57-0.62x at 100.  (Until stop 24 this was 500, from a measurement before
#: the occlusion trails and the bins: flat 0.30 s against the tree's 0.56 s at 250.)
BVH_MIN_SPHERES = 24
#: Meshes with at most this many triangles in all are tested flat, with no tree, unless a
#: tree of them saves a ray TREE_SAVED_TESTS triangle tests (``small_mesh_saved_tests``).
BVH_MIN_TRIANGLES = 16
#: A few triangles get a tree where it saves a ray at least this many of the flat test's
#: triangle tests (about 120 ns each, every ray against every triangle its bundle's cone
#: reaches), against a tree's fixed cost a batch; the tree answers only rays leaving points
#: (``_tree_answers``).  Same images; a cube over a floor plane (14 triangles, saves 12.2)
#: and the cube alone (saves 8.0), at 320x180 (adaptive) and 640x360 (AA off), under a soft
#: point light and soft and hard suns with the world's occlusion rays: 0.32-0.71x the flat
#: time on one thread, 0.54-1.01x on two (the soft light's samples gain most from the
#: flat kernels' threads).  A room's floor, walls and ceiling (4-8 triangles spanning the
#: scene, saving 2.5-5: a tree took 0.99-1.74x their flat time) and a floor plane under a
#: sphere (saves 0; 1.6-2.2x) stay flat.
TREE_SAVED_TESTS = 8.0
#: A sphere whose radius exceeds this multiple of the median stays out of the tree (the
#: article's floor, radius 9000, would make the root's box that size: every ray would
#: enter it); at most MAX_HUGE of them.  Triangles all go into the tree: its SAH build
#: keeps large ones (a backdrop) apart from small ones.
HUGE_RATIO = 8.0
MAX_HUGE = 64
#: Shared-origin sphere terms for the tree's spheres only up to this many spheres (memory:
#: about 40 bytes a sphere for every light sample).
SHARED_TERMS_LIMIT = 100_000
#: Rays sharing an origin are answered by direction bins (``core.bins``) instead of the
#: tree only while the tree holds at most this many primitives (counting a million boxes'
#: cells for every light sample would cost more than the bins could save).  An aggregate's
#: bins (a frame's eye and light samples) hold at most about BINS_MAX_BYTES: origins met
#: once that much is held use the tree (which batches use bins may then depend on the order
#: tiles ran in, and so the stats' box tests; the hits never do).
BINS_MAX_PRIMITIVES = 100_000
BINS_MAX_BYTES = 64 * 1024 ** 2
#: A batch goes to bins only with at least one ray per BINS_PRIMITIVES_PER_RAY tree
#: primitives: counting an origin's cells costs about a microsecond a primitive, as much as
#: tracing a ray through the tree, so an origin whose bins are refused costs at most about
#: one such batch more (and a frame has a batch per tile).  The rule depends on the batch
#: alone, so which batches use bins does not depend on the order tiles run in.
BINS_PRIMITIVES_PER_RAY = 1
#: Where id-ordered bins would not pay (dense fields, or more than BINS_MAX_PRIMITIVES),
#: an origin gets depth-ordered bins (``OriginBins.walk``) when a frame traces at least this
#: many rays from one origin (``rays_per_origin``) per tree primitive: listing a million
#: boxes costs about a second, a camera ray through a dense field's tree about 4 us.
DEPTH_RAYS_PER_PRIMITIVE = 1.0
#: ... and when the tree is a dense field: a random line through its root box crosses at
#: least this many leaf boxes (``BVH.leaf_crossings``).  Where rays meet few leaves the tree
#: answers a camera ray in a few box tests and the bins' build is all cost: Suzanne of
#: 251,906 triangles at 960x540 (0.9 crossings) took 2.0 s of nearest hits with them against
#: 1.0 s without (one thread); the 10^5 GN instances (24.2) and the 10^5 and 10^6 sphere
#: sets (39, 276) gain.
DEPTH_BINS_CROSSINGS = 16.0
#: Bytes of bins an aggregate holds beside BINS_MAX_BYTES, per tree primitive (depth-ordered
#: bins: a few entries per primitive for the eye and a light).
BINS_BYTES_PER_PRIMITIVE = 64
#: A sun's shadow rays (unbounded, one direction) in a tree of spheres go through parallel
#: bins (``core.bins.ParallelBins``) when the frame traces at least this many rays from one
#: origin (``rays_per_origin``: its pixels, about as many as a sun's shadow rays) per tree
#: sphere: listing costs about 0.65 us a sphere, a sun's ray through the tree of a dense
#: field about 2 us (the bins about 0.45 us).  (The 10^5 GN instances at 640x360: 2.3;
#: the 10^6 points: 0.23, left to the tree.)
PARALLEL_RAYS_PER_PRIMITIVE = 1.0
#: Rays leaving one primitive whose lines pass this close to one point (a fraction of the
#: tree's median box half side; ``Aggregate._mirror_groups``) are answered by direction bins
#: around that point, with the boxes grown by as much.
MIRROR_SLACK = 0.125
#: Spheres culled flat beside a tree are the huge ones (``_partition``: a floor), which
#: nearly every bundle's cone reaches: up to this many, every ray tests each of them
#: without the bundle's cone, which cost more than it saved (issue 9's 1,000 spheres over
#: the article's floor: the cone 15-23 ns a ray, 0.08 s of a 2 s frame, left the floor
#: out of 60 of 508 batches; a test of the floor about 25 ns a ray).
UNCULLED_BESIDE_TREE = 2


def _roots_block(t_near, t_far, low, high, article: bool):
    """Whether a sphere with roots t_near, t_far (valid ones) blocks a segment (low, high):
    under the article's rules when its far root lies within (the article tests the reversed
    ray, from the shaded point), else when either root does."""
    if article:
        return (t_far < high) & (t_far > low)
    return ((t_near > low) & (t_near < high)) | ((t_far > low) & (t_far < high))


def _per_ray(values, n, dtype=np.float64):
    return np.broadcast_to(np.asarray(values, dtype), (n,))


class Aggregate:
    """All of a scene's geometry, in the render precision ``dtype``.

    spheres, triangles: the scene's primitives (``core.arrays``); article: the article's hit
    rules; root_formula: 'textbook' or 'stable' (``ROOT_FORMULAS``); threads: how many
    threads the tree may be built on (``BVH.build``: the same tree for any number);
    rays_per_origin: how many rays a frame traces from one shared origin (the eye, a light
    sample), as far as the caller knows (``make_context``: the pixels; 0: unknown), which
    decides whether a shared origin's depth-ordered or parallel bins pay
    (DEPTH_RAYS_PER_PRIMITIVE, PARALLEL_RAYS_PER_PRIMITIVE).
    """

    def __init__(self, spheres: SphereArrays, triangles: TriangleArrays, dtype, *,
                 article: bool, root_formula: str, threads: int = 1,
                 rays_per_origin: int = 0):
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
        self._radii_t = cast(spheres.radii)
        self._sphere_material = spheres.material
        flat_spheres, tree_spheres = _partition(spheres.radii, BVH_MIN_SPHERES)
        # Spheres culled flat: all of them (ids None), or the huge ones beside a tree.
        self._flat_ids = None if len(tree_spheres) == 0 else flat_spheres
        self._flat_centers = spheres.centers[flat_spheres]
        self._flat_radii = spheres.radii[flat_spheres]
        self._flat_count = len(flat_spheres)
        self._clusters = cluster_spheres(self._flat_centers, self._flat_radii)
        tree_triangles = np.zeros(0, np.intp)
        self._flat_triangles = np.arange(self.triangle_count)
        self._small_tree = False
        if self.triangle_count:
            t = triangles
            # The corners as rows (9, T) for the tree's pair kernel; _v are views of them.
            self._corners = cast(np.concatenate([t.v0, t.v1, t.v2]))
            self._v = (self._corners[0:3], self._corners[3:6], self._corners[6:9])
            self._tri_normals = cast(t.normals)
            self._tri_corner_normals = (None if t.corner_normals is None
                                        else cast(t.corner_normals))
            # Geometry offsets of the smooth triangles' shadow rays (None: no such triangle;
            # the article's rules have none).
            self._tri_terminator = (None if t.terminator_offset is None or article
                                    else cast(t.terminator_offset))
            # Bounding spheres of the triangles, for the bundle's cone test.
            centre = (t.v0 + t.v1 + t.v2) / 3
            reach = np.sqrt(np.maximum.reduce([((v - centre) ** 2).sum(axis=0)
                                               for v in (t.v0, t.v1, t.v2)]))
            self._tri_centers = centre
            self._tri_radii = reach * (1 + 1e-9) + 1e-12 * (1 + np.abs(centre).max(axis=0))
            self._tri_material = t.material
            # Every triangle goes into the tree once there are enough (the SAH build puts
            # large ones, a backdrop, in their own subtrees).  A few compact ones beside
            # flat spheres get a tree of their own and stay flat as well (``_small_tree``:
            # ``_tree_answers``).
            if builds_tree(0, self.triangle_count):
                self._flat_triangles, tree_triangles = (np.zeros(0, np.intp),
                                                        np.arange(self.triangle_count))
            elif len(tree_spheres) == 0 and builds_tree(
                    0, self.triangle_count, small_mesh_saved_tests(t.v0, t.v1, t.v2)):
                self._small_tree = True
                tree_triangles = np.arange(self.triangle_count)
        # One tree over the rest, spheres and triangles together (global ids).
        self._tree = None
        self._tree_boxes = None
        self.mirror_slack = 0.0
        self._surface_keys = None   # built on first use (adaptive anti-aliasing only)
        self._tree_spheres = len(tree_spheres)
        self._tree_triangles = len(tree_triangles)
        # A tree of spheres alone: rays that exclude a sphere (the default rules' rays
        # leaving one) visit its leaves by slot, on the leaf-ordered spheres
        # (``_leaf_spheres``).
        self._spheres_by_slot = bool(self._tree_spheres) and not self._tree_triangles
        if len(tree_spheres) or len(tree_triangles):
            self._build_tree(spheres, triangles, tree_spheres, tree_triangles, threads)
        self._bins = {}     # origin (bytes) -> OriginBins, or None: the tree answers there
        self._parallel = {}     # a sun's direction (bytes) -> (ParallelBins, ids), or None
        self._bins_bytes = 0
        self.rays_per_origin = int(rays_per_origin)
        # (Guards what tiles running in threads build on first use: bins, leaf-ordered
        # spheres.)
        self._lazy_lock = threading.Lock()
        self._leaf_rows = None      # the tree's spheres in leaf order (``_leaf_spheres``)

    def _build_tree(self, spheres, triangles, tree_spheres, tree_triangles, threads):
        """The tree over spheres tree_spheres (k,) and triangles tree_triangles (t,) (indices),
        under global ids (triangles after every sphere), built on up to ``threads`` threads."""
        # The boxes as columns (3, P), which the build works on (passed as their (P, 3) views).
        lows, highs = [], []
        if len(tree_spheres):
            every = len(tree_spheres) == len(spheres)       # (then tree_spheres is 0 .. N-1)
            c = spheres.centers.T if every else spheres.centers[tree_spheres].T
            r = spheres.radii if every else spheres.radii[tree_spheres]
            lows.append(np.subtract(c, r, out=np.empty(c.shape)))
            highs.append(np.add(c, r, out=np.empty(c.shape)))
            del c, r
        if len(tree_triangles):
            v0, v1, v2 = (take(v, tree_triangles) for v in (triangles.v0, triangles.v1,
                                                             triangles.v2))
            lows.append(np.minimum(np.minimum(v0, v1), v2))
            highs.append(np.maximum(np.maximum(v0, v1), v2))
            del v0, v1, v2
        ids = np.concatenate([tree_spheres, tree_triangles + self.sphere_count])
        # (One kind only: its boxes as they are, no concatenated copy held beside them.)
        low = (lows[0] if len(lows) == 1 else np.concatenate(lows, axis=1)).T
        high = (highs[0] if len(highs) == 1 else np.concatenate(highs, axis=1)).T
        del lows, highs
        self._tree = BVH.build(ids, low, high, threads)
        # The boxes again for direction bins (``_origin_bins``), while they may pay.
        self._tree_boxes = (ids, low, high) if len(ids) <= BINS_MAX_PRIMITIVES else None
        # How far from a common point mirror images' lines may pass (``_mirror_groups``): a
        # fraction of the boxes' typical half side, so grown boxes list few more rays.
        if self._tree_boxes is not None:
            self.mirror_slack = MIRROR_SLACK * float(np.median((high - low).max(axis=1))) / 2

    def __len__(self) -> int:
        return self.sphere_count + self.triangle_count

    @property
    def lifts_terminator(self) -> bool:
        """Whether hits on smooth triangles are lifted off their facets (``Hits.terminator``:
        their shadow rays leave the lifted points, ``core.terminator``)."""
        return bool(self.triangle_count) and self._tri_terminator is not None

    def __getstate__(self):
        """Pickled (for worker processes) without its lock, with the tables built so far
        (``build_frame_tables``: the frame's, built once for every worker; a table a worker
        then builds on first use, such as a sun's parallel bins, is its own)."""
        state = dict(self.__dict__)
        del state["_lazy_lock"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lazy_lock = threading.Lock()

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
        terms = tree_terms = None
        if self._flat_count:
            terms = OriginTerms.at(position, self._flat_centers, self._flat_radii)
        if self._tree_spheres and self.sphere_count <= SHARED_TERMS_LIMIT:
            tree_terms = OriginTerms.at(position, self.spheres.centers, self.spheres.radii)
        return SharedOrigin(position, terms, tree_terms)

    def segments_need_origin(self, count: int) -> bool:
        """Whether ``count`` segments leaving one shared origin (a light sample) are answered
        through it by ``occluded``: with its spheres' terms (``shared_origin``: extended
        precision), with the flat triangles' corners less one origin (cheaper than one per
        ray: a 14-triangle scene's area light 1.2x slower traced apart), or through its
        direction bins (batches large enough to pay for them).  Where not, the same segments
        traced with their own origins, in one batch with other origins' segments, get the
        same answers, and the batch's fixed costs are paid once."""
        if self._flat_count or (self._tree_spheres and self.sphere_count <= SHARED_TERMS_LIMIT):
            return True
        if len(self._flat_triangles):
            return True
        return self._tree is not None and not self._too_few_for_bins(count)

    def _tree_answers(self, rays: RayBatch) -> bool:
        """Whether the tree answers this batch.  A tree of a few triangles
        (``small_mesh_saved_tests``, which are kept flat as well) answers only rays that do
        not share an origin (rays leaving points: a sun's, the world's, reflections), whose
        occlusion trails start beside their own triangle; batches from one origin (the
        eye, a light sample) test the flat triangles, whose whole-array kernels run well
        on threads (two threads, a soft point light's samples over a cube and a plane: the
        tree 1.08-1.47x the flat test's time; the corpus' area lamp 1.2x; the suns and the
        world's rays 0.66-0.85x).  The same hits either way."""
        return self._tree is not None and not (self._small_tree and rays.shared is not None)

    def _flat_answers(self, rays: RayBatch) -> bool:
        """Whether the flat triangles answer this batch (``_tree_answers``)."""
        return bool(len(self._flat_triangles)) and not (self._small_tree
                                                         and rays.shared is None)

    def _too_few_for_bins(self, count: int) -> bool:
        """Whether a batch of ``count`` rays from one origin is too small for id-ordered
        direction bins (BINS_PRIMITIVES_PER_RAY), or the tree too large for any."""
        return (self._tree_boxes is None
                or count * BINS_PRIMITIVES_PER_RAY < len(self._tree_boxes[0]))

    # ---- nearest hits -------------------------------------------------------------------

    def intersect(self, rays: RayBatch, stats: RayStats):
        """(t (n,), primitive (n,) or -1, barycentrics (b0, b1, b2) of triangle hits (n,)
        each, or None): the nearest hit of every ray.  ``nearest`` builds the hits from it."""
        t, primitive = self._nearest_spheres(rays, stats)
        barycentrics = None
        if self.triangle_count:
            barycentrics = tuple(np.zeros(len(rays), self.dtype) for _ in range(3))
        if self._tree_answers(rays):
            self._nearest_in_tree(rays, t, primitive, barycentrics, stats)
        if self._flat_answers(rays):
            t_tri, triangle, flat_bary = self._nearest_triangles(rays, t, stats)
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
        keep = np.flatnonzero(primitive >= 0)
        origins, directions = rays.origins, rays.directions
        if len(keep) < len(primitive):
            t, hit_primitive = t[keep], primitive[keep]
            directions = take(directions, keep)
            origins = origins if origins.shape[1] == 1 else take(origins, keep)
        else:
            hit_primitive = primitive
        is_triangle = hit_primitive >= self.sphere_count
        lifted = None    # smooth triangles' terminator lift (``_terminator_lift``)
        hit_barycentrics = None
        if not is_triangle.any():
            points = t * directions
            points += origins
            normals = take(self._centers_t, hit_primitive)
            np.subtract(points, normals, out=normals)
            size = dot(normals, normals)
            np.sqrt(size, out=size)
            normals *= np.reciprocal(size, out=size)
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
            hit_barycentrics = tuple(b[keep] for b in barycentrics)
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
                corners = tuple(take(c, triangle) for c in corner)
                smooth = b0 * corners[0] + b1 * corners[1] + b2 * corners[2]
                shading[:, tris] = smooth * (1 / np.sqrt(dot(smooth, smooth)))
                if self._tri_terminator is not None:
                    lifted = (tris, triangle, (v0, v1, v2), corners, (b0, b1, b2))
        cos_in = dot(directions, shading)
        front = cos_in < 0 if shading is normals else dot(directions, normals) < 0
        terminator = None
        if lifted is not None:
            terminator = self._terminator_lift(normals, shading, front, *lifted)
        return Hits(keep, primitive, t, hit_primitive, material, points, directions, normals,
                    shading, cos_in, front, terminator, hit_barycentrics)

    def _terminator_lift(self, normals, shading, front, tris, triangle, corners,
                         corner_normals, barycentrics):
        """The hits' ``TerminatorLift`` (``core.terminator``): the smooth-surface offsets
        of the hits ``tris`` on triangles ``triangle`` (k,), their corners, corner normals
        (3, k) each and barycentrics (k,) each; the other hits keep their origins."""
        geometric, seen_shading = facing(normals, front), facing(shading, front)
        lift = np.zeros_like(normals)
        lift[:, tris] = smooth_surface_lift(corners, corner_normals, barycentrics,
                                            geometric[:, tris])
        cutoff = np.zeros(normals.shape[1], self.dtype)
        cutoff[tris] = self._tri_terminator.take(triangle)
        return TerminatorLift(lift, cutoff, geometric, seen_shading)

    def _nearest_spheres(self, rays: RayBatch, stats):
        n = len(rays)
        best_t = np.full(n, np.inf, rays.directions.dtype)
        best = np.full(n, -1, np.intp)
        if not self._flat_count:
            return best_t, best
        ids = self._flat_ids
        terms = rays.shared.sphere_terms if rays.shared is not None else None
        key = self._flat_key(rays)
        t_min, t_max, exclude = rays.t_min, rays.t_max, rays.exclude
        candidates = self._bundle_candidates(rays)
        if len(candidates) <= DENSE_CANDIDATES:
            if len(candidates):
                stats.sphere_tests += n * len(candidates)
                self._few(rays, terms).nearest(candidates, t_min, t_max, exclude, ids, best_t,
                                               best)
            return best_t, best
        for block in candidate_roots(self._flat_centers, self._flat_radii, self._clusters,
                                     rays.origins, rays.directions, t_max, terms,
                                     textbook=self._textbook, stats=stats, key=key,
                                     candidates=candidates):
            distances = first_hit_distance(block.t_near, block.t_far, block.valid,
                                           block.per_pair(t_min), article=self.article)
            distances[~(distances < block.per_pair(t_max))] = np.inf
            if exclude is not None:
                spheres = block.spheres if ids is None else ids[block.spheres]
                distances[spheres == block.per_pair(exclude)] = np.inf
            t, sphere = block.nearest(distances)
            if ids is not None:
                sphere = np.where(sphere >= 0, ids[sphere], -1)
            # Strictly nearer only: on a tie the earlier block (earlier in scene order) keeps it.
            better = t < best_t[block.rays]
            best_t[block.rays] = np.where(better, t, best_t[block.rays])
            best[block.rays] = np.where(better, sphere, best[block.rays])
        return best_t, best

    def _flat_key(self, rays: RayBatch):
        """(n,) the packets the flat culling groups rays into (None: in their order).  Rays
        from one origin (a light sample) packed by direction make narrow cones; rays leaving
        one primitive (``source``) in one direction cell cull well together."""
        if self._flat_count <= DENSE_CANDIDATES:
            return None
        if rays.shared is not None:
            return direction_cells(rays.directions, SHADOW_CELLS)
        if rays.source is not None:
            return (rays.source * (6 * REFLECTION_CELLS ** 2)
                    + direction_cells(rays.directions, REFLECTION_CELLS))
        return None

    def _bundle_candidates(self, rays: RayBatch) -> np.ndarray:
        """(k,) the flat spheres (local indices) some ray of the batch may reach: all of
        them beside a tree when they are at most UNCULLED_BESIDE_TREE."""
        if len(rays) == 0:
            return np.zeros(0, np.intp)
        if self._tree is not None and self._flat_count <= UNCULLED_BESIDE_TREE:
            return np.arange(self._flat_count)
        reach = rays.t_max if np.ndim(rays.t_max) == 0 else rays.t_max.max()
        return bundle_candidates(self._flat_centers, self._flat_radii, rays.origins,
                                 rays.directions, float(reach))

    def _few(self, rays: RayBatch, terms) -> FewSpheres:
        return FewSpheres(self._flat_centers, self._flat_radii, rays.origins, rays.directions,
                          terms, textbook=self._textbook, article=self.article)

    def _triangle_candidates(self, rays: RayBatch, reach):
        """Triangles the batch's bounding cone can reach within ``reach`` (scalar)."""
        apex, spread, axis, half = cones(rays.origins[:, None, :], rays.directions[:, None, :])
        flat = self._flat_triangles
        return flat[reachable(self._tri_centers[:, flat], self._tri_radii[flat], apex, spread,
                              axis, half, reach)]

    def _triangle_blocks(self, rays: RayBatch, t_max, stats):
        """Yields (triangles (k,), rays (r,) of the batch, t, b0, b1, b2, valid (k, r)) over
        candidate triangles, the rays in groups of one shear's axes (``watertight_axes``:
        at most six, by the direction's largest axis and its sign), each ray's triangles in
        candidate order.  t_max: scalar or (n,), read again for every block (a nearest-hit
        search lowers it as hits are found)."""
        n = len(rays)
        reach = _per_ray(t_max, n)
        finite = reach[np.isfinite(reach)]
        limit = np.inf if len(finite) < n else (finite.max() if n else 0.0)
        candidates = self._triangle_candidates(rays, limit)
        if len(candidates) == 0 or n == 0:
            return
        shear = Shear.of(rays.directions)
        kx, ky, kz = shear.axes
        key = 3 * kz + kx                     # (kz, kx) fixes the permutation
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(key.take(order))) + 1
        shared = rays.origins.shape[1] == 1
        origins = rays.origins.astype(self.dtype, copy=False)
        t_min = np.asarray(rays.t_min, self.dtype)
        for group in np.split(order, bounds):
            first = group[0]
            axes = (int(kx[first]), int(ky[first]), int(kz[first]))
            factors = take(shear.factors, group)
            starts = origins[:, None, :] if shared else take(origins, group)[:, None, :]
            low = t_min.take(group)[None, :] if t_min.ndim else t_min
            chunk = max(1, TRIANGLE_BLOCK_PAIRS // len(group))
            for start in range(0, len(candidates), chunk):
                triangles = candidates[start:start + chunk]
                if stats is not None:
                    stats.triangle_tests += len(group) * len(triangles)
                v0, v1, v2 = (v[:, triangles][:, :, None] for v in self._v)
                high = np.asarray(t_max, self.dtype)
                high = high.take(group)[None, :] if high.ndim else high
                t, b0, b1, b2, valid = watertight_axes(v0, v1, v2, starts, axes, factors,
                                                       low, high)
                if rays.exclude is not None:
                    valid &= ((triangles + self.sphere_count)[:, None]
                              != rays.exclude.take(group)[None, :])
                yield triangles, group, t, b0, b1, b2, valid

    def _nearest_triangles(self, rays: RayBatch, t_max_now, stats):
        """(t (n,), triangle (n,) local index or -1, (b0, b1, b2) (n,) each) of the nearest
        triangle hit nearer than ``t_max_now`` (n,) and the batch's own t_max."""
        n = len(rays)
        # Hits must beat this; it shrinks as hits are found (the blocks read it each time).
        limit = np.minimum(np.asarray(t_max_now, self.dtype), _per_ray(rays.t_max, n, self.dtype))
        found_t = np.full(n, np.inf, self.dtype)
        best = np.full(n, -1, np.intp)
        bary = [np.zeros(n, self.dtype) for _ in range(3)]
        for triangles, group, t, b0, b1, b2, valid in self._triangle_blocks(rays, limit, stats):
            t = np.where(valid, t, np.inf)
            row = np.argmin(t, axis=0)
            columns = np.arange(len(group))
            nearest = t[row, columns]
            better = np.flatnonzero(nearest < limit.take(group))
            rays_better = group.take(better)
            found_t[rays_better] = nearest.take(better)
            best[rays_better] = triangles.take(row.take(better))
            for store, b in zip(bary, (b0, b1, b2)):
                store[rays_better] = b[row.take(better), better]
            limit[rays_better] = found_t.take(rays_better)   # (each below its limit)
        return found_t, best, tuple(bary)

    # ---- the tree -----------------------------------------------------------------------

    def _box_terms(self, rays: RayBatch, keep=None):
        """The tree's box tests' terms of the batch's rays (of rays ``keep`` (k,), None:
        all): float64 origins and inverse directions (only where the tree is traversed:
        rays answered by bins need neither)."""
        directions = rays.directions if keep is None else take(rays.directions, keep)
        origins = rays.origins if keep is None or rays.origins.shape[1] == 1 \
            else take(rays.origins, keep)
        with np.errstate(divide="ignore"):
            inverse = 1 / directions.astype(np.float64)
        return origins.astype(np.float64, copy=False), inverse

    def _sphere_pairs(self, rays: RayBatch, r, sphere):
        """(t_near, t_far, valid) (E,) of pairs (ray r, sphere), with the batch's shared
        terms when it has them for every sphere."""
        directions = take(rays.directions, r)
        terms = rays.shared.tree_terms if rays.shared is not None else None
        if terms is not None:
            return origin_roots(take(terms.rows, sphere), terms.c_prime.take(sphere),
                                terms.article_c.take(sphere), self.spheres.radii.take(sphere),
                                directions, article=self._textbook)
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        return offset_roots(origins - take(self._centers_t, sphere), directions,
                            self._radii_t[sphere], article=self._textbook)

    def _sphere_blocks(self, rays: RayBatch, r, sphere, low, high):
        """(E,) whether pairs (ray r, sphere) (E,) are blocked under the default rules: a
        root of the pair within (low, high) (n,) of its ray.  The roots of ``_sphere_pairs``,
        computed only for the pairs whose ray meets the sphere (most of a leaf's miss): the
        same flags, found 4-5 % faster on the occlusion rays of issue 9's sphere fields."""
        terms = rays.shared.tree_terms if rays.shared is not None else None
        if terms is not None or self._textbook:
            t_near, t_far, valid = self._sphere_pairs(rays, r, sphere)
            return valid & _roots_block(t_near, t_far, low[r], high[r], article=False)
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        f = origins - take(self._centers_t, sphere)
        radii = self._radii_t.take(sphere)
        b, disc = offset_discriminants(f, take(rays.directions, r), radii)
        blocked = disc > 0
        meet = np.flatnonzero(blocked)
        t_near, t_far = offset_press_roots(take(f, meet), radii.take(meet), b.take(meet),
                                           disc.take(meet))
        rows = r.take(meet)
        blocked[meet] = _roots_block(t_near, t_far, low.take(rows), high.take(rows),
                                     article=False)
        return blocked

    def _leaf_spheres(self):
        """(x, y, z, radii, ids) (L * MAX_LEAF,): the tree's spheres in leaf-slot order (leaf
        i's slots at i * MAX_LEAF ...): centres and radii in the render precision (NaN in a
        padding slot) and global ids (-1: padding).  The pairs of a visit then read short
        stretches of these instead of random elements of scene-long arrays.  Built for the
        frame (``build_frame_tables``) or on first use (about 40 bytes a sphere in float64,
        24 in float32)."""
        rows = self._leaf_rows
        if rows is None:
            with self._lazy_lock:
                rows = self._leaf_rows
                if rows is None:
                    rows = self._leaf_rows = self._leaf_ordered_spheres()
        # (The ids are the tree's leaves themselves: not held, nor pickled, twice.)
        return (*rows, self._tree.leaves.ravel())

    def _leaf_ordered_spheres(self):
        """``_leaf_spheres``' centres and radii, made."""
        ids = self._tree.leaves.ravel()
        pad = ids < 0
        safe = np.where(pad, 0, ids)
        columns = [self._centers_t[k].take(safe) for k in range(3)]
        columns.append(self._radii_t.take(safe))
        for column in columns:
            column[pad] = np.nan
        return tuple(columns)

    def build_frame_tables(self, eye=None, *, bounces: bool = True, trails: bool = True,
                           threads: int = 1) -> None:
        """Build now, on up to ``threads`` threads, the tables a frame's tiles would each
        build on first use (in every worker process, before its first tile: the eye's
        depth-ordered bins of a million spheres took 2 s of each worker's CPU), for a frame
        whose camera rays share the origin ``eye`` (3,) (None: they do not), whose rays may
        leave hit points (``bounces``) and whose occlusion rays may (``trails``: a sun's,
        the world's; ``shading.traces_from_points``).  Only what those rays would use: the
        tree's traversal tables; the eye's bins where a camera batch of the frame gets
        depth-ordered ones (``_depth_bins_pay``: whatever the batch); the occlusion trails'
        tables (``BVH.table_jobs``); the leaf-ordered spheres where rays leaving spheres
        read them (``_spheres_by_slot``).  They are pickled with the aggregate, so workers
        get them in the render's shared arrays (``core.workers``) and build none."""
        tree = self._tree
        if tree is None:
            return
        tree.leaf_crossings     # (which the rules below and the traversal ask for)
        leaf_rows = (self._spheres_by_slot and not self.article and self._leaf_rows is None
                     and (bounces or (trails and not self._textbook)))
        with thread_pool(threads) as pool:
            # (Queued first, so that they run on the pool while this thread starts the bins.)
            made = [run_on(pool, job) for job in tree.table_jobs(trails)]
            rows = run_on(pool, self._leaf_ordered_spheres) if leaf_rows else None
            if eye is not None and self._depth_bins_pay():
                self._bins_at(eye, depth=True, pool=pool)
            for future in made:
                future.result()
            if rows is not None:
                self._leaf_rows = rows.result()

    def _leaf_offsets(self, rays: RayBatch, r, slots, centres, stats):
        """(3, k) each pair's ray origin less its sphere's centre, for pairs (ray ``r``,
        leaf slot ``slots``) (k,) each, the centres (x, y, z) being the leaf-ordered
        spheres' (``_leaf_spheres``); counts the k sphere tests."""
        if stats is not None:
            stats.sphere_tests += len(slots)
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        f = np.empty((3, len(slots)), np.result_type(origins.dtype, self.dtype))
        for k, column in enumerate(centres):
            np.subtract(origins[k], column.take(slots), out=f[k])
        return f

    def _leaf_blocks(self, rays: RayBatch, r, slots, low, high, stats):
        """The rays (k,) of pairs (ray r, leaf slot) (E,) whose sphere blocks them under the
        default rules with the stable roots and no shared terms: ``_sphere_blocks`` on the
        leaf-ordered spheres (the same operations on the same values, so the same flags),
        less the pairs of the sphere each ray excludes (``exclude``)."""
        return self._slot_blocks(rays, r, slots, self._leaf_spheres(), low, high, stats)

    def _slot_blocks(self, rays: RayBatch, r, slots, spheres, low, high, stats):
        """``_leaf_blocks`` of pairs (ray r, slot) (E,) of spheres laid out by slot
        (``spheres``: (x, y, z, radii, ids) as ``_leaf_spheres`` gives them, or the scene's
        own arrays with ids None, the slots being the sphere ids: a parallel bins' entries,
        ``_parallel_spheres``)."""
        x, y, z, radii, ids = spheres
        if rays.exclude is not None:
            # The sphere a ray leaves is excluded: dropped before its roots (its own slot's
            # box holds the ray's origin: 22 % of the pairs in issue 9's fields).
            other = np.flatnonzero((slots if ids is None else ids.take(slots))
                                   != rays.exclude.take(r))
            r, slots = r.take(other), slots.take(other)
        f = self._leaf_offsets(rays, r, slots, (x, y, z), stats)
        radius = radii.take(slots)
        b, disc = offset_discriminants(f, take(rays.directions, r), radius)
        meet = np.flatnonzero(disc > 0)
        t_near, t_far = offset_press_roots(take(f, meet), radius.take(meet), b.take(meet),
                                           disc.take(meet))
        met = r.take(meet)
        blocked = _roots_block(t_near, t_far, low.take(met), high.take(met), article=False)
        return met[blocked]

    def _triangle_pairs(self, rays: RayBatch, shear, r, triangle, t_min, t_max):
        return watertight_pairs(self._corners, triangle,
                                rays.origins.astype(self.dtype, copy=False), shear, r, t_min,
                                t_max)

    def _pairs_by_kind(self, prims, stats):
        """(sphere pairs, triangle pairs): indices into a tree leaf's (ray, primitive) pairs
        prims (E,) by the primitive's kind, each counted in stats; slices (views, no
        gathers) when the tree holds one kind only."""
        if not self._tree_triangles:
            spheres, tris = slice(0, len(prims)), slice(0, 0)
        elif not self._tree_spheres:
            spheres, tris = slice(0, 0), slice(0, len(prims))
        else:
            is_sphere = prims < self.sphere_count
            spheres, tris = np.flatnonzero(is_sphere), np.flatnonzero(~is_sphere)
        if stats is not None:
            stats.sphere_tests += _size(spheres)
            stats.triangle_tests += _size(tris)
        return spheres, tris

    def _nearest_in_tree(self, rays: RayBatch, best_t, best, barycentrics, stats):
        """Improves best_t, best (n,) and the triangle barycentrics in place with the tree's
        primitives."""
        n = len(rays)
        shear = Shear.of(rays.directions) if self.triangle_count else None
        reach = np.minimum(best_t.astype(np.float64), _per_ray(rays.t_max, n))
        t_min = _per_ray(rays.t_min, n, self.dtype)
        exclude = rays.exclude
        last = {}

        def visit(r, prims, reached=None):
            # (reached: (E,) the pairs' rays' reach, when a group of rays keeps its own.)
            t = np.full(len(r), np.inf, self.dtype)
            limit = (reach[r] if reached is None else reached).astype(self.dtype)
            spheres, tris = self._pairs_by_kind(prims, stats)
            if _size(spheres):
                pr = r[spheres]
                roots = self._sphere_pairs(rays, pr, prims[spheres])
                d = first_hit_distance(*roots, t_min[pr], article=self.article)
                t[spheres] = np.where(d < limit[spheres], d, np.inf)
            bary = None
            if _size(tris):
                pr = r[tris]
                tt, b0, b1, b2, valid = self._triangle_pairs(
                    rays, shear, pr, prims[tris] - self.sphere_count, t_min[pr], limit[tris])
                t[tris] = np.where(valid, tt, np.inf)
                bary = (tris, b0, b1, b2)
            if exclude is not None:
                t[prims == exclude[r]] = np.inf
            last.update(prims=prims, bary=bary, t=t)
            return t

        slot_visit = None
        if (exclude is not None and self._spheres_by_slot
                and (rays.shared is None or rays.shared.tree_terms is None)):
            def slot_visit(r, slots, reached=None):
                # visit's sphere pairs by leaf slot, on the leaf-ordered spheres
                # (``_leaf_spheres``: a leaf's spheres side by side, not scattered over
                # the scene's arrays), less the pairs of the sphere each ray excludes,
                # dropped before their roots (rays leaving a sphere's outside: 1 of 1.75
                # sphere tests a reflection ray off issue 9's 1,000 spheres; where no ray
                # excludes anything, the article's rules, visiting by slot costs 1 %
                # more): the same operations on the same values, so the same distances.
                x, y, z, radii, ids = self._leaf_spheres()
                prims = ids.take(slots)
                kept = np.flatnonzero(prims != exclude.take(r))
                r, slots, prims = r.take(kept), slots.take(kept), prims.take(kept)
                reached = None if reached is None else reached.take(kept)
                f = self._leaf_offsets(rays, r, slots, (x, y, z), stats)
                roots = offset_roots(f, take(rays.directions, r), radii.take(slots),
                                     article=self._textbook)
                d = first_hit_distance(*roots, t_min.take(r), article=self.article)
                limit = (reach.take(r) if reached is None else reached).astype(self.dtype)
                t = np.where(d < limit, d, np.inf).astype(self.dtype, copy=False)
                last.update(prims=prims, bary=None, t=t)
                return kept, prims, t

        def accept(owner, pair):
            prims = last["prims"]
            best[owner] = prims[pair]
            best_t[owner] = last["t"][pair]
            if barycentrics is None:
                return
            # A sphere's hit clears what a triangle found before it (0, as before any hit):
            # a ray's barycentrics do not depend on the order its leaves were visited in.
            bary = last["bary"]
            if bary is None:
                for store in barycentrics:
                    store[owner] = 0
                return
            tris, b0, b1, b2 = bary
            slot = np.full(len(prims), -1, np.intp)
            slot[tris] = np.arange(_size(tris))
            chosen = slot[pair]
            won = chosen >= 0
            for store, b in zip(barycentrics, (b0, b1, b2)):
                store[owner[won]] = b[chosen[won]]
                store[owner[~won]] = 0

        bins, plan = self._origin_bins(rays)
        if plan is not None and not bins.by_depth:
            bins.traverse(plan, reach, visit, accept, exclude=exclude)
            return
        rest = None     # the rays the tree answers (None: all of them)
        if plan is not None:
            # Front to back through the cells; the rays still walking after the last round
            # are the tree's, from what they had before (``OriginBins.walk``).
            before = (reach.copy(), best_t.copy(), best.copy(),
                      None if barycentrics is None else tuple(b.copy() for b in barycentrics))
            _, walking = bins.walk(plan, reach, visit, accept, exclude=exclude)
            if len(walking) == 0:
                return
            for store, kept in zip((reach, best_t, best) + (barycentrics or ()),
                                   before[:3] + (before[3] or ())):
                store[walking] = kept.take(walking)
            rest = np.zeros(n, bool)
            rest[walking] = True
        for members, bins, plan, shift in (self._mirror_groups(rays) if rest is None else ()):
            # (Numbered within the group: the kernels' rays mapped back to the batch's.)
            local = reach.take(members)
            bins.traverse(plan, local,
                          lambda r, prims, m=members, local=local: visit(m.take(r), prims,
                                                                         local.take(r)),
                          lambda owner, pair, m=members: accept(m.take(owner), pair),
                          exclude=None if exclude is None else exclude.take(members),
                          reach_shift=shift)
            rest = np.ones(n, bool) if rest is None else rest
            rest[members] = False
        box_t_min = _box_start(rays.t_min)
        if rest is None:
            self._tree.traverse(*self._box_terms(rays), box_t_min, reach, visit, accept,
                                slot_visit=slot_visit, stats=stats)
            return
        rest = np.flatnonzero(rest)
        if len(rest):
            local = reach.take(rest)
            self._tree.traverse(
                *self._box_terms(rays, rest), box_t_min, local,
                lambda r, prims: visit(rest.take(r), prims, local.take(r)),
                lambda owner, pair: accept(rest.take(owner), pair),
                slot_visit=None if slot_visit is None else
                lambda r, slots: slot_visit(rest.take(r), slots, local.take(r)), stats=stats)

    def _occluded_in_tree(self, segments: RayBatch, stats) -> np.ndarray:
        n = len(segments)
        shear = Shear.of(segments.directions) if self.triangle_count else None
        reach = np.array(_per_ray(segments.t_max, n), np.float64)
        low = _per_ray(segments.t_min, n, self.dtype)
        high = _per_ray(segments.t_max, n, self.dtype)
        exclude = segments.exclude

        def visit(r, prims):
            blocked = np.zeros(len(r), bool)
            spheres, tris = self._pairs_by_kind(prims, stats)
            if _size(spheres):
                pr = r[spheres]
                if self.article:
                    t_near, t_far, valid = self._sphere_pairs(segments, pr, prims[spheres])
                    blocked[spheres] = valid & _roots_block(t_near, t_far, low[pr], high[pr],
                                                            article=True)
                else:
                    blocked[spheres] = self._sphere_blocks(segments, pr, prims[spheres], low,
                                                           high)
            if _size(tris):
                pr = r[tris]
                blocked[tris] = self._triangle_pairs(segments, shear, pr,
                                                     prims[tris] - self.sphere_count,
                                                     low[pr], high[pr])[4]
            if exclude is not None:
                blocked &= prims != exclude[r]
            return np.where(blocked, 0.0, np.inf)

        bins, plan = self._origin_bins(segments, depth=False)
        if plan is not None:
            return bins.traverse(plan, reach, visit, any_hit=True, exclude=exclude)
        box_t_min = max(_box_start(segments.t_min), 0.0)
        # Rays leaving a primitive start at its leaf (``BVH._trail``): most blockers are near;
        # a tree of spheres alone is visited by leaf there (``_leaf_blocks``) when its spheres
        # take the offset roots.
        leaf_blocks = None
        if (not self.article and not self._textbook and self._spheres_by_slot
                and (segments.shared is None or segments.shared.tree_terms is None)):
            def leaf_blocks(r, leaf):
                return self._leaf_blocks(segments, r, leaf, low, high, stats)

            parallel = self._parallel_spheres(segments)
            if parallel is not None:
                bins, listed = parallel
                blocked = np.zeros(n, bool)
                r, entries = bins.pairs(segments.origins)
                spheres = (*self._centers_t, self._radii_t, None)
                blocked[self._slot_blocks(segments, r, listed.take(entries), spheres, low, high,
                                          stats)] = True
                return blocked
        return self._tree.traverse(*self._box_terms(segments), box_t_min, reach, visit,
                                   any_hit=True, sources=segments.source,
                                   leaf_blocks=leaf_blocks, stats=stats)

    def _origin_bins(self, rays: RayBatch, depth: bool = True):
        """(bins, plan): the direction bins of the batch's shared origin and the batch's
        plan over them (``core.bins``), or (None, None) where the tree answers instead (no
        shared origin, too few rays to pay for bins, bins that would not pay there, or too
        many candidates for this batch).  Bins are built on first use, once per origin,
        under a lock (tiles run in threads)."""
        if rays.shared is None or self._tree is None:
            return None, None
        depth = depth and self._depth_bins_pay()
        few = self._too_few_for_bins(len(rays))
        if few and not depth:
            return None, None
        bins = self._bins_at(rays.shared.position, depth=depth)
        if bins is None or (few and not bins.by_depth):
            return None, None
        plan = bins.plan(rays.directions)
        return (bins, plan) if plan is not None else (None, None)

    def _bins_at(self, position, mirror: bool = False, depth: bool = False, pool=None):
        """The direction bins around ``position`` (3,) of the tree's boxes (mirror: grown by
        ``mirror_slack``, ``_mirror_groups``), or None where they do not pay or the bins
        held are at their bound; with ``depth``, depth-ordered bins (``OriginBins.walk``)
        where id-ordered ones do not pay.  Built on first use, once per origin, under a
        lock (tiles run in threads); pool: a thread pool to build them on (``OriginBins
        .build``), or None."""
        position = np.asarray(position, np.float64)

        def make():
            bins = None
            if self._bins_bytes < BINS_MAX_BYTES and self._tree_boxes is not None:
                ids, low, high = self._tree_boxes
                if mirror:
                    low, high = low - self.mirror_slack, high + self.mirror_slack
                bins = OriginBins.build(position, ids, low, high, pool=pool)
            if bins is None and depth and self._bins_bytes < self._bins_max_bytes():
                ids, low, high = self._bins_boxes()
                bins = OriginBins.build(position, ids, low, high, by_depth=True,
                                        bounds=self._bounding_spheres(ids),
                                        rounding=float(np.finfo(self.dtype).eps), pool=pool)
            return None if bins is None else (bins, bins.nbytes)

        return self._held_bins(self._bins, (position.tobytes(), mirror, depth), make)

    def _held_bins(self, store, key, make):
        """The bins held in ``store`` under ``key``, made on first use by ``make()``
        ((bins, bytes), or None where there are none), once, under a lock (tiles run in
        threads)."""
        held = store.get(key, False)
        if held is False:
            with self._lazy_lock:
                held = store.get(key, False)
                if held is False:
                    made = make()
                    held = store[key] = None if made is None else made[0]
                    self._bins_bytes += 0 if made is None else made[1]
        return held

    def _parallel_spheres(self, segments: RayBatch):
        """(bins, listed): the parallel bins (``core.bins.ParallelBins``) of segments that
        all leave along one direction unbounded from t_min >= 0 (a sun's shadow rays), with
        the sphere (global id) of each entry; or None where the tree answers (other
        segments, a frame of too few rays per tree sphere, PARALLEL_RAYS_PER_PRIMITIVE, bins
        that would not pay or not fit).  Built on first use, once per direction.  For a tree
        of spheres alone (``_occluded_in_tree``'s leaf visits by slot)."""
        d = segments.directions
        if (self.rays_per_origin < PARALLEL_RAYS_PER_PRIMITIVE * self._tree_size()
                or len(segments) == 0 or not np.isposinf(segments.t_max).all()
                or np.min(segments.t_min) < 0 or not (d == d[:, :1]).all()):
            return None

        def make():
            if self._bins_bytes >= self._bins_max_bytes():
                return None
            ids = self._tree.primitives()
            # The tree's own padding of its boxes, which covers the kernels' rounding (twice,
            # and the projections' own).
            pad = 2 * SLAB_PADDING_32 * self._tree.origin_reach
            bins = ParallelBins.build(d[:, 0], self.spheres.centers[ids].T,
                                      self.spheres.radii[ids], pad)
            if bins is None:
                return None
            # (Each entry's sphere id: its centre is read from the scene's arrays, as fast
            # as from copies in entry order.)
            listed = ids.take(bins.entries)
            return (bins, listed), bins.nbytes + listed.nbytes

        return self._held_bins(self._parallel, d[:, 0].astype(np.float64).tobytes(), make)

    def _tree_size(self) -> int:
        return self._tree_spheres + self._tree_triangles

    def _depth_bins_pay(self) -> bool:
        """Whether an origin whose id-ordered bins do not pay gets depth-ordered ones
        (DEPTH_RAYS_PER_PRIMITIVE, DEPTH_BINS_CROSSINGS)."""
        return (self._tree is not None
                and self.rays_per_origin >= DEPTH_RAYS_PER_PRIMITIVE * self._tree_size()
                and self._tree.leaf_crossings >= DEPTH_BINS_CROSSINGS)

    def _bins_max_bytes(self) -> int:
        return BINS_MAX_BYTES + BINS_BYTES_PER_PRIMITIVE * self._tree_size()

    def _bins_boxes(self):
        """(ids (P,), low, high (P, 3) float64) of the tree's primitives, for bins: the ones
        kept (``_tree_boxes``), or made again from the scene's arrays (trees of more than
        BINS_MAX_PRIMITIVES keep none)."""
        if self._tree_boxes is not None:
            return self._tree_boxes
        lows, highs, ids = [], [], []
        if self._tree_spheres:
            spheres = np.ones(self.sphere_count, bool)
            if self._flat_ids is not None:
                spheres[self._flat_ids] = False
            spheres = np.flatnonzero(spheres)
            c, r = self.spheres.centers[spheres], self.spheres.radii[spheres, None]
            lows.append(c - r)
            highs.append(c + r)
            ids.append(spheres)
        if self._tree_triangles:
            t = self.triangles
            lows.append(np.minimum(np.minimum(t.v0, t.v1), t.v2).T)
            highs.append(np.maximum(np.maximum(t.v0, t.v1), t.v2).T)
            ids.append(np.arange(self.triangle_count) + self.sphere_count)
        return np.concatenate(ids), np.concatenate(lows), np.concatenate(highs)

    def _bounding_spheres(self, ids):
        """(centres (k, 3), radii (k,)) float64 bounding spheres of primitives ``ids`` (k,)
        ascending, spheres before triangles (``_bins_boxes``' order): the spheres
        themselves, the triangles' (``_tri_centers``, ``_tri_radii``)."""
        spheres = ids[:np.searchsorted(ids, self.sphere_count)]
        triangles = ids[len(spheres):] - self.sphere_count
        centres = np.concatenate([self.spheres.centers[spheres],
                                  self._tri_centers.T[triangles] if len(triangles)
                                  else np.zeros((0, 3))])
        radii = np.concatenate([self.spheres.radii[spheres],
                                self._tri_radii[triangles] if len(triangles) else []])
        return centres, radii

    def _mirror_groups(self, rays: RayBatch):
        """[(members (k,), bins, plan, reach shift (k,))]: groups of the batch's rays whose
        lines pass within ``mirror_slack`` (per axis) of one point q behind their origins,
        enough of them to pay for bins (``BINS_PRIMITIVES_PER_RAY``), and the direction bins
        around q of the tree's boxes grown by that much.

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
        if (eye is None or rays.source is None or self._tree_boxes is None
                or not self.mirror_slack > 0):
            return []
        need = len(self._tree_boxes[0]) * BINS_PRIMITIVES_PER_RAY
        if len(rays) < need:
            return []
        grid = self.mirror_slack / 4
        images = self._mirror_images(np.asarray(eye, np.float64), rays.source, grid, need)
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
            bins = self._bins_at(point, mirror=True)
            plan = None if bins is None else bins.plan(take(rays.directions, members))
            if plan is not None:
                groups.append((members, bins, plan, -tau.take(near)))
        return groups

    def _mirror_images(self, eye, source, grid, need):
        """(image (n,) index into points or -1, points (G, 3)): the mirror image of ``eye``
        (3,) in the tangent plane of each ray's source primitive (``source`` (n,), -1:
        none) nearest to it (a sphere's) or in its plane (a triangle's), rounded to
        multiples of ``grid``; None when no ray has a source.  Only for the spheres that
        ``need`` rays or more leave (no two spheres share an image) and every triangle
        (the triangles of a plane do); -1 for the rest."""
        counts = np.bincount(source + 1)[1:]
        ids = np.arange(len(counts))
        prims = np.flatnonzero((counts >= need) | ((ids >= self.sphere_count) & (counts > 0)))
        if len(prims) == 0:
            return None
        normal = np.empty((len(prims), 3))
        plane = np.empty(len(prims))        # the image is eye - 2 plane * normal
        spheres = prims < self.sphere_count
        # (An eye at a sphere's centre has no image: NaN, dropped below.)
        with np.errstate(invalid="ignore", divide="ignore"):
            if spheres.any():
                k = prims[spheres]
                away = eye - self.spheres.centers[k]
                size = np.sqrt((away * away).sum(axis=1))
                normal[spheres] = away / size[:, None]
                plane[spheres] = size - self.spheres.radii[k]
            if not spheres.all():
                k = prims[~spheres] - self.sphere_count
                n = self.triangles.normals[:, k].T
                normal[~spheres] = n
                plane[~spheres] = ((eye - self.triangles.v0[:, k].T) * n).sum(axis=1)
            images = np.round((eye - 2 * plane[:, None] * normal) / grid)
        points, which = np.unique(images, axis=0, return_inverse=True)
        which = which.ravel()   # (numpy 2.x keeps the axis's shape)
        # Per primitive id (and -1 for none, the last entry): its image or -1.
        image = np.full(len(counts) + 1, -1, np.intp)
        image[prims] = np.where(np.isfinite(points).all(axis=1)[which], which, -1)
        return image.take(source), points * grid

    # ---- occlusion ----------------------------------------------------------------------

    @timed("seconds_shadows")
    def occluded(self, segments: RayBatch, stats: RayStats) -> np.ndarray:
        """(n,) whether a primitive other than ``segments.exclude`` is crossed within
        (t_min, t_max) of each segment.  Article rules: a sphere blocks when its far root
        lies there (the article tests the reversed ray, from the shaded point)."""
        n = len(segments)
        blocked = np.zeros(n, bool)
        if n == 0:
            return blocked
        stats.shadow_rays += n
        if self._flat_count:
            blocked |= self._sphere_occlusion(segments, stats)
        for occlusion in (self._occluded_in_tree if self._tree_answers(segments) else None,
                          self._triangle_occlusion if self._flat_answers(segments) else None):
            if occlusion is None or blocked.all():
                continue
            open_ = np.flatnonzero(~blocked)
            rest = segments if len(open_) == n else _subset(segments, open_)
            blocked[open_] |= occlusion(rest, stats)
        return blocked

    def _triangle_occlusion(self, segments: RayBatch, stats):
        blocked = np.zeros(len(segments), bool)
        for triangles, group, t, b0, b1, b2, valid in self._triangle_blocks(
                segments, segments.t_max, stats):
            blocked[group] |= valid.any(axis=0)
        return blocked

    def _sphere_occlusion(self, segments: RayBatch, stats):
        n = len(segments)
        blocked = np.zeros(n, bool)
        shared = segments.shared
        terms = shared.sphere_terms if shared is not None else None
        key = self._flat_key(segments)
        t_min, t_max, exclude = segments.t_min, segments.t_max, segments.exclude
        ids = self._flat_ids
        candidates = self._bundle_candidates(segments)
        if len(candidates) <= DENSE_CANDIDATES:
            if len(candidates):
                stats.sphere_tests += n * len(candidates)
                self._few(segments, terms).blocked(candidates, t_min, t_max, exclude, ids,
                                                   blocked)
            return blocked
        for block in candidate_roots(self._flat_centers, self._flat_radii, self._clusters,
                                     segments.origins, segments.directions, t_max, terms,
                                     textbook=self._textbook, stats=stats, key=key,
                                     candidates=candidates):
            t_near, t_far, valid = block.t_near, block.t_far, block.valid
            low, high = block.per_pair(t_min), block.per_pair(t_max)
            hit = valid & _roots_block(t_near, t_far, low, high, self.article)
            if not self.article and exclude is not None:
                spheres = block.spheres if ids is None else ids[block.spheres]
                hit &= spheres != block.per_pair(exclude)
            blocked[block.rays] |= block.any(hit)
        return blocked

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
        their geometric ``normals`` (3, m) (front / outside) where ``leave_front`` (m,).

        Default rules: the origin moves off the surface by ``ray_offsets`` (scaled to the
        point's magnitude) along the geometric normal, on the side the ray leaves, and the
        ray ignores its own primitive where it cannot hit it again (``exclusions``).
        Article rules: the article's fixed offset along the sphere's outward normal (for a
        triangle, on the side the ray leaves), no exclusion.  arrived_from: (3,) the point
        the rays that arrived at the points all left, or None (``RayBatch.arrived_from``)."""
        if not self.mirror_slack > 0:
            arrived_from = None     # (no bins for mirror images: nothing to carry)
        everywhere = bool(leave_front.all())
        side = None if everywhere else np.where(leave_front, 1, -1).astype(self.dtype)
        if self.article:
            if self.triangle_count and side is not None:
                side = np.where(primitive >= self.sphere_count, side, 1).astype(self.dtype)
                return RayBatch(points + ARTICLE_OFFSET * (normals * side), directions,
                                source=primitive, arrived_from=arrived_from)
            origins = ARTICLE_OFFSET * normals
            origins += points
            return RayBatch(origins, directions, source=primitive, arrived_from=arrived_from)
        # (Multiplying by a side of 1 everywhere would change nothing: skipped.)
        origins = points + ray_offsets(points) * (normals if side is None else normals * side)
        return RayBatch(origins, directions, exclude=self.exclusions(primitive, leave_front),
                        source=primitive, arrived_from=arrived_from)


def _size(index) -> int:
    """How many pairs an index array or a slice (``Aggregate._pairs_by_kind``) picks."""
    return index.stop - index.start if isinstance(index, slice) else len(index)


def _box_start(t_min) -> float:
    """Where the tree's box tests start along a batch's rays: the least of their t_min.  A
    scalar keeps a per-pair gather out of every box test; the rays' own t_min
    (offsets off surfaces, at most a shadow segment's start) still bounds their primitive
    tests, so the hits are the same and a box is at worst entered a little early."""
    return float(np.min(t_min)) if np.size(t_min) else 0.0


def _subset(rays: RayBatch, keep) -> RayBatch:
    """The rays ``keep`` (k,) of a batch."""
    def pick(values):
        return values[keep] if np.ndim(values) else values

    origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, keep)
    return RayBatch(origins, take(rays.directions, keep), pick(rays.t_min), pick(rays.t_max),
                    rays.shared,
                    None if rays.exclude is None else rays.exclude[keep],
                    None if rays.source is None else rays.source[keep], rays.arrived_from)


def builds_tree(spheres: int, triangles: int, saved_tests: float = 0.0) -> bool:
    """Whether a scene of this many spheres and triangles gets a tree (``Aggregate``), a
    tree of its few triangles saving a ray ``saved_tests`` tests (``small_mesh_saved_tests``;
    0: counts alone, which is what the worker-process rule weighs a scene by: a tree that
    only a few compact triangles get does not make a scene heavy)."""
    return (spheres > BVH_MIN_SPHERES or triangles > BVH_MIN_TRIANGLES
            or (triangles > 0 and saved_tests >= TREE_SAVED_TESTS))


def small_mesh_saved_tests(v0, v1, v2) -> float:
    """The triangle tests (of T) a tree saves a ray over testing every triangle, for
    triangles with corners v0, v1, v2 (3, T) and at most BVH_MIN_TRIANGLES of them (0
    past that: the count decides): T less the tests a ray crossing their bounds would make
    in a tree, estimated as the SAH does, by the sum of the triangles' boxes' surface areas
    over their bounds'.  A floor or a wall spans the bounds, so every ray meets it either
    way; a cube's faces are small boxes."""
    count = v0.shape[1]
    if count == 0 or count > BVH_MIN_TRIANGLES:
        return 0.0

    def area(low, high):
        size = np.maximum(high - low, 0)
        return 2 * (size[0] * size[1] + size[1] * size[2] + size[2] * size[0])

    low = np.minimum(np.minimum(v0, v1), v2)
    high = np.maximum(np.maximum(v0, v1), v2)
    bounds = area(low.min(axis=1), high.max(axis=1))
    if not bounds > 0:
        return 0.0
    return float(count - area(low, high).sum() / bounds)


def _partition(sizes: np.ndarray, flat_limit: int):
    """(flat (f,), tree (k,)) primitive indices: all flat while there are at most
    ``flat_limit``; otherwise the huge ones (bounding size above HUGE_RATIO times the
    median, the MAX_HUGE largest at most) flat and the rest in the tree."""
    count = len(sizes)
    everything = np.arange(count)
    if count <= flat_limit:
        return everything, np.zeros(0, np.intp)
    if sizes.max() <= HUGE_RATIO * sizes.min():     # (none above HUGE_RATIO times the least)
        return np.zeros(0, np.intp), everything
    huge = np.flatnonzero(sizes > HUGE_RATIO * np.median(sizes))
    if len(huge) > MAX_HUGE:
        huge = np.sort(huge[np.argsort(sizes[huge])[-MAX_HUGE:]])
    tree = np.ones(count, bool)
    tree[huge] = False
    return huge, everything[tree]
