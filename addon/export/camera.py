"""The scene camera -> ``core.BlenderCamera``.

Everything the view depends on is copied as Blender stores it; the core applies Blender's own
view-plane rules (``core.camera.blender_view_plane``): projection, lens or orthographic scale,
sensor size and fit, shift, clip start/end, the render resolution and percentage, and the
pixel aspect.  ``matrix_world`` is passed as nested tuples; the core drops its scale, as
Blender does.  Panoramic cameras have no counterpart in the core: they are an error, as is a
scene without a camera.
"""

from __future__ import annotations

import numpy as np

from ...core import BlenderCamera, SceneError
from .errors import ExportError


def camera_object(depsgraph, camera_override=None):
    """The evaluated camera object to render through (the override if given)."""
    camera = camera_override if camera_override is not None else depsgraph.scene_eval.camera
    if camera is None:
        raise ExportError(f"scene '{depsgraph.scene.name}' has no camera: add one and make it "
                          f"the scene camera")
    camera = camera.original.evaluated_get(depsgraph)
    if camera.type != 'CAMERA':
        raise ExportError(f"scene camera '{camera.name}' is a {camera.type.lower()} object, "
                          f"not a camera")
    if camera.data.type == 'PANO':
        raise ExportError(f"camera '{camera.name}' is panoramic: Glint renders perspective and "
                          f"orthographic cameras only")
    return camera


def export_camera(depsgraph, camera_override=None) -> BlenderCamera:
    camera = camera_object(depsgraph, camera_override)
    data = camera.data
    render = depsgraph.scene_eval.render
    try:
        return BlenderCamera(
            matrix_world=tuple(tuple(row) for row in camera.matrix_world),
            resolution_x=render.resolution_x,
            resolution_y=render.resolution_y,
            resolution_percentage=render.resolution_percentage,
            projection=data.type,
            lens=data.lens,
            ortho_scale=data.ortho_scale,
            sensor_width=data.sensor_width,
            sensor_height=data.sensor_height,
            sensor_fit=data.sensor_fit,
            shift_x=data.shift_x,
            shift_y=data.shift_y,
            clip_start=data.clip_start,
            clip_end=data.clip_end,
            pixel_aspect_x=render.pixel_aspect_x,
            pixel_aspect_y=render.pixel_aspect_y,
            **depth_of_field(camera),
            name=camera.name,
        )
    except SceneError as error:
        raise ExportError(f"camera '{camera.name}': {error}") from None


def depth_of_field(camera) -> dict:
    """The thin lens of a camera with Depth of Field on, as Cycles reads it
    (``blender_camera.cpp``): aperture radius = lens (mm, as metres: 1e-3 per scene unit) /
    (2 F-stop) for a perspective camera, 1 / (2 F-stop) scene units for an orthographic one
    (checked against Cycles: an F-stop of 10 blurs a silhouette 2 focus distances away over 4
    pixels of 0.025 per edge, a radius of 0.05); focus distance along the view axis to the
    focus object's origin, else the Focus Distance; blades and rotation as set (fewer than 3
    blades: a round aperture)."""
    dof = camera.data.dof
    if not dof.use_dof:
        return {}
    distance = dof.focus_distance
    if dof.focus_object is not None:
        matrix = camera.matrix_world
        axis = -np.asarray([matrix[r][2] for r in range(3)], np.float64)
        axis /= np.linalg.norm(axis)
        offset = np.asarray(dof.focus_object.matrix_world.translation) - \
            np.asarray(matrix.translation)
        distance = max(float(offset @ axis), 1e-6)
    blades = dof.aperture_blades if dof.aperture_blades >= 3 else 0
    size = 1.0 if camera.data.type == 'ORTHO' else camera.data.lens * 1e-3
    return dict(aperture_radius=size / (2.0 * max(dof.aperture_fstop, 1e-5)),
                focus_distance=distance, aperture_blades=blades,
                aperture_rotation=dof.aperture_rotation)
