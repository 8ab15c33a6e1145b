"""The baseline: the article's algorithm written the obvious vectorised way.

Every optimisation in Glint is measured against this, so it is plain but not wasteful:
float64, the article's semantics and formulas (docs/article.md), and ONE broadcast of all rays
still going against all spheres per intersection pass.  No tiles, no culling (every ray is
tested against every sphere), no threads.

Layout: n rays are (3, n) arrays (one row per coordinate) and ray-sphere quantities are
(m, n) arrays (one row per sphere).  This is the ordinary NumPy idiom of keeping the long
axis last; (n, 3) and (n, m) arrays would make every broadcast run inner loops only 3 or m
long, several times slower for no reason a straightforward implementation would accept.

``render`` traces every pixel in one go (the timed contender).  ``render_in_chunks`` traces
the same rays a band of rows at a time; it exists only to compute float64 reference images of
scenes too big for one broadcast (its results are identical, row for row).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core import Scene, ScreenCamera

#: The article's shadow and reflection offset along the normal.
SHIFT = 1e-5


@dataclass(frozen=True)
class ArticleScene:
    """The spheres (m of them) and the single light as float64 arrays, coordinates first."""

    centers: np.ndarray      # (3, m)
    radii: np.ndarray        # (m,)
    ambient: np.ndarray      # (3, m)
    diffuse: np.ndarray      # (3, m)
    specular: np.ndarray     # (3, m)
    exponent: np.ndarray     # (m,) shininess / 4
    reflection: np.ndarray   # (m,)
    light: np.ndarray        # (3, 1)
    light_ambient: np.ndarray    # (3, 1)
    light_diffuse: np.ndarray    # (3, 1)
    light_specular: np.ndarray   # (3, 1)
    eye: np.ndarray          # (3, 1)


def article_arrays(scene: Scene) -> ArticleScene:
    """The arrays of a scene the article's program can express: a ScreenCamera, one light."""
    if not isinstance(scene.camera, ScreenCamera):
        raise ValueError("the baseline renders ScreenCamera scenes only (the article's camera)")
    if len(scene.lights) != 1:
        raise ValueError(f"the baseline renders scenes with exactly one light, "
                         f"got {len(scene.lights)}")
    spheres, light = scene.spheres, scene.lights[0]

    def per_sphere(name):
        return np.array([getattr(s.material, name) for s in spheres], np.float64)

    def column(vector):
        return np.array(vector, np.float64).reshape(3, 1)

    return ArticleScene(
        centers=np.array([s.center for s in spheres], np.float64).reshape(-1, 3).T.copy(),
        radii=np.array([s.radius for s in spheres], np.float64),
        ambient=per_sphere("ambient").reshape(-1, 3).T.copy(),
        diffuse=per_sphere("diffuse").reshape(-1, 3).T.copy(),
        specular=per_sphere("specular").reshape(-1, 3).T.copy(),
        exponent=per_sphere("shininess") / 4,
        reflection=per_sphere("reflection"),
        light=column(light.position),
        light_ambient=column(light.ambient),
        light_diffuse=column(light.diffuse),
        light_specular=column(light.specular),
        eye=column(scene.camera.eye),
    )


def _dot(a, b):
    """Dot products of (3, ...) arrays over their first axis."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _normalize(v):
    return v / np.sqrt(_dot(v, v))


def nearest(arrays: ArticleScene, origins, directions):
    """(index (n,), distance (n,)) of the nearest sphere hit by each ray; -1 / inf for none.

    origins (3, n) or (3, 1), directions (3, n) unit.  The article's test, broadcast to
    (m, n): both roots must be positive and the discriminant strictly so; ties go to the
    sphere listed first (argmin's first minimum).
    """
    # (m, n) per coordinate: o_k - c_k for every sphere and ray.
    offsets = [origins[k][None, :] - arrays.centers[k][:, None] for k in range(3)]
    b = 2 * (directions[0] * offsets[0] + directions[1] * offsets[1]
             + directions[2] * offsets[2])
    c = (np.sqrt(offsets[0] ** 2 + offsets[1] ** 2 + offsets[2] ** 2) ** 2
         - (arrays.radii ** 2)[:, None])
    delta = b ** 2 - 4 * c
    root = np.sqrt(np.maximum(delta, 0.0))
    t1 = (-b + root) / 2
    t2 = (-b - root) / 2
    hit = (delta > 0) & (t1 > 0) & (t2 > 0)
    distances = np.where(hit, np.minimum(t1, t2), np.inf)
    index = np.argmin(distances, axis=0)
    distance = np.take_along_axis(distances, index[None, :], axis=0)[0]
    index[~np.isfinite(distance)] = -1
    return index, distance


def trace(arrays: ArticleScene, origins, directions, max_depth: int = 3):
    """(rgb (3, n) clipped to [0, 1], covered (n,) bool: the camera ray hit a sphere).

    Each bounce carries on only the rays still going (hit, and not shadowed), indexed by the
    pixel they belong to: the article's ``break``s, vectorised."""
    n = directions.shape[1]
    colour = np.zeros((3, n))
    covered = np.zeros(n, bool)
    pixel = np.arange(n)
    reflection = np.ones(n)
    for depth in range(max_depth):
        index, distance = nearest(arrays, origins, directions)
        hit = index >= 0
        if depth == 0:
            covered[hit] = True
        pixel, index, distance, reflection = pixel[hit], index[hit], distance[hit], reflection[hit]
        origins = origins if origins.shape[1] == 1 else origins[:, hit]
        directions = directions[:, hit]
        if not len(pixel):
            break
        point = origins + distance * directions
        normal = _normalize(point - arrays.centers[:, index])
        shifted = point + SHIFT * normal
        to_light = _normalize(arrays.light - shifted)
        _, blocker = nearest(arrays, shifted, to_light)
        light_distance = np.sqrt(_dot(arrays.light - point, arrays.light - point))
        lit = ~(blocker < light_distance)

        pixel, index, reflection = pixel[lit], index[lit], reflection[lit]
        point, normal, shifted = point[:, lit], normal[:, lit], shifted[:, lit]
        to_light, directions = to_light[:, lit], directions[:, lit]
        to_camera = _normalize(arrays.eye - point)
        halfway = _normalize(to_light + to_camera)
        illumination = (
            arrays.ambient[:, index] * arrays.light_ambient
            + arrays.diffuse[:, index] * arrays.light_diffuse * _dot(to_light, normal)
            + arrays.specular[:, index] * arrays.light_specular
            * _dot(normal, halfway) ** arrays.exponent[index])
        colour[:, pixel] += reflection * illumination
        reflection = reflection * arrays.reflection[index]

        origins = shifted
        directions = directions - 2 * _dot(directions, normal) * normal
    return np.clip(colour, 0, 1), covered


def camera_rays(camera: ScreenCamera, rows=None):
    """(origins (3, 1), directions (3, n)) through the article's linspace pixel positions, in
    row-major order, for all rows or the given row indices."""
    xs = np.linspace(camera.left, camera.right, camera.width)
    ys = np.linspace(camera.top, camera.bottom, camera.height)
    if rows is not None:
        ys = ys[rows]
    grid_y, grid_x = np.meshgrid(ys, xs, indexing="ij")
    eye = np.array(camera.eye, np.float64).reshape(3, 1)
    pixels = np.stack([grid_x.ravel(), grid_y.ravel(), np.full(grid_x.size, camera.screen_z)])
    return eye, _normalize(pixels - eye)


def _image(rgb, covered, height, width):
    rgba = np.empty((height, width, 4))
    rgba[..., :3] = rgb.T.reshape(height, width, 3)
    rgba[..., 3] = covered.reshape(height, width)
    return rgba


def render(scene: Scene, max_depth: int = 3) -> np.ndarray:
    """(H, W, 4) float64, row 0 = top: RGB as the article computes it, alpha = coverage."""
    camera = scene.camera
    origins, directions = camera_rays(camera)
    rgb, covered = trace(article_arrays(scene), origins, directions, max_depth)
    return _image(rgb, covered, camera.height, camera.width)


def render_in_chunks(scene: Scene, max_depth: int = 3, max_elements: int = 20_000_000):
    """The same image as ``render``, a band of rows at a time, keeping each (m, n) array
    under ``max_elements``: for references of scenes one broadcast cannot hold."""
    camera = scene.camera
    arrays = article_arrays(scene)
    rows_per_band = max(1, max_elements // max(1, camera.width * len(arrays.radii)))
    bands = []
    for start in range(0, camera.height, rows_per_band):
        rows = np.arange(start, min(start + rows_per_band, camera.height))
        origins, directions = camera_rays(camera, rows)
        rgb, covered = trace(arrays, origins, directions, max_depth)
        bands.append(_image(rgb, covered, len(rows), camera.width))
    return np.concatenate(bands, axis=0)


def one_broadcast_bytes(scene: Scene) -> int:
    """Size of one (m, n) float64 array of ``render``'s broadcast: what decides whether the
    baseline fits in memory (it holds about ten of them at once)."""
    camera = scene.camera
    return camera.width * camera.height * len(scene.spheres) * 8
