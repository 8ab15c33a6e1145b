"""Everything a render precomputes once and every tile reads: arrays in the render's precision,
per-origin sphere terms for the camera and the lights, and the bounds that let paths stop early.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import SceneArrays, scene_arrays
from .bsdf import SurfaceArrays, surface_arrays
from .camera import eye_position
from .cull import SphereClusters, cluster_spheres
from .intersect import OriginTerms
from .lights import PreparedLight, fibonacci_sphere, prepare_light
from .scene import BlenderCamera, PointLight, RenderSettings, Scene

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
    return (1 + np.abs(points).max(axis=0)) * dtype.type(RAY_EPSILON[dtype])


@dataclass
class RayStats:
    """What a render traced.  camera_rays: rays from the camera (every sample);
    shadow_rays: light visibility rays; reflection_rays: mirror rays; sphere_tests: ray/sphere
    pairs intersected (after culling); tiles: tiles rendered; supersampled_pixels: pixels given
    more than one sample."""

    camera_rays: int = 0
    shadow_rays: int = 0
    reflection_rays: int = 0
    sphere_tests: int = 0
    tiles: int = 0
    supersampled_pixels: int = 0

    def add(self, other: "RayStats") -> None:
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name) + getattr(other, name))


@dataclass(frozen=True)
class Materials:
    """Per-sphere material arrays in the render precision: ambient, diffuse, specular as
    (3, N) (one row per channel, ready for ``vectors.take``), exponent and reflection (N,)."""

    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    reflection: np.ndarray


@dataclass(frozen=True)
class LookContext:
    """What the default semantics' Blender look needs (``core.bsdf``, ``core.lights``):
    per-sphere lobes, Blender's lights prepared for sampling, and whether anything in the
    scene is physically based (else the article's model runs alone, unchanged)."""

    surfaces: SurfaceArrays
    lights: tuple[PreparedLight, ...]
    active: bool


@dataclass(frozen=True)
class TraceContext:
    arrays: SceneArrays
    settings: RenderSettings
    dtype: np.dtype
    article: bool
    eye: np.ndarray                      # (3,) camera position, float64
    camera_terms: OriginTerms | None     # shared-origin terms at the eye (perspective only)
    light_terms: tuple                   # OriginTerms per light sample position
    light_samples: tuple                 # per light: (samples, 3) float64 positions
    materials: Materials
    centers_t: np.ndarray                # (3, N) centres in the render precision
    clusters: SphereClusters             # the spheres grouped for culling
    path_gain_bound: float               # max colour one bounce can add per unit weight
    spheres_can_reflect: bool
    look: LookContext | None = None      # default semantics only

    @property
    def centers(self):
        return self.arrays.spheres.centers

    @property
    def radii(self):
        return self.arrays.spheres.radii


def make_context(scene: Scene, settings: RenderSettings, dtype) -> TraceContext:
    arrays = scene_arrays(scene)
    spheres, lights = arrays.spheres, arrays.lights
    article = settings.semantics == "article"
    eye = eye_position(scene.camera)
    perspective = not (isinstance(scene.camera, BlenderCamera) and scene.camera.projection == "ORTHO")
    camera_terms = OriginTerms.at(eye, spheres.centers, spheres.radii) if perspective else None
    samples = []
    for position, radius in zip(lights.positions, lights.radii):
        if radius > 0 and not article:
            samples.append(position + radius * fibonacci_sphere(settings.light_samples))
        else:
            samples.append(position[None, :])
    light_terms = tuple(tuple(OriginTerms.at(p, spheres.centers, spheres.radii) for p in s)
                        for s in samples)
    total_light = (lights.ambient.sum(axis=0) + lights.diffuse.sum(axis=0)
                   + lights.specular.sum(axis=0) + arrays.ambient)
    if len(spheres):
        per_sphere = (spheres.ambient + spheres.diffuse + spheres.specular) * total_light
        gain = float(max(per_sphere.max(), arrays.background.max()))
    else:
        gain = float(arrays.background.max())
    look = None
    if not article:
        surfaces = surface_arrays([s.material for s in scene.spheres], dtype)
        blender_lights = tuple(prepare_light(light, settings.light_samples, spheres.centers,
                                             spheres.radii)
                               for light in scene.lights if not isinstance(light, PointLight))
        look = LookContext(surfaces, blender_lights,
                           active=bool(blender_lights) or surfaces.any_physical)
        if look.active:
            # Blender's lights have no bound on what a bounce adds (watts, not the article's
            # unit intensities): paths then stop only where their weight is zero.
            gain = np.inf
    cast = lambda a: np.ascontiguousarray(a, dtype)  # noqa: E731
    return TraceContext(
        arrays=arrays, settings=settings, dtype=np.dtype(dtype), article=article, eye=eye,
        camera_terms=camera_terms, light_terms=light_terms, light_samples=tuple(samples),
        materials=Materials(cast(spheres.ambient.T), cast(spheres.diffuse.T),
                            cast(spheres.specular.T), cast(spheres.exponent),
                            cast(spheres.reflection)),
        centers_t=cast(spheres.centers.T),
        clusters=cluster_spheres(spheres.centers, spheres.radii),
        path_gain_bound=gain,
        spheres_can_reflect=bool(len(spheres) and spheres.reflection.max() > 0),
        look=look,
    )
