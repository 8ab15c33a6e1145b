"""Glint's core: a pure Python + NumPy ray tracer for spheres and Blender's lights (no bpy).

Public API::

    from core import (Scene, Sphere, SphereSet, TriangleMesh, Material, PointLight,
                      ScreenCamera, BlenderCamera, RenderSettings, render, article_scene,
                      SceneError, RenderCancelled)

    result = render(scene, RenderSettings(...), progress=None, should_cancel=None)
    result.image      # (H, W, 4) float64 or float32, row 0 = TOP; RGB: article semantics
                      # clipped to [0, 1], default semantics unclipped scene-linear radiance;
                      # alpha = fraction of the pixel whose camera ray hit a sphere
    result.display()  # display values for an 8-bit file (view transform Standard)
    result.stats      # RayStats: camera_rays, shadow_rays, reflection_rays, ...
    result.precision  # 'float64' or 'float32', the precision the render ran in

``progress(fraction)`` is called as tiles finish; ``should_cancel()`` is polled between tiles
and a True answer raises RenderCancelled.  Invalid scenes or settings raise SceneError (a
ValueError) naming the field, before any ray is traced; values Blender can hold that Cycles
renders in its own way (a NaN vertex, a light scaled to 0, ...) are rendered as Cycles does,
each part saying so in ``Scene.warnings`` (docs/invalid-data.md).
"""

from .camera import BlenderCamera, ScreenCamera
from .light_sources import AreaLight, PointLight, SphereLight, SpotLight, SunLight
from .materials import Material, SurfaceMaterial
from .scene import Scene, Sphere, SphereSet, TriangleMesh
from .settings import RenderSettings
from .validation import SceneError
from .failures import RenderCancelled
from .render import RayStats, RenderResult, render
from .article import article_scene, article_settings

__all__ = [
    "AreaLight", "SphereLight", "SpotLight", "SunLight", "SurfaceMaterial",
    "BlenderCamera", "Material", "PointLight", "RenderSettings", "Scene", "SceneError",
    "ScreenCamera", "Sphere", "SphereSet", "TriangleMesh", "RayStats", "RenderCancelled",
    "RenderResult", "render",
    "article_scene", "article_settings",
]
