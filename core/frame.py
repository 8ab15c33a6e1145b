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
distance falloff; Blender's lights, whose irradiance falls off as power / d^2, have their
power scaled by scale^2 with it, ``_light``).

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

from .camera import BlenderCamera, ScreenCamera, eye_position
from .light_sources import AreaLight, SphereLight, SpotLight, SunLight
from .scene import Scene
from .settings import RenderSettings
from .validation import MAX_MAGNITUDE, SceneError

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


def sphere_groups(scene: Scene) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(centres (N, 3), radii (N,))]: the hand-made spheres, then each sphere set."""
    return [(np.array([s.center for s in scene.spheres], np.float64).reshape(-1, 3),
             np.array([s.radius for s in scene.spheres], np.float64))] + \
        [(s.centers, s.radii) for s in scene.sphere_sets]


def _sphere_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(lower (3,), upper (3,)) of every sphere (inf, -inf with none), an axis at a time: a
    reduction over an (N, 3) array's first axis, and its (N, 3) temporaries, cost 4x as much
    (a million spheres: 0.09 s)."""
    lower, upper = np.full(3, np.inf), np.full(3, -np.inf)
    for centres, radii in sphere_groups(scene):
        if len(radii):
            for axis in range(3):
                column = centres[:, axis]
                lower[axis] = min(lower[axis], np.subtract(column, radii).min())
                upper[axis] = max(upper[axis], np.add(column, radii).max())
    return lower, upper


def _mesh_boxes(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(lower (K, 3), upper (K, 3)) world-space boxes of every mesh instance: the object-space
    box's eight corners through each transform."""
    lowers, uppers = [np.empty((0, 3))], [np.empty((0, 3))]
    for mesh in scene.meshes:
        if len(mesh.vertices) == 0:
            continue
        low, high = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
        corners = np.array([[(high if (k >> a) & 1 else low)[a] for a in range(3)]
                            for k in range(8)])                          # (8, 3)
        world = (np.einsum("kij,cj->kci", mesh.transforms[:, :3, :3], corners)
                 + mesh.transforms[:, None, :3, 3])                      # (K, 8, 3)
        lowers.append(world.min(axis=1))
        uppers.append(world.max(axis=1))
    return np.concatenate(lowers), np.concatenate(uppers)


def scene_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(lower (3,), upper (3,)) of spheres, meshes, lights (with radii) and the camera."""
    placed = [light for light in scene.lights if not isinstance(light, SunLight)]  # no place
    lights = np.array([light.position for light in placed], np.float64).reshape(-1, 3)
    light_radii = np.array([light.radius for light in placed], np.float64)
    eye = eye_position(scene.camera)[None, :]
    mesh_low, mesh_high = _mesh_boxes(scene)
    sphere_low, sphere_high = _sphere_bounds(scene)
    lower = np.concatenate([eye, sphere_low[None, :], lights - light_radii[:, None],
                            mesh_low]).min(axis=0)
    upper = np.concatenate([eye, sphere_high[None, :], lights + light_radii[:, None],
                            mesh_high]).max(axis=0)
    return lower, upper


def scene_reach(scene: Scene) -> float:
    """The largest distance (per axis) from the camera's eye to anything a ray meets."""
    centre = eye_position(scene.camera)
    lower, upper = scene_bounds(scene)
    # Halves first: differences of values up to 1e300 apart must not overflow.
    return 2 * float(np.maximum(np.abs(lower / 2 - centre / 2),
                                np.abs(upper / 2 - centre / 2)).max())


def smallest_feature(scene: Scene) -> tuple[float, str]:
    """(size, what) of the scene's smallest object: a sphere's radius, or half the largest
    side of a mesh instance's box; (0, "") for a scene without any."""
    candidates = []
    if scene.spheres:
        smallest = min(range(len(scene.spheres)), key=lambda i: scene.spheres[i].radius)
        sphere = scene.spheres[smallest]
        label = f"sphere '{sphere.name}'" if sphere.name else f"sphere {smallest}"
        candidates.append((sphere.radius, label))
    for sphere_set in scene.sphere_sets:
        if len(sphere_set):
            i = int(sphere_set.radii.argmin())
            candidates.append((float(sphere_set.radii[i]),
                               f"sphere set '{sphere_set.name}' sphere {i}"))
    for mesh in scene.meshes:
        low, high = _mesh_boxes(Scene(camera=scene.camera, meshes=(mesh,)))
        if len(low):
            sizes = (high - low).max(axis=1) / 2
            i = int(sizes.argmin())
            if sizes[i] > 0:
                candidates.append((float(sizes[i]), f"mesh '{mesh.name}' instance {i}"))
    return min(candidates, default=(0.0, ""))


def scene_frame(scene: Scene) -> Frame:
    """The frame whose unit is the scene's smallest object, centred on the camera's eye
    (module docstring)."""
    centre = eye_position(scene.camera)
    unit = smallest_feature(scene)[0] or scene_reach(scene)
    if unit == 0.0:
        return Frame(centre, 1.0)
    exponent = math.frexp(unit)[1]  # unit = m 2^e, 0.5 <= m < 1
    return Frame(centre, math.ldexp(1.0, -exponent))


def check_resolvable(scene: Scene) -> None:
    """Raise SceneError when float64 cannot resolve the scene's smallest object from where
    rays reach."""
    reach = scene_reach(scene)
    if not math.isfinite(reach):
        raise SceneError(f"the scene's coordinates reach past {MAX_MAGNITUDE:g} (sphere sets, "
                         f"meshes or their transforms): scale the scene down")
    size, label = smallest_feature(scene)
    if size == 0.0:
        return
    ratio = reach / size
    if ratio > MAX_SCALE_RATIO:
        raise SceneError(
            f"{label} (size {size:g}) is {ratio:.1e} times smaller than the scene's extent "
            f"({farthest(scene)} reaches {reach:.1e} from the camera), more than the "
            f"{MAX_SCALE_RATIO:.0e} float64 can render exactly: enlarge it, or move far-away "
            f"objects, lights or the camera closer")


def farthest(scene: Scene) -> str:
    """What reaches farthest from the camera's eye (``scene_reach``'s measure): a sphere,
    a sphere set's sphere, a light or a mesh instance, named as ``smallest_feature`` names
    them (asked only to explain a refusal)."""
    centre = eye_position(scene.camera)

    def reach(lower, upper) -> np.ndarray:
        return np.maximum(np.abs(lower / 2 - centre / 2), np.abs(upper / 2 - centre / 2)).max(
            axis=-1)

    candidates = []
    for i, sphere in enumerate(scene.spheres):
        centre_of = np.asarray(sphere.center)
        label = f"sphere '{sphere.name}'" if sphere.name else f"sphere {i}"
        candidates.append((float(reach(centre_of - sphere.radius, centre_of + sphere.radius)),
                           label))
    for sphere_set in scene.sphere_sets:
        if len(sphere_set):
            radii = sphere_set.radii[:, None]
            far = reach(sphere_set.centers - radii, sphere_set.centers + radii)
            i = int(far.argmax())
            candidates.append((float(far[i]), f"sphere set '{sphere_set.name}' sphere {i}"))
    for light in scene.lights:
        if not isinstance(light, SunLight):
            position = np.asarray(light.position)
            candidates.append((float(reach(position - light.radius, position + light.radius)),
                               f"light '{light.name}'"))
    for mesh in scene.meshes:
        low, high = _mesh_boxes(Scene(camera=scene.camera, meshes=(mesh,)))
        if len(low):
            far = reach(low, high)
            i = int(far.argmax())
            candidates.append((float(far[i]), f"mesh '{mesh.name}' instance {i}"))
    return max(candidates, default=(0.0, "the camera"))[1]


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
        clip_end=capped(camera.clip_end),
        aperture_radius=capped(camera.aperture_radius),
        focus_distance=capped(camera.focus_distance))


def _light(light, frame: Frame):
    """A light in the canonical frame.  Positions and sizes move and scale like the geometry;
    Blender's positional lights also get power x scale^2, so that their irradiance
    power / d^2 (area lights: power / area, over a solid angle that does not change) is what
    it was; a sun only has a direction."""
    if isinstance(light, SunLight):
        return light
    if isinstance(light, AreaLight):
        return dataclasses.replace(light, position=frame.point(light.position),
                                   size_x=frame.length(light.size_x),
                                   size_y=frame.length(light.size_y),
                                   power=light.power * frame.scale ** 2)
    moved = dataclasses.replace(light, position=frame.point(light.position),
                                radius=frame.length(light.radius))
    if isinstance(light, (SphereLight, SpotLight)):
        moved = dataclasses.replace(moved, power=light.power * frame.scale ** 2)
    return moved


def canonical_scene(scene: Scene, settings: RenderSettings) -> Scene:
    """``scene`` in its canonical frame (module docstring); article semantics unchanged.
    Raises SceneError for a scene float64 cannot resolve."""
    check_resolvable(scene)
    if settings.semantics == "article":
        return scene
    frame = scene_frame(scene)
    spheres = _moved_spheres(scene.spheres, frame)
    sphere_sets = tuple(dataclasses.replace(
        s, centers=(s.centers - frame.centre) * frame.scale, radii=s.radii * frame.scale)
        for s in scene.sphere_sets)
    meshes = tuple(dataclasses.replace(mesh, transforms=_placed(mesh.transforms, frame))
                   for mesh in scene.meshes)
    lights = tuple(_light(light, frame) for light in scene.lights)
    return dataclasses.replace(scene, camera=_camera(scene.camera, frame), spheres=spheres,
                               sphere_sets=sphere_sets, meshes=meshes, lights=lights)


def _placed(transforms: np.ndarray, frame: Frame) -> np.ndarray:
    """Object-to-world matrices (K, 4, 4) -> object-to-canonical: scale the 3 x 3 part,
    move and scale the translation."""
    placed = np.array(transforms, np.float64, copy=True)
    placed[:, :3, :3] *= frame.scale
    placed[:, :3, 3] = (placed[:, :3, 3] - frame.centre) * frame.scale
    return placed


def _moved_spheres(spheres, frame: Frame) -> tuple:
    """The spheres in the canonical frame, all at once.  Built without Sphere's field-by-field
    validation (36 us a sphere, which dominated renders of 1e5 loose spheres): every value
    comes from a validated sphere through a power-of-two scale, so it stays finite, and a
    radius stays > 0 (the smallest becomes about 1, the others larger)."""
    if not spheres:
        return ()
    centres = (np.array([s.center for s in spheres], np.float64) - frame.centre) * frame.scale
    radii = np.array([s.radius for s in spheres], np.float64) * frame.scale
    moved = []
    for sphere, centre, radius in zip(spheres, centres.tolist(), radii.tolist()):
        copy = object.__new__(type(sphere))
        copy.__dict__.update(sphere.__dict__, center=tuple(centre), radius=radius)
        moved.append(copy)
    return tuple(moved)
