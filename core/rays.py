"""What the tracer hands the geometry and gets back: ray batches, hits, and ray statistics.

The bounce loop (``core.trace``) and the shading (``core.shading``) talk to the scene's
geometry only through these types and ``core.geometry.Aggregate``'s ``nearest``,
``occluded`` and ``spawn``; how the geometry finds hits (culling, packets, a BVH) stays
behind that interface, as in pbrt's ``Primitive``/``Aggregate``.

Vectors are (3, n) bundles (``core.vectors``).
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

#: The article's fixed shadow/reflection offset along the normal.
ARTICLE_OFFSET = 1e-5
#: Default semantics offset: (1 + max|P_i|) * RAY_EPSILON, Mitsuba 3's scaled ray epsilon
#: (1500 eps of the precision), so offsets grow with the hit point's magnitude.
RAY_EPSILON = {np.dtype(np.float64): 1500 * np.finfo(np.float64).eps,
               np.dtype(np.float32): 1500 * np.finfo(np.float32).eps}


def ray_offsets(points: np.ndarray) -> np.ndarray:
    """(m,) how far rays leaving points (3, m) start from them, or shadow segments stop short
    of them, in default semantics: (1 + max|P_i|) * RAY_EPSILON of the points' precision."""
    dtype = points.dtype
    size = np.abs(points)
    largest = np.maximum(size[0], size[1], out=size[0])   # (row-wise: a strided max(axis=0)
    np.maximum(largest, size[2], out=largest)              # costs several times more)
    largest += 1
    largest *= dtype.type(RAY_EPSILON[dtype])
    return largest


@dataclass
class RayStats:
    """What a render traced.  camera_rays: rays from the camera (every sample);
    shadow_rays: light visibility rays; reflection_rays: mirror rays; sphere_tests: ray/sphere
    pairs intersected (after culling); triangle_tests: ray/triangle pairs intersected;
    node_tests: ray/BVH-node box tests; tiles: tiles rendered; supersampled_pixels: pixels
    given more than one sample.

    seconds_*: per-phase timers (``time.perf_counter`` at a few calls per bundle of rays,
    cheap enough to stay on), summed over tiles and so over threads or workers: tiles
    (``render_tile``), camera (camera rays), bounces (``trace_bundle``), nearest
    (``Aggregate.nearest``), shading (``shade``, its shadow rays included) and shadows
    (``Aggregate.occluded``).  ``phases()`` splits them.  They are not compared: two renders
    of the same image have equal stats whatever their timings."""

    camera_rays: int = 0
    shadow_rays: int = 0
    reflection_rays: int = 0
    sphere_tests: int = 0
    triangle_tests: int = 0
    node_tests: int = 0
    tiles: int = 0
    supersampled_pixels: int = 0
    seconds_tiles: float = field(default=0.0, compare=False)
    seconds_camera: float = field(default=0.0, compare=False)
    seconds_bounces: float = field(default=0.0, compare=False)
    seconds_nearest: float = field(default=0.0, compare=False)
    seconds_shading: float = field(default=0.0, compare=False)
    seconds_shadows: float = field(default=0.0, compare=False)

    def add(self, other: "RayStats") -> None:
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def phases(self) -> dict:
        """Seconds per phase, which add up to ``seconds_tiles``: camera rays, nearest hits,
        shadow rays, the rest of shading, the rest of the bounce loop (hit points, normals,
        compaction, reflection rays) and tile overhead (pixel grids, anti-aliasing,
        assembly)."""
        return {
            "camera rays": self.seconds_camera,
            "nearest hits": self.seconds_nearest,
            "shadow rays": self.seconds_shadows,
            "shading": self.seconds_shading - self.seconds_shadows,
            "rest of bounces": self.seconds_bounces - self.seconds_nearest - self.seconds_shading,
            "tile overhead": self.seconds_tiles - self.seconds_camera - self.seconds_bounces,
        }


def timed(counter: str):
    """Decorator: add the call's wall time to ``stats.<counter>``, stats being the call's
    last positional argument (a RayStats; keyword arguments may follow it)."""
    def decorate(function):
        @functools.wraps(function)
        def timed_call(*args, **keywords):
            start = time.perf_counter()
            try:
                return function(*args, **keywords)
            finally:
                stats = args[-1]
                setattr(stats, counter, getattr(stats, counter) + time.perf_counter() - start)
        return timed_call
    return decorate


@dataclass(frozen=True)
class SharedOrigin:
    """Per-primitive terms for rays that all leave ``position`` (3,) (float64): the camera's
    eye, a light sample.  Made by ``Aggregate.shared_origin``; opaque to the tracer."""

    position: np.ndarray
    sphere_terms: object = None      # core.geometry.spheres.OriginTerms of the flat-culled spheres
    tree_terms: object = None        # OriginTerms of every sphere, for the tree's, or None


@dataclass
class RayBatch:
    """n rays, or n segments for ``Aggregate.occluded`` (a segment is a ray with a finite
    t_max).

    origins: (3, n), or (3, 1) when every ray starts at ``shared.position``;
    directions: (3, n) unit vectors in the render precision;
    t_min, t_max: scalars or (n,): hits count for t_min < t < t_max;
    shared: SharedOrigin when the rays share their origin (camera rays of a perspective
        camera, shadow segments traced from a light sample), else None;
    exclude: (n,) primitive each ray ignores (-1: none), or None (the primitive a ray leaves,
        when it cannot hit it again: ``Aggregate.spawn`` fills it in);
    source: (n,) primitive each ray leaves (-1: none), or None: rays leaving one primitive
        in similar directions are traced together;
    arrived_from: (3,) the point the rays that arrived where these leave all left (a
        perspective camera's eye), or None: reflections off flat or large surfaces then pass
        near its mirror image (``DirectionBins._mirror_groups``).
    """

    origins: np.ndarray
    directions: np.ndarray
    t_min: np.ndarray | float = 0.0
    t_max: np.ndarray | float = np.inf
    shared: SharedOrigin | None = None
    exclude: np.ndarray | None = None
    source: np.ndarray | None = None
    arrived_from: np.ndarray | None = None

    def __len__(self) -> int:
        return self.directions.shape[1]


@dataclass
class Hits:
    """The nearest hits of the rays of a batch that hit something: m of its n rays.

    rays: (m,) index of each hit's ray in the batch; primitive_per_ray: (n,) primitive hit by
    each ray of the batch, -1 where it missed.  t: (m,) distance; primitive, material: (m,)
    global primitive id and material id; points: (3, m); directions: (3, m) the rays'
    directions; normals: (3, m) unit geometric normals, on the outside (spheres) or the front
    (triangles: counter-clockwise winding); shading: (3, m) unit shading normals on the same
    side (interpolated corner normals; for spheres and flat triangles the geometric normal);
    cos_in: (m,) directions . shading normals; front: (m,) whether the ray arrived from the
    outside / front side (directions . geometric normals < 0); terminator: where the hits'
    shadow rays leave (``core.terminator.TerminatorLift``, normals on the side the ray
    arrived from), or None when no hit is on a smooth triangle with a geometry offset;
    barycentrics: (b0, b1, b2) (m,) each, the triangle hits' weights of their corners (0
    for sphere hits), or None when no hit is on a triangle.
    """

    rays: np.ndarray
    primitive_per_ray: np.ndarray
    t: np.ndarray
    primitive: np.ndarray
    material: np.ndarray
    points: np.ndarray
    directions: np.ndarray
    normals: np.ndarray
    shading: np.ndarray
    cos_in: np.ndarray
    front: np.ndarray
    terminator: object = None
    barycentrics: tuple | None = None

    def __len__(self) -> int:
        return len(self.rays)
