"""Camera ray generation.

Pixels are addressed in image coordinates: column x in [0, W), row y in [0, H) with row 0 at
the TOP; the pixel (c, r) covers [c, c + 1) x [r, r + 1), and a sample at (c + 0.5, r + 0.5) is
its centre.  ``camera_rays`` maps sample positions (n,) x (n,) to rays.

Blender's camera (``BKE_camera_params_compute_viewplane``, Cycles ``blender_camera_viewplane``)
puts pixel (i, j), j = 0 at the bottom, at u = off_x + (2 (i + .5) / W - 1) half_w,
v = off_y + (2 (j + .5) / H - 1) half_h on the plane z = -1 of camera space.  The article's
camera puts pixel centres at ``linspace`` positions, both ends included.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import BlenderCamera, Camera, ScreenCamera
from .vectors import normalize, normalize_in_place


@dataclass(frozen=True)
class ViewPlane:
    """Blender's view plane in camera space: half sizes and offset of the z = -1 (or ortho) plane."""

    half_width: float
    half_height: float
    offset_x: float
    offset_y: float


def blender_view_plane(camera: BlenderCamera) -> ViewPlane:
    """The camera-space window Blender renders, from the formulas in the module docstring."""
    x_ratio = camera.width * camera.pixel_aspect_x
    y_ratio = camera.height * camera.pixel_aspect_y
    horizontal = camera.sensor_fit == "HORIZONTAL" or (
        camera.sensor_fit == "AUTO" and x_ratio >= y_ratio)
    sensor = camera.sensor_height if camera.sensor_fit == "VERTICAL" else camera.sensor_width
    size = camera.ortho_scale if camera.projection == "ORTHO" else sensor / camera.lens
    if horizontal:
        half_w = size / 2
        half_h = half_w * y_ratio / x_ratio
    else:
        half_h = size / 2
        half_w = half_h * x_ratio / y_ratio
    return ViewPlane(half_w, half_h, camera.shift_x * size, camera.shift_y * size)


def camera_to_world(camera: BlenderCamera) -> tuple[np.ndarray, np.ndarray]:
    """(rotation (3, 3) with unit columns, translation (3,)) of the camera, scale removed."""
    matrix = np.asarray(camera.matrix_world, np.float64)
    rotation = matrix[:3, :3]
    rotation = rotation / np.linalg.norm(rotation, axis=0, keepdims=True)
    return rotation, matrix[:3, 3].copy()


@dataclass(frozen=True)
class CameraRays:
    """Rays for n samples, as (3, n) bundles (see ``core.vectors``).

    origins: (3, n), or (3, 1) when all rays share the camera's eye (perspective cameras).
    directions: (3, n) unit vectors.
    t_min, t_max: (n,) distances along each ray where hits count (Blender's clip planes,
        measured along the view axis, become per-ray distances); scalars 0 / inf if unclipped.
    shares: which share of the soft lights' samples each ray's path traces, for
        anti-aliasing samples (``core.lights.SampleShares``, set by ``core.render``); None:
        pixel centres, which trace all of them.
    world_shift: (n, 2) in [0, 1)^2, how each ray's pixel shifts the grid of the world's
        occlusion directions (``core.lights.shifted_cosine_direction``, set by
        ``core.render`` where the world's occlusion is traced), or None: the unshifted grid.
    """

    origins: np.ndarray
    directions: np.ndarray
    t_min: np.ndarray | float
    t_max: np.ndarray | float
    shares: object = None
    world_shift: np.ndarray | None = None

    @property
    def shared_origin(self) -> bool:
        return self.origins.shape[1] == 1


def _screen_rays(camera: ScreenCamera, xs, ys, dtype) -> CameraRays:
    xs_line = np.linspace(camera.left, camera.right, camera.width)
    ys_line = np.linspace(camera.top, camera.bottom, camera.height)
    step_x = (camera.right - camera.left) / max(camera.width - 1, 1)
    step_y = (camera.bottom - camera.top) / max(camera.height - 1, 1)
    # A sample at the pixel centre lands exactly on the article's linspace position.
    eye = np.asarray(camera.eye, np.float64)
    towards = np.empty((3, len(xs)))
    for axis, (positions, line, step, count) in enumerate(
            ((xs, xs_line, step_x, camera.width), (ys, ys_line, step_y, camera.height))):
        # line[i] + (p - i - 0.5) step - eye, i = floor(p) clipped to the pixels, in place.
        index = np.floor(positions)
        np.minimum(np.maximum(index, 0, out=index), count - 1, out=index)
        out = towards[axis]
        np.subtract(positions, index, out=out)
        out -= 0.5
        out *= step
        out += line.take(index.astype(np.intp))
        out -= eye[axis]
    towards[2] = camera.screen_z - eye[2]
    normalize_in_place(towards)
    return CameraRays(eye[:, None].astype(dtype), towards.astype(dtype, copy=False), 0.0,
                      np.inf)


def has_aperture(camera) -> bool:
    """Whether the camera is a thin lens (depth of field), not a pinhole (perspective or
    orthographic)."""
    return isinstance(camera, BlenderCamera) and camera.aperture_radius > 0


def aperture_points(camera: BlenderCamera, lens: np.ndarray) -> np.ndarray:
    """(2, n) points on the camera's aperture (camera space x, y) for lens samples (2, n) in
    [0, 1)^2, uniform over its area: Shirley and Chiu's concentric map onto the disc, or with
    B >= 3 blades a regular B-gon (one of its B triangles, then a point in it)."""
    u, v = 2.0 * lens[0] - 1.0, 2.0 * lens[1] - 1.0
    blades = camera.aperture_blades
    if blades >= 3:
        corner = np.minimum(np.floor(lens[0] * blades), blades - 1)
        a = lens[0] * blades - corner                     # reuse the fraction
        b = lens[1]
        root = np.sqrt(a)
        weights = (root * (1 - b), root * b)              # uniform in the triangle
        angle0 = camera.aperture_rotation + 2 * np.pi * corner / blades
        angle1 = angle0 + 2 * np.pi / blades
        x = weights[0] * np.cos(angle0) + weights[1] * np.cos(angle1)
        y = weights[0] * np.sin(angle0) + weights[1] * np.sin(angle1)
        return camera.aperture_radius * np.stack([x, y])
    big = np.abs(u) > np.abs(v)
    safe_u = np.where(u == 0, 1.0, u)
    safe_v = np.where(v == 0, 1.0, v)
    radius = np.where(big, u, v)
    theta = np.where(big, (np.pi / 4) * (v / safe_u), np.pi / 2 - (np.pi / 4) * (u / safe_v))
    theta = np.where((u == 0) & (v == 0), 0.0, theta)
    return camera.aperture_radius * np.stack([radius * np.cos(theta), radius * np.sin(theta)])


def _blender_rays(camera: BlenderCamera, xs, ys, dtype, lens=None) -> CameraRays:
    plane = blender_view_plane(camera)
    u = plane.offset_x + (2.0 * xs / camera.width - 1.0) * plane.half_width
    v = plane.offset_y + (2.0 * (camera.height - ys) / camera.height - 1.0) * plane.half_height
    rotation, translation = camera_to_world(camera)
    thin_lens = lens is not None and has_aperture(camera)
    if camera.projection == "ORTHO":
        origins = rotation[:, :2] @ np.stack([u, v]) + translation[:, None]
        if thin_lens:
            # Cycles' orthographic thin lens (``camera_sample_orthographic``): from the pixel's
            # point on the camera plane moved by an aperture point l, towards the pixel's
            # point on the focus plane, so the circle of confusion at depth z has radius
            # aperture_radius |1 - z / focus_distance| in scene units, whatever the scale.
            offset = aperture_points(camera, np.asarray(lens, np.float64))
            towards = np.stack([-offset[0], -offset[1],
                                np.full(len(xs), -camera.focus_distance)])
            directions, length = normalize(rotation @ towards)
            origins = origins + rotation[:, :2] @ offset
            per_depth = length / camera.focus_distance
            return CameraRays(origins.astype(dtype), directions.astype(dtype),
                              (camera.clip_start * per_depth).astype(dtype),
                              (camera.clip_end * per_depth).astype(dtype))
        directions = np.repeat(-rotation[:, 2:3], len(xs), axis=1)
        return CameraRays(origins.astype(dtype), directions.astype(dtype),
                          camera.clip_start, camera.clip_end)
    local = np.stack([u, v, -np.ones_like(u)])
    if thin_lens:
        # Thin lens: from a point on the aperture towards where the pinhole ray crosses the
        # focus plane (depth focus_distance), so every ray of a pixel meets there.
        offset = np.zeros_like(local)
        offset[:2] = aperture_points(camera, np.asarray(lens, np.float64))
        towards = local * camera.focus_distance - offset
        directions, length = normalize(rotation @ towards)
        origins = rotation @ offset + translation[:, None]
        # The depth reached per unit of t is focus_distance / |towards|.
        per_depth = length / camera.focus_distance
        return CameraRays(origins.astype(dtype), directions.astype(dtype),
                          (camera.clip_start * per_depth).astype(dtype),
                          (camera.clip_end * per_depth).astype(dtype))
    directions, local_length = normalize(rotation @ local)
    # Clip planes are depths along -Z; a unit ray reaches depth z after z * |(u, v, -1)|.
    return CameraRays(translation[:, None].astype(dtype), directions.astype(dtype),
                      (camera.clip_start * local_length).astype(dtype),
                      (camera.clip_end * local_length).astype(dtype))


def camera_rays(camera: Camera, xs: np.ndarray, ys: np.ndarray, dtype=np.float64,
                lens=None) -> CameraRays:
    """Rays through image positions xs, ys (n,) (columns and rows, row 0 at the top).  lens:
    (2, n) positions on the aperture in [0, 1)^2 for a thin-lens camera (``has_aperture``);
    None (or a pinhole camera) traces from the eye."""
    xs = np.asarray(xs, np.float64)
    ys = np.asarray(ys, np.float64)
    if isinstance(camera, ScreenCamera):
        return _screen_rays(camera, xs, ys, dtype)
    return _blender_rays(camera, xs, ys, dtype, lens)


def eye_position(camera: Camera) -> np.ndarray:
    """The camera's position (3,) in world space (the ortho camera's centre)."""
    if isinstance(camera, ScreenCamera):
        return np.asarray(camera.eye, np.float64)
    return camera_to_world(camera)[1]
