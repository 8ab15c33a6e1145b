"""Material, light and world previews (``bl_use_preview``): the small renders Blender makes of
its own preview scene (``release/datafiles/preview.blend``) for the Material, Light and World
properties and for thumbnails.

The preview scene's sphere is a sphere mesh, which Glint renders as an exact sphere with the
user's material; its lights are area lights set up for Blender's own engines.  So a preview:

* reports no warnings (they would be about Blender's preview scene, not the user's, and
  Blender renders a preview on every edit of the material: one warning each time is spam);
* is lit by a point light of Blender's default power placed up and to the left of the
  preview camera (``PREVIEW_LIGHT_DIRECTION``, in camera space, at the distance of the
  nearest sphere) instead of the preview scene's lights, unless it has a point light of its
  own (a point light being previewed is rendered as it is, alone);
* draws the preview's sphere-like meshes as exact spheres (``analytic_spheres``: the
  exporter keeps a mesh analytic only within a quarter pixel, and Blender's preview sphere at
  preview sizes is not; the preview is of the material, not of the tessellation);
* renders with the preview scene's own Glint settings (Blender's defaults: default semantics,
  adaptive anti-aliasing), which take milliseconds at preview sizes.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...core import PointLight, Sphere, SphereLight
from ...core.camera import camera_to_world
from ..export.geometry import MAX_FACE_SAGITTA, fit_sphere, uniform_scales
from .final import failures_reported, render_job
from .job import RenderJob, prepare_job

#: Where the preview's key light comes from, in camera space (x right, y up, -z ahead): up
#: and to the left of the camera, as a photographer's key light, so the sphere shows its
#: diffuse falloff, a highlight and its shadow side.
PREVIEW_LIGHT_DIRECTION = (-0.6, 0.7, 0.4)
PREVIEW_LIGHT_POWER_W = PointLight.REFERENCE_POWER_W


def preview_light(scene) -> PointLight:
    """The key light for a preview scene without a point light (module docstring)."""
    rotation, eye = camera_to_world(scene.camera)
    if scene.spheres:
        distance = min(float(np.linalg.norm(np.asarray(s.center) - eye)) for s in scene.spheres)
    else:
        distance = 1.0
    direction = np.asarray(PREVIEW_LIGHT_DIRECTION)
    position = eye + distance * (rotation @ (direction / np.linalg.norm(direction)))
    return PointLight.from_power(tuple(position), (1.0, 1.0, 1.0), PREVIEW_LIGHT_POWER_W,
                                 name="Glint preview light")


def analytic_spheres(scene):
    """``scene`` with each single-material triangle mesh whose vertices lie on a sphere and
    whose faces follow it (``export.geometry``'s tests: fit_sphere, face sag under
    MAX_FACE_SAGITTA of the radius) replaced by its analytic spheres, one per uniformly scaled
    instance."""
    spheres, meshes = list(scene.spheres), []
    for mesh in scene.meshes:
        fit = fit_sphere(mesh.vertices) if len(mesh.materials) == 1 else None
        if fit is not None:
            corners = mesh.vertices[mesh.triangles]                 # (T, 3, 3)
            sag = fit.radius - np.linalg.norm(corners.mean(axis=1) - fit.center, axis=1)
            scales, uniform = uniform_scales(mesh.transforms)
            if sag.max() <= MAX_FACE_SAGITTA * fit.radius and uniform.all():
                centres = (mesh.transforms[:, :3, :3] @ np.asarray(fit.center)
                           + mesh.transforms[:, :3, 3])
                spheres += [Sphere(tuple(centre), fit.radius * scale, mesh.materials[0],
                                   mesh.name) for centre, scale in zip(centres, scales)]
                continue
        meshes.append(mesh)
    return dataclasses.replace(scene, spheres=tuple(spheres), meshes=tuple(meshes))


def prepare_preview_job(depsgraph, camera_override=None) -> RenderJob:
    """A RenderJob for Blender's preview scene (module docstring): no warnings, exact
    spheres, a key light when the scene has no point light."""
    job = prepare_job(depsgraph, camera_override=camera_override)
    job.scene = analytic_spheres(job.scene)
    points = tuple(light for light in job.scene.lights
                   if isinstance(light, (PointLight, SphereLight)))
    job.scene = dataclasses.replace(job.scene, lights=points or (preview_light(job.scene),))
    job.warnings = []
    job.settings = dataclasses.replace(job.settings, cluster="")   # (small: rendered here)
    return job


def render_preview(engine, depsgraph) -> None:
    """A preview's render (``GlintRenderEngine.render`` with ``is_preview``): its job traced
    and handed to Blender as a final render's is, without passes."""
    with failures_reported(engine):
        render_job(engine, depsgraph,
                   prepare_preview_job(depsgraph, camera_override=engine.camera_override))
