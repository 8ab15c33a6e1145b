"""The render's frame of reference: every scene moved and scaled to about unit size.

An image must not depend on where the user put the scene or the unit they modelled in.  In
a scene's own coordinates it does: squared lengths overflow float32 beyond about 1e19 and
float64 beyond 1e154, a scene far from the origin loses digits to its offset, and tolerances
that are relative to coordinates (the default semantics' ray offsets) grow with that offset.
So ``canonical_scene`` maps the scene, before any array is built, by

    x -> (x - centre) * scale

with ``centre`` the camera's eye (camera-relative coordinates, as production renderers use:
floating point is densest at the origin, where camera rays start and the nearest, largest
objects on screen are) and ``scale`` the power of two that brings the smallest sphere's
radius into [0.5, 1) (without spheres: the largest distance from the eye to a light).  The
smallest feature becomes the unit because the default semantics' ray offsets,
``(1 + max|P|) * 1500 eps`` (Mitsuba 3's), take 1 as the size below which positions do not
grow the offset; coordinates are then at most the scene's extent-to-radius ratio, which
``check_resolvable`` bounds, so squares never overflow.  A power of two multiplies exactly, so
only the translation rounds, once, in float64.  The image is unchanged by construction: every
length scales alike and colours do not depend on lengths (the article's lights have no
distance falloff).

The precision ``auto`` then chooses depends only on the scene's shape (``core.precision``).
Where even float64 cannot resolve the scene, because its smallest sphere is more than
``MAX_SCALE_RATIO`` times smaller than its extent (a ray's hit point carries an error of about
1e-16 of the extent, and offsets of 1500 eps), ``canonical_scene`` refuses it, naming that
sphere, instead of rendering a wrong picture.

Article semantics is left as it is: its fixed 1e-5 offset is part of the article's image,
measured in the scene's own units.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .camera import eye_position
from .scene import (MAX_MAGNITUDE, BlenderCamera, RenderSettings, Scene, SceneError,
                    ScreenCamera)

#: Largest extent / smallest radius float64 can render exactly: the hit point's relative
#: error (~1e-16 * 1500 for offsets, ~2e-13) times this stays below 1e-1 of the radius.
MAX_SCALE_RATIO = 1e12


@dataclasses.dataclass(frozen=True)
class Frame:
    """x_canonical = (x - centre) * scale (scale a power of two)."""

    centre: np.ndarray   # (3,) float64
    scale: float

    def point(self, p) -> tuple:
        return tuple(float(v) for v in (np.asarray(p, np.float64) - self.centre) * self.scale)

    def length(self, d: float) -> float:
        return float(d) * self.scale

    def transforms(self, matrices: np.ndarray) -> np.ndarray:
        """(K, 4, 4) object-to-world matrices -> object-to-canonical: scale the 3 x 3 part,
        move and scale the translation."""
        moved = np.array(matrices, np.float64)
        moved[:, :3, :3] *= self.scale
        moved[:, :3, 3] = (moved[:, :3, 3] - self.centre) * self.scale
        return moved


def _mesh_corners(mesh) -> np.ndarray:
    """(8 K, 3) world-space corners of a mesh's object-space bounding box, per instance."""
    lower, upper = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    corners = np.array([[(lower, upper)[(i >> axis) & 1][axis] for axis in range(3)]
                        for i in range(8)])                                     # (8, 3)
    linear, shift = mesh.transforms[:, :3, :3], mesh.transforms[:, :3, 3]
    return (np.einsum("kij,cj->kci", linear, corners) + shift[:, None, :]).reshape(-1, 3)


def scene_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(lower (3,), upper (3,)) of spheres, sphere sets, meshes, lights (with radii) and the
    camera's eye."""
    points = [eye_position(scene.camera)[None, :]]
    reach = [np.zeros(1)]
    if scene.spheres:
        points.append(np.array([s.center for s in scene.spheres], np.float64))
        reach.append(np.array([s.radius for s in scene.spheres], np.float64))
    for sphere_set in scene.sphere_sets:
        points.append(sphere_set.centers)
        reach.append(sphere_set.radii)
    for mesh in scene.meshes:
        if len(mesh.vertices):
            corners = _mesh_corners(mesh)
            points.append(corners)
            reach.append(np.zeros(len(corners)))
    if scene.lights:
        points.append(np.array([light.position for light in scene.lights], np.float64))
        reach.append(np.array([light.radius for light in scene.lights], np.float64))
    points, reach = np.concatenate(points), np.concatenate(reach)[:, None]
    return (points - reach).min(axis=0), (points + reach).max(axis=0)


def smallest_sphere(scene: Scene) -> tuple[float, str] | None:
    """(radius, name) of the scene's smallest sphere, loose or in a set; None without any."""
    candidates = [(s.radius, f"sphere '{s.name}'" if s.name else f"sphere {i}")
                  for i, s in enumerate(scene.spheres)]
    for sphere_set in scene.sphere_sets:
        if len(sphere_set):
            index = int(sphere_set.radii.argmin())
            label = f"sphere set '{sphere_set.name}'" if sphere_set.name else "sphere set"
            candidates.append((float(sphere_set.radii[index]), f"{label} sphere {index}"))
    return min(candidates, default=None, key=lambda item: item[0])


def scene_reach(scene: Scene) -> float:
    """The largest distance (per axis) from the camera's eye to anything a ray meets."""
    centre = eye_position(scene.camera)
    lower, upper = scene_bounds(scene)
    # Halves first: differences of values up to 1e300 apart must not overflow.
    return 2 * float(np.maximum(np.abs(lower / 2 - centre / 2),
                                np.abs(upper / 2 - centre / 2)).max())


def scene_frame(scene: Scene) -> Frame:
    """The frame whose unit is the scene's smallest sphere, centred on the camera's eye
    (module docstring)."""
    centre = eye_position(scene.camera)
    smallest = smallest_sphere(scene)
    unit = smallest[0] if smallest is not None else scene_reach(scene)
    if unit == 0.0:
        return Frame(centre, 1.0)
    exponent = math.frexp(unit)[1]  # unit = m 2^e, 0.5 <= m < 1
    return Frame(centre, math.ldexp(1.0, -exponent))


def check_resolvable(scene: Scene) -> None:
    """Raise SceneError when float64 cannot resolve the scene's smallest sphere from where
    rays reach."""
    smallest = smallest_sphere(scene)
    if smallest is None:
        return
    radius, name = smallest
    ratio = scene_reach(scene) / radius
    if ratio > MAX_SCALE_RATIO:
        raise SceneError(
            f"{name} (radius {radius:g}) is {ratio:.1e} times smaller than the "
            f"scene's extent, more than the {MAX_SCALE_RATIO:.0e} float64 can render exactly: "
            f"enlarge it, or move far-away objects, lights or the camera closer")


def _camera(camera, frame: Frame):
    if isinstance(camera, ScreenCamera):
        cx, cy, cz = frame.centre
        s = frame.scale
        return dataclasses.replace(
            camera, eye=frame.point(camera.eye), left=(camera.left - cx) * s,
            right=(camera.right - cx) * s, top=(camera.top - cy) * s,
            bottom=(camera.bottom - cy) * s, screen_z=(camera.screen_z - cz) * s)
    assert isinstance(camera, BlenderCamera)
    matrix = [list(row) for row in camera.matrix_world]
    translation = frame.point([matrix[r][3] for r in range(3)])
    for r in range(3):
        matrix[r][3] = translation[r]
    # Lengths the scene does not reach may grow past validation's limit; capped, they clip
    # nothing more or less.
    def capped(length):
        return min(frame.length(length), MAX_MAGNITUDE)

    ortho = camera.projection == "ORTHO"
    return dataclasses.replace(
        camera, matrix_world=tuple(tuple(row) for row in matrix),
        ortho_scale=capped(camera.ortho_scale) if ortho else camera.ortho_scale,
        clip_start=min(frame.length(camera.clip_start), MAX_MAGNITUDE / 2),
        clip_end=capped(camera.clip_end))


def canonical_scene(scene: Scene, settings: RenderSettings) -> Scene:
    """``scene`` in its canonical frame (module docstring); article semantics unchanged.
    Raises SceneError for a scene float64 cannot resolve."""
    check_resolvable(scene)
    if settings.semantics == "article":
        return scene
    frame = scene_frame(scene)
    spheres = tuple(dataclasses.replace(s, center=frame.point(s.center),
                                        radius=frame.length(s.radius)) for s in scene.spheres)
    lights = tuple(dataclasses.replace(light, position=frame.point(light.position),
                                       radius=frame.length(light.radius))
                   for light in scene.lights)
    sphere_sets = tuple(dataclasses.replace(
        sphere_set, centers=(sphere_set.centers - frame.centre) * frame.scale,
        radii=sphere_set.radii * frame.scale) for sphere_set in scene.sphere_sets)
    meshes = tuple(dataclasses.replace(mesh, transforms=frame.transforms(mesh.transforms))
                   for mesh in scene.meshes)
    return dataclasses.replace(scene, camera=_camera(scene.camera, frame), spheres=spheres,
                               lights=lights, sphere_sets=sphere_sets, meshes=meshes)
