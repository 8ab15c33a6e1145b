"""Cameras as a scene describes them (the article's ``ScreenCamera``, Blender's
``BlenderCamera``: validated on construction, as every part of a scene is, ``core.scene``), and
the rays they make.

Pixels are addressed in image coordinates: column x in [0, W), row y in [0, H) with row 0 at
the TOP; the pixel (c, r) covers [c, c + 1) x [r, r + 1), and a sample at (c + 0.5, r + 0.5) is
its centre.  ``camera_rays`` maps sample positions (n,) x (n,) to rays.

Blender's camera (``BKE_camera_params_compute_viewplane``, Cycles ``blender_camera_viewplane``)
puts pixel (i, j), j = 0 at the bottom, at u = off_x + (2 (i + .5) / W - 1) half_w,
v = off_y + (2 (j + .5) / H - 1) half_h on the plane z = -1 of camera space.  The article's
camera puts pixel centres at ``linspace`` positions, both ends included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Union

import numpy as np

from .validation import (SceneError, Vec3, value_text, _choice, _count, _finite, _non_negative,
                         _positive, _set, _set_label, _vec3)
from .vectors import normalize, normalize_in_place

PROJECTIONS = ("PERSP", "ORTHO")
SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")


@dataclass(frozen=True)
class ScreenCamera:
    """The article's camera: an eye looking through a screen rectangle on a plane.

    eye: (3,) position.  The screen lies on the plane z = ``screen_z`` and spans
    [left, right] x [bottom, top].  Pixel positions are ``linspace(left, right, width)`` and
    ``linspace(top, bottom, height)``: both ends included, so pixel centres sit ON the screen's
    edges (unlike Blender's (i + 0.5) / W).  Row 0 is the top.
    """

    width: int
    height: int
    eye: Vec3 = (0.0, 0.0, 1.0)
    left: float = -1.0
    right: float = 1.0
    top: float | None = None      # None: 1 / (width / height), the article's choice
    bottom: float | None = None   # None: -1 / (width / height)
    screen_z: float = 0.0

    def __post_init__(self):
        _count("camera.width", self.width)
        _count("camera.height", self.height)
        _set(self, "eye", _vec3("camera.eye", self.eye))
        ratio = self.width / self.height
        if self.top is None:
            _set(self, "top", 1.0 / ratio)
        if self.bottom is None:
            _set(self, "bottom", -1.0 / ratio)
        for name in ("left", "right", "top", "bottom", "screen_z"):
            _set(self, name, _finite(f"camera.{name}", getattr(self, name)))


@dataclass(frozen=True)
class BlenderCamera:
    """Blender's camera, with Blender's own conventions (``BKE_camera_params_compute_viewplane``).

    matrix_world: 4x4 camera-to-world matrix, rows of 4 (Blender's ``Object.matrix_world``
        as nested tuples); any scale in it is removed, as Blender does for the view.
        The camera looks down its local -Z with +Y up.
    projection: 'PERSP' or 'ORTHO'.  lens: focal length in mm (perspective);
        ortho_scale: the view's width or height in scene units (orthographic).
    sensor_width, sensor_height: mm; sensor_fit: 'AUTO', 'HORIZONTAL' or 'VERTICAL'.
    shift_x, shift_y: in units of the fitted view size, like Blender.
    clip_start, clip_end: distances along the view axis (depth planes, as in Cycles and
        Workbench, not distances along each ray).
    resolution_x, resolution_y, resolution_percentage: the output is
        ``int(resolution_x * percentage / 100)`` by ``int(resolution_y * percentage / 100)``.
    pixel_aspect_x, pixel_aspect_y: non-square pixels.
    Pixel (i, j) with j = 0 at the bottom has its centre at ((i + 0.5) / W, (j + 0.5) / H).
    aperture_radius, focus_distance, aperture_blades, aperture_rotation: a thin lens
        (Cycles' depth of field): rays leave a disc (or, with 3 or more blades, a regular
        polygon turned by the rotation) of that radius around the eye (orthographic: around
        the pixel's point on the camera plane) and meet at the plane at focus_distance along
        the view axis; 0 radius is a pinhole.
    name: the camera object's name, for warnings.

    A camera through which Cycles renders a black frame (measured: its matrix scaled to 0,
    clip_end not past clip_start, an orthographic camera of ortho_scale 0, depth of field
    focused at 0; alpha 1, or 0 with a transparent film) renders one too (``sees_nothing``:
    ``core.render`` renders nothing through it), with one warning naming the fields; its
    stored values are then stand-ins that let the view be worked out (an unscaled matrix, a
    clip range, a scale and a focus of 1).
    """

    matrix_world: tuple
    resolution_x: int = 1920
    resolution_y: int = 1080
    resolution_percentage: int = 100
    projection: Literal["PERSP", "ORTHO"] = "PERSP"
    lens: float = 50.0
    ortho_scale: float = 6.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: Literal["AUTO", "HORIZONTAL", "VERTICAL"] = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    pixel_aspect_x: float = 1.0
    pixel_aspect_y: float = 1.0
    aperture_radius: float = 0.0     # thin lens: 0 is a pinhole
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    name: str = ""
    sees_nothing: bool = field(default=False, init=False, repr=False, compare=False)
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        try:
            rows = tuple(tuple(row) for row in self.matrix_world)
        except TypeError:
            raise SceneError(f"camera.matrix_world must be 4x4, got "
                             f"{value_text(self.matrix_world)}") from None
        if len(rows) != 4 or any(len(row) != 4 for row in rows):
            raise SceneError(f"camera.matrix_world must be 4x4, got "
                             f"{value_text(self.matrix_world)}")
        _set(self, "matrix_world", tuple(
            tuple(_finite(f"camera.matrix_world[{r}][{c}]", v) for c, v in enumerate(row))
            for r, row in enumerate(rows)))
        _count("camera.resolution_x", self.resolution_x)
        _count("camera.resolution_y", self.resolution_y)
        _count("camera.resolution_percentage", self.resolution_percentage)
        _choice("camera.projection", self.projection, PROJECTIONS)
        _choice("camera.sensor_fit", self.sensor_fit, SENSOR_FITS)
        for name in ("lens", "sensor_width", "sensor_height", "pixel_aspect_x",
                     "pixel_aspect_y", "clip_start"):
            _set(self, name, _positive(f"camera.{name}", getattr(self, name)))
        for name in ("shift_x", "shift_y", "aperture_rotation"):
            _set(self, name, _finite(f"camera.{name}", getattr(self, name)))
        _set(self, "aperture_radius", _non_negative("camera.aperture_radius",
                                                    self.aperture_radius))
        if self.aperture_blades != 0:
            _count("camera.aperture_blades", self.aperture_blades, minimum=3)
        if self.width < 1 or self.height < 1:
            raise SceneError(
                f"camera resolution {self.resolution_x}x{self.resolution_y} at "
                f"{self.resolution_percentage}% gives a {self.width}x{self.height} image")
        blind = []   # why Cycles renders this camera's frame black
        rows = [list(row) for row in self.matrix_world]
        axes = [[rows[r][c] for r in range(3)] for c in range(3)]
        if any(math.sqrt(sum(v * v for v in axis)) < 1e-12 for axis in axes):
            blind.append("matrix_world is scaled to 0")
            for r in range(3):
                rows[r][:3] = [float(r == c) for c in range(3)]
            _set(self, "matrix_world", tuple(tuple(row) for row in rows))
        _set(self, "clip_end", _positive("camera.clip_end", self.clip_end))
        if self.clip_end <= self.clip_start:
            blind.append(f"clip_end {value_text(self.clip_end)} is not past clip_start "
                         f"{value_text(self.clip_start)}")
            _set(self, "clip_end", self.clip_start + 1.0)
        _set(self, "ortho_scale", _non_negative("camera.ortho_scale", self.ortho_scale))
        if self.ortho_scale == 0.0:
            if self.projection == "ORTHO":
                blind.append("ortho_scale is 0")
            _set(self, "ortho_scale", 1.0)
        _set(self, "focus_distance", _non_negative("camera.focus_distance",
                                                   self.focus_distance))
        if self.focus_distance == 0.0:
            if self.aperture_radius > 0.0:
                blind.append("focus_distance is 0 with depth of field")
            _set(self, "focus_distance", 1.0)
        if blind:
            _set(self, "sees_nothing", True)
            _set(self, "warnings", (f"{_set_label('camera', self.name)}: {', '.join(blind)}: "
                                    f"the frame renders black, as in Cycles",))

    @property
    def width(self) -> int:
        return int(self.resolution_x * self.resolution_percentage / 100)

    @property
    def height(self) -> int:
        return int(self.resolution_y * self.resolution_percentage / 100)


Camera = Union[ScreenCamera, BlenderCamera]


# --------------------------------------------------------------------------------------------
# The rays a camera makes


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
