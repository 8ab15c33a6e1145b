"""A 3D View -> a core camera: the export of what a viewport region shows (Rendered shading).

* ``view_camera``: a region's view and projection matrices (``RegionView3D.view_matrix`` /
  ``window_matrix``) -> a ``core.BlenderCamera`` whose rays are the rays through the region's
  pixels.  This covers perspective and orthographic views, the camera view (whose window
  matrix already holds the camera's lens, shift, sensor fit and the view's zoom and pan) and
  any sub-rectangle (``crop_projection``: the camera view's render border, coarse passes).
* ``camera_frame_rect``: where the scene camera's frame lies in the region (camera view),
  and so where its render border lies (``border_rect``).
* ``ViewportView``: what a region shows (its matrices, size and the rectangle to render),
  read from Blender's context on the main thread, plain data afterwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core import BlenderCamera

#: A clip end beyond this (or an infinite far plane) is clamped to it: BlenderCamera needs a
#: finite value, and no scene reaches that far.
FAR_LIMIT = 1e30


def _matrix(matrix) -> np.ndarray:
    return np.array([list(row) for row in matrix], np.float64)


def view_camera(view_matrix, window_matrix, width: int, height: int) -> BlenderCamera:
    """A BlenderCamera of width x height pixels whose rays are the region's.

    view_matrix: world -> view (4x4, a rigid transform); window_matrix: view -> clip, an
    OpenGL perspective (row 3 = (0, 0, -1, 0)) or orthographic (row 3 = (0, 0, 0, 1))
    projection, as ``RegionView3D`` holds them.  A region pixel (i, j), j from the bottom,
    has its centre at NDC (2 (i + .5) / W - 1, 2 (j + .5) / H - 1), exactly as the core's
    camera places pixel centres; the camera is given a horizontal sensor fit whose view-plane
    width is the projection's, a pixel aspect that makes its height the projection's, and a
    shift for an off-centre projection (camera shift, the camera view's pan, a crop).

    Perspective, at view depth 1: x_view = (ndc_x + P02) / P00, so half width 1 / P00 and
    centre P02 / P00; clip planes n = P23 / (P22 - 1), f = P23 / (P22 + 1).
    Orthographic: x_view = (ndc_x - P03) / P00; n = (P23 + 1) / P22, f = (P23 - 1) / P22.
    An orthographic viewport's near plane is behind its view point (n < 0); the camera is
    moved back along the view axis so that its clip start is positive.
    """
    view = _matrix(view_matrix)
    projection = _matrix(window_matrix)
    camera_to_world = np.linalg.inv(view)
    p = projection
    perspective = p[3, 3] == 0.0
    if perspective:
        half_w, half_h = 1.0 / p[0, 0], 1.0 / p[1, 1]
        centre_x, centre_y = p[0, 2] / p[0, 0], p[1, 2] / p[1, 1]
        near = p[2, 3] / (p[2, 2] - 1.0)
        far = p[2, 3] / (p[2, 2] + 1.0) if p[2, 2] != -1.0 else math.inf
    else:
        half_w, half_h = 1.0 / p[0, 0], 1.0 / p[1, 1]
        centre_x, centre_y = -p[0, 3] / p[0, 0], -p[1, 3] / p[1, 1]
        near = (p[2, 3] + 1.0) / p[2, 2]
        far = (p[2, 3] - 1.0) / p[2, 2]
    if not math.isfinite(far) or far <= near or far > FAR_LIMIT:
        far = FAR_LIMIT
    size = 2.0 * half_w                 # the view plane's width (sensor_width / lens, or ortho)
    # half_h = half_w * (H * aspect_y) / (W * aspect_x) with aspect_x = 1:
    aspect_y = half_h * width / (half_w * height)
    if not perspective and near <= 0.0:
        # Move the eye back so the near plane is ahead of it.
        back = (far - near) * 1e-6 - near
        camera_to_world = camera_to_world.copy()
        camera_to_world[:3, 3] += back * camera_to_world[:3, 2]
        near, far = near + back, far + back
    lens = 50.0
    return BlenderCamera(
        matrix_world=tuple(tuple(row) for row in camera_to_world),
        resolution_x=int(width), resolution_y=int(height), resolution_percentage=100,
        projection="PERSP" if perspective else "ORTHO",
        lens=lens, sensor_width=lens * size, sensor_height=lens * size, ortho_scale=size,
        sensor_fit="HORIZONTAL",
        shift_x=centre_x / size, shift_y=centre_y / size,
        clip_start=near, clip_end=far,
        pixel_aspect_x=1.0, pixel_aspect_y=aspect_y,
    )


def crop_projection(window_matrix, width: int, height: int, rect) -> np.ndarray:
    """The projection (4x4) of the sub-rectangle rect = (x0, y0, x1, y1) of a width x height
    region (pixels, rows from the bottom): the same rays, re-normalised so that the rectangle
    spans NDC [-1, 1]^2.  clip' = S clip with S scaling and translating x and y."""
    x0, y0, x1, y1 = rect
    ndc = lambda a, size: 2.0 * a / size - 1.0  # noqa: E731
    left, right = ndc(x0, width), ndc(x1, width)
    bottom, top = ndc(y0, height), ndc(y1, height)
    scale = np.eye(4)
    scale[0, 0] = 2.0 / (right - left)
    scale[0, 3] = -(right + left) / (right - left)
    scale[1, 1] = 2.0 / (top - bottom)
    scale[1, 3] = -(top + bottom) / (top - bottom)
    return scale @ _matrix(window_matrix)


def camera_frame_rect(perspective_matrix, frame_corners, width: int, height: int):
    """(x0, y0, x1, y1) in region pixels (float, rows from the bottom) of the scene camera's
    frame in a camera view: its four world-space corners (``Camera.view_frame`` placed by the
    camera's world matrix) projected by the region's perspective matrix (window @ view), as
    ``bpy_extras.view3d_utils.location_3d_to_region_2d`` does."""
    pers = _matrix(perspective_matrix)
    corners = np.array([list(c)[:3] + [1.0] for c in frame_corners], np.float64)
    clip = corners @ pers.T
    xs = width / 2.0 * (1.0 + clip[:, 0] / clip[:, 3])
    ys = height / 2.0 * (1.0 + clip[:, 1] / clip[:, 3])
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())


def border_rect(frame, border, width: int, height: int):
    """The render border (min_x, min_y, max_x, max_y fractions of the camera frame) in whole
    region pixels (edges rounded to the nearest pixel edge), clamped to the region; None if
    it covers no pixel."""
    fx0, fy0, fx1, fy1 = frame
    min_x, min_y, max_x, max_y = border
    x0 = max(0, round(fx0 + min_x * (fx1 - fx0)))
    x1 = min(width, round(fx0 + max_x * (fx1 - fx0)))
    y0 = max(0, round(fy0 + min_y * (fy1 - fy0)))
    y1 = min(height, round(fy0 + max_y * (fy1 - fy0)))
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


@dataclass(frozen=True)
class ViewportView:
    """What the region shows: its matrices, size in pixels and the rectangle to render
    (rows from the bottom; the whole region, or the render border in a camera view)."""

    view_matrix: tuple
    window_matrix: tuple
    width: int
    height: int
    rect: tuple

    @classmethod
    def from_matrices(cls, view_matrix, window_matrix, width, height, rect=None):
        as_tuple = lambda m: tuple(tuple(float(v) for v in row) for row in m)  # noqa: E731
        return cls(as_tuple(view_matrix), as_tuple(window_matrix), int(width), int(height),
                   tuple(rect) if rect is not None else (0, 0, int(width), int(height)))

    @classmethod
    def from_context(cls, context, scene):
        """The view of ``context.region`` / ``context.region_data`` (main thread); ``scene``
        is the evaluated scene, for the camera and its render border in a camera view.
        Returns None when the render border covers no pixel."""
        region, rv3d = context.region, context.region_data
        width, height = region.width, region.height
        rect = None
        camera = scene.camera
        if (rv3d.view_perspective == 'CAMERA' and scene.render.use_border and camera is not None
                and camera.type == 'CAMERA'):
            frame = [camera.matrix_world @ corner for corner in camera.data.view_frame(scene=scene)]
            rect = border_rect(camera_frame_rect(rv3d.perspective_matrix, frame, width, height),
                               (scene.render.border_min_x, scene.render.border_min_y,
                                scene.render.border_max_x, scene.render.border_max_y),
                               width, height)
            if rect is None:
                return None
        return cls.from_matrices(rv3d.view_matrix, rv3d.window_matrix, width, height, rect)

    def camera(self, divisor: int = 1) -> BlenderCamera:
        """The core camera of the view's rectangle traced at 1 / divisor of its resolution."""
        x0, y0, x1, y1 = self.rect
        projection = self.window_matrix
        if self.rect != (0, 0, self.width, self.height):
            projection = crop_projection(projection, self.width, self.height, self.rect)
        return view_camera(self.view_matrix, projection,
                           max(1, (x1 - x0) // divisor), max(1, (y1 - y0) // divisor))
