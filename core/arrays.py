"""The scene as structure-of-arrays, the form the tracer works on.

Built once per render from a validated ``Scene``; every array is float64 (the render casts
what it needs to its precision).  N spheres, L lights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import PointLight, Scene


@dataclass(frozen=True)
class SphereArrays:
    """centers (N, 3), radii (N,), ambient / diffuse / specular (N, 3) reflectances,
    exponent (N,) = shininess / 4 (the article's Blinn-Phong exponent), reflection (N,)."""

    centers: np.ndarray
    radii: np.ndarray
    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    reflection: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class LightArrays:
    """positions (L, 3), ambient / diffuse / specular (L, 3) intensities, radii (L,)."""

    positions: np.ndarray
    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    radii: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class SceneArrays:
    spheres: SphereArrays
    lights: LightArrays
    background: np.ndarray   # (3,)
    ambient: np.ndarray      # (3,) scene ambient intensity (default semantics)


def _rows(values, width: int) -> np.ndarray:
    return np.asarray(values, np.float64).reshape(-1, width)


def scene_arrays(scene: Scene) -> SceneArrays:
    spheres = scene.spheres
    materials = [s.material for s in spheres]
    # The article's point lights; Blender's light types are prepared by ``core.lights``.
    lights = [light for light in scene.lights if isinstance(light, PointLight)]
    return SceneArrays(
        spheres=SphereArrays(
            centers=_rows([s.center for s in spheres], 3),
            radii=np.asarray([s.radius for s in spheres], np.float64),
            ambient=_rows([m.ambient for m in materials], 3),
            diffuse=_rows([m.diffuse for m in materials], 3),
            specular=_rows([m.specular for m in materials], 3),
            exponent=np.asarray([m.shininess / 4 for m in materials], np.float64),
            reflection=np.asarray([m.reflection for m in materials], np.float64),
        ),
        lights=LightArrays(
            positions=_rows([l.position for l in lights], 3),
            ambient=_rows([l.ambient for l in lights], 3),
            diffuse=_rows([l.diffuse for l in lights], 3),
            specular=_rows([l.specular for l in lights], 3),
            radii=np.asarray([l.radius for l in lights], np.float64),
        ),
        background=np.asarray(scene.background, np.float64),
        ambient=np.asarray(scene.ambient, np.float64),
    )
