"""The scene camera -> ``core.BlenderCamera``.

Everything the view depends on is copied as Blender stores it; the core applies Blender's own
view-plane rules (``core.camera.blender_view_plane``): projection, lens or orthographic scale,
sensor size and fit, shift, clip start/end, the render resolution and percentage, and the
pixel aspect.  ``matrix_world`` is passed as nested tuples; the core drops its scale, as
Blender does.  Panoramic cameras have no counterpart in the core: they are an error, as is a
scene without a camera.
"""

from __future__ import annotations

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
        )
    except SceneError as error:
        raise ExportError(f"camera '{camera.name}': {error}") from None
