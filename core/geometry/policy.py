"""Every threshold by which the geometry chooses a strategy, in one frozen object.

An ``Aggregate`` is built with a ``GeometryPolicy`` (``DEFAULT_POLICY`` unless told
otherwise) and hands it to what it builds (the tree, the bins, the flat culling), so a
caller that wants another strategy (a test forcing the tree, a benchmark trying a limit)
builds a policy with ``dataclasses.replace`` instead of changing module constants.  Each
default names the measurement behind it; the figures are in the commit history and
docs/scale-log.md.  Constants that are layout or numerics rather than choices (a node's
width, box padding, bit packing) stay in their modules.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GeometryPolicy:
    # ---- which primitives get a tree ----------------------------------------------------
    #: Scenes of at most this many spheres cull them flat, with no tree
    #: (``python -m bench --only cost-spheres``: the tree against flat culling).
    tree_min_spheres: int = 24
    #: Meshes of at most this many triangles in all are tested flat, with no tree, ...
    tree_min_triangles: int = 16
    #: ... unless a tree saves a ray this many of their triangle tests
    #: (``Triangles.saved_tests``; tests/test_core_bvh.py's cube over a floor and room).
    tree_saved_tests: float = 8.0
    #: A sphere whose radius exceeds this multiple of the median stays out of the tree and
    #: gets a culling cluster of its own (the article's floor would make every box that
    #: size); at most ``max_huge`` of them.
    huge_ratio: float = 8.0
    max_huge: int = 64
    #: Up to this many huge spheres beside a tree, every ray tests each of them without a
    #: bundle's cone (``bench.scenes.random_spheres_scene``: the floor under 1,000 spheres).
    unculled_beside_tree: int = 2
    #: Shared-origin terms for the tree's spheres only up to this many spheres (memory: about
    #: 40 bytes a sphere for every light sample).
    shared_terms_limit: int = 100_000

    # ---- flat culling -------------------------------------------------------------------
    #: With at most this many candidates for a whole batch, one dense pass beats per-packet
    #: culling (``bench --only cost-spheres``, small counts).
    dense_candidates: int = 8

    # ---- direction bins -----------------------------------------------------------------
    #: Origins get id-ordered bins only while the tree holds at most this many primitives,
    #: and an aggregate's bins hold about ``bins_max_bytes``, plus, for depth-ordered bins,
    #: ``bins_bytes_per_primitive`` a tree primitive (``bench --only cost-sphere-sets``).
    bins_max_primitives: int = 100_000
    bins_max_bytes: int = 64 * 1024 ** 2
    bins_bytes_per_primitive: int = 64
    #: A batch goes to bins only with at least one ray per this many tree primitives
    #: (listing an origin costs about as much a primitive as tracing a ray).
    bins_primitives_per_ray: int = 1
    #: Depth-ordered bins for an origin where a frame traces at least this many rays from
    #: it per tree primitive and a line through the root crosses at least
    #: ``depth_bins_crossings`` leaves (``bench --only scale-points,scale-instances``).
    depth_rays_per_primitive: float = 1.0
    depth_bins_crossings: float = 16.0
    #: A sun's shadow rays through parallel bins where a frame traces at least this many
    #: rays from one origin per tree sphere (``bench --only scale-instances``).
    parallel_rays_per_primitive: float = 1.0
    #: Reflections whose lines pass this close to one point (a fraction of the tree's median
    #: box half side) are answered by bins around it (``bench --only spheres``).
    mirror_slack: float = 0.125
    #: An origin's id-ordered bins hold at most this many entries, with at most
    #: ``max_mean_candidates`` a cell on average; a batch averaging more than
    #: ``max_pairs_per_ray`` candidates a ray goes to the tree (``bench --only spheres``).
    max_entries: int = 1 << 21
    max_mean_candidates: float = 16.0
    max_pairs_per_ray: float = 16.0
    #: Depth-ordered bins: at most this many entries, and per primitive
    #: (``bench --only scale-points``).
    max_depth_entries: int = 1 << 23
    max_depth_entries_per_primitive: int = 8
    #: How many of its cell's entries a ray of depth-ordered bins meets in each round; a ray
    #: still walking after them goes to the tree.
    walk_rounds: tuple = (1, 1, 2, 2, 4, 4, 8, 8)
    #: Boxes whose bins entries are made in one job (bounds the build's temporaries).
    bins_chunk: int = 1 << 17
    #: Parallel bins' cells, in diameters of the median sphere, and the most entries a sphere
    #: (``bench --only scale-instances``: the sun's rays).
    parallel_cell_diameters: float = 0.7
    parallel_max_entries_per_primitive: int = 16

    # ---- the tree's build ---------------------------------------------------------------
    #: A triangle whose box's half area exceeds ``split_ratio`` times its area and the
    #: median triangle's (a long thin one: a box far larger than the triangle, which most
    #: rays through it miss) goes into the tree as fragments with tighter boxes, at most
    #: ``split_levels`` cuts deep and ``split_budget`` x the tree's triangles in extra
    #: fragments (``Triangles.fragments``; ``python -m bench.rays`` on clevr_Rubber's
    #: backdrop of slivers).
    split_ratio: float = 8.0
    split_levels: int = 6
    split_budget: float = 1.0
    #: Trees of this many primitives or more are built over Morton clusters
    #: (``bench --only scale-points``: the build's time).
    cluster_from: int = 50_000
    #: Builds of this many boxes or more asked for threads run in parts on a pool
    #: (``bench --only scale-points,scale-instances``: the context's time).
    parallel_from: int = 50_000

    # ---- the tree's traversal -----------------------------------------------------------
    #: Nearest hits are found front to back in trees of at least this many leaves, and
    #: sorted down to the widest depth where a line through the root crosses at least
    #: ``deep_sort_crossings`` leaves (``bench --only cost-sphere-sets``).
    sorted_from: int = 2048
    deep_sort_crossings: float = 32.0
    #: Rays descend the tree unsorted, level by level, unless a line through its root
    #: crosses at least this many leaves: rays sharing an origin (the eye, a light sample)
    #: ``coherent_sort_crossings`` (a mesh's surfaces cross about 2, a field of spheres 5 or
    #: more), rays that share none (bounces, shadow rays from points)
    #: ``incoherent_sort_crossings`` (a dense field) (``python -m bench.rays``:
    #: clevr_Rubber's camera rays 1.9x and bounces 2.2x faster unsorted, the 10^4-sphere
    #: set's camera rays 1.4x and the 10^5-sphere set's bounces 6x slower).
    coherent_sort_crossings: float = 4.0
    incoherent_sort_crossings: float = 32.0
    #: Climbing steps an occlusion trail takes before it meets its home node's children
    #: (``bench --only cost-sphere-sets``: the 10^5 and 10^6 fields' shadow rays).
    home_after: int = 4

    def builds_tree(self, spheres: int, triangles: int, saved_tests: float = 0.0) -> bool:
        """Whether a scene of this many spheres and triangles gets a tree, a tree of its few
        triangles saving a ray ``saved_tests`` tests (``Triangles.saved_tests``; 0: counts
        alone, which is what the worker-process rule weighs a scene by)."""
        return (spheres > self.tree_min_spheres or triangles > self.tree_min_triangles
                or (triangles > 0 and saved_tests >= self.tree_saved_tests))

    def split_spheres(self, radii: np.ndarray):
        """(flat (f,), tree (k,)) sphere indices: all flat while there are at most
        ``tree_min_spheres``; otherwise the huge ones (``is_huge``, the ``max_huge``
        largest at most) flat and the rest in the tree."""
        count = len(radii)
        everything = np.arange(count)
        if count <= self.tree_min_spheres:
            return everything, np.zeros(0, np.intp)
        if radii.max() <= self.huge_ratio * radii.min():    # (none can be huge)
            return np.zeros(0, np.intp), everything
        huge = np.flatnonzero(self.is_huge(radii))
        if len(huge) > self.max_huge:
            huge = np.sort(huge[np.argsort(radii[huge])[-self.max_huge:]])
        tree = np.ones(count, bool)
        tree[huge] = False
        return huge, everything[tree]

    def is_huge(self, radii: np.ndarray) -> np.ndarray:
        """(N,) whether each sphere is much larger than the median (a floor)."""
        if len(radii) == 0:
            return np.zeros(0, bool)
        return radii > self.huge_ratio * np.median(radii)


DEFAULT_POLICY = GeometryPolicy()
