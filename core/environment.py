"""An environment map for the integrator: the world's image seen in every direction, and the
distribution Cycles samples its background light with (``scene/light.cpp``
``background_cdf`` and ``kernel/light/background.h`` ``background_map_sample`` /
``background_map_pdf``).

The map is a grid of res_x x res_y cells over the equirectangular parametrisation of world
directions (u = 0.5 - atan2(y, x) / 2 pi, v = 1 - theta / pi: row 0 looks down, -Z).  Each
cell's weight is the mean of its centre's |radiance| (R, G and B: Cycles' ``average``, not a
luminance) times sin(theta) at its centre, the cell's share of the sphere.  Directions are
drawn as Cycles draws them: a row from the marginal CDF of the rows' sums, a column from that
row's conditional CDF, each position within its cell linearly, so the density per solid
angle is weight / (2 pi^2 sin(theta) total) with theta the drawn direction's own.

Resolution: Cycles' World > Settings > Sampling "Auto" builds the map at the environment
image's own size (its "Manual" map resolution R at R x R/2), which resolves every texel's
own brightness, a small bright sun included; a coarser grid smears a sun over a cell and
raises the variance of what it lights.  The default here is the same; memory is 8 bytes a
cell (float32 weights and CDF, as Cycles keeps its CDFs), 0.27 GB for an 8k x 4k map.

The radiance of a direction is the Environment Texture's lookup (``core.shader.images``),
Linear, after the world rotation (the Mapping node's rotation in front of the texture: the
image is read at rotation @ direction).
"""

from __future__ import annotations

import numpy as np

from .shader.images import ImageData, environment_uv, image_from_pixels, lookup

#: Cells whose radiance is looked up at once while the map is built.
BLOCK_CELLS = 1 << 20


def equirectangular_directions(u, v):
    """(3, n) unit directions at equirectangular coordinates (u, v) (arrays): Cycles'
    ``equirectangular_to_direction``, the inverse of ``shader.images.equirectangular_uv``."""
    phi = np.pi - 2 * np.pi * np.asarray(u, np.float64)
    theta = np.pi * (1 - np.asarray(v, np.float64))
    sin_theta = np.sin(theta)
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), np.cos(theta)])


class EnvironmentMap:
    """The world's environment image as a light: ``radiance``, ``sample`` and ``pdf`` of
    world directions (module docstring).

    image: the Environment Texture's ImageData (or ``from_array``).
    rotation: (3, 3) the image is read at rotation @ direction (None: identity).
    projection: the texture's projection ('EQUIRECTANGULAR' or 'MIRROR_BALL').
    resolution: (res_x, res_y) of the sampling grid; None: the image's size (Cycles' Auto).
    strength: the Background's strength, multiplying the radiance.
    """

    def __init__(self, image: ImageData, rotation=None, projection: str = "EQUIRECTANGULAR",
                 resolution=None, strength: float = 1.0):
        self.image = image
        self.rotation = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
        if self.rotation.shape != (3, 3) or not np.all(np.isfinite(self.rotation)):
            raise ValueError(f"environment '{image.name}': rotation must be a finite 3x3 "
                             f"matrix, got {np.shape(rotation)}")
        self.projection = projection
        self.strength = float(strength)
        res_x, res_y = (image.width, image.height) if resolution is None else resolution
        if int(res_x) < 1 or int(res_y) < 1:
            raise ValueError(f"environment '{image.name}': resolution must be positive, got "
                             f"{resolution}")
        self.res_x, self.res_y = int(res_x), int(res_y)
        self._build()

    @classmethod
    def from_array(cls, name: str, rgb, **settings) -> "EnvironmentMap":
        """A map of an (H, W, 3) float radiance image whose row 0 is the top (+Z)."""
        rgb = np.asarray(rgb, np.float32)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"environment '{name}': image must be (H, W, 3), got {rgb.shape}")
        return cls(image_from_pixels(name, rgb[::-1].copy()), **settings)

    # --- the distribution ---------------------------------------------------------------

    def _build(self) -> None:
        res_x, res_y = self.res_x, self.res_y
        sin_theta = np.sin(np.pi * (np.arange(res_y) + 0.5) / res_y)
        weights = np.empty((res_y, res_x), np.float32)
        centre_u = (np.arange(res_x) + 0.5) / res_x
        block = max(1, BLOCK_CELLS // res_x)
        for first in range(0, res_y, block):   # blocks of rows: bounded temporaries
            rows = np.arange(first, min(first + block, res_y))
            u = np.tile(centre_u, len(rows))
            v = np.repeat((rows + 0.5) / res_y, res_x)
            radiance = self.radiance(equirectangular_directions(u, v))
            weights[rows] = (np.abs(radiance).mean(axis=0).reshape(len(rows), res_x)
                             * sin_theta[rows, None])
        weights[~np.isfinite(weights)] = 0
        if not weights.any():
            # A black environment: sample the sphere uniformly (no direction matters more).
            weights = np.repeat(sin_theta[:, None], res_x, axis=1)
        self.weights = weights                          # (res_y, res_x) |L| sin(theta)
        row_sums = weights.sum(axis=1, dtype=np.float64)
        self.total = row_sums.sum() / (res_x * res_y)   # Cycles' cdf_last_v.x
        # CDFs at the cells' left edges (Cycles' .y), rows normalised (a zero row stays 0),
        # accumulated in float64 and kept in float32.
        conditional = np.zeros((res_y, res_x), np.float32)
        for first in range(0, res_y, block):
            rows = slice(first, min(first + block, res_y))
            partial = np.cumsum(weights[rows, :-1], axis=1, dtype=np.float64)
            sums = row_sums[rows, None]
            conditional[rows, 1:] = np.divide(partial, sums, out=np.zeros_like(partial),
                                              where=sums > 0)
        self.conditional = conditional
        marginal = np.zeros(res_y)
        np.cumsum(row_sums[:-1], out=marginal[1:])
        marginal /= row_sums.sum()
        self.marginal = marginal

    # --- queries ------------------------------------------------------------------------

    def radiance(self, directions) -> np.ndarray:
        """(3, n) radiance seen in world directions (3, n): the Environment Texture's Linear
        lookup of rotation @ direction, times strength."""
        directions = np.asarray(directions, np.float64)
        u, v = environment_uv(self.rotation @ directions, self.projection)
        colour, _ = lookup(self.image, u, v, "Linear", "REPEAT", dtype=np.float64)
        if self.strength != 1:
            colour *= self.strength
        return colour

    def _cell_pdf(self, row, column, v):
        sin_theta = np.sin(np.pi * v)
        denominator = 2 * np.pi ** 2 * sin_theta * self.total
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = self.weights[row, column] / denominator
        return np.where((sin_theta > 0) & (denominator > 0), pdf, 0.0)

    def sample(self, u1, u2):
        """Directions drawn from the map for uniform numbers u1, u2 in [0, 1) (arrays of n):
        (directions (3, n), pdf (n,) per solid angle, radiance (3, n))."""
        u1 = np.asarray(u1, np.float64).reshape(-1)
        u2 = np.asarray(u2, np.float64).reshape(-1)
        res_x, res_y = self.res_x, self.res_y
        # Cycles' lower_bound on the marginal CDF, then one step back.
        row = np.maximum(np.searchsorted(self.marginal, u2, side="left") - 1, 0)
        next_marginal = np.append(self.marginal, 1.0)
        low, high = self.marginal[row], next_marginal[row + 1]
        dv = np.divide(u2 - low, high - low, out=np.zeros_like(u2), where=high > low)
        v = (row + dv) / res_y
        column = np.maximum(self._lower_bound(row, u1) - 1, 0)
        low = self.conditional[row, column]
        high = np.where(column + 1 < res_x,
                        self.conditional[row, np.minimum(column + 1, res_x - 1)], 1.0)
        du = np.divide(u1 - low, high - low, out=np.zeros_like(u1), where=high > low)
        u = (column + du) / res_x
        directions = equirectangular_directions(u, v)
        return directions, self._cell_pdf(row, column, v), self.radiance(directions)

    def _lower_bound(self, row, value):
        """Per point, the first column whose CDF (in its row) is >= value, res_x if none:
        a binary search over all points at once (log2 res_x steps)."""
        low = np.zeros(len(row), np.int64)
        high = np.full(len(row), self.res_x, np.int64)
        while True:
            open_ = low < high
            if not open_.any():
                return low
            middle = (low + high) // 2
            right = open_ & (self.conditional[row, np.minimum(middle, self.res_x - 1)] < value)
            low = np.where(right, middle + 1, low)
            high = np.where(open_ & ~right, middle, high)

    def pdf(self, directions) -> np.ndarray:
        """(n,) the density per solid angle with which ``sample`` draws world directions
        (3, n) (Cycles' ``background_map_pdf``)."""
        directions = np.asarray(directions, np.float64)
        x, y, z = directions
        length = np.sqrt(x * x + y * y + z * z)
        u = 0.5 - np.arctan2(y, x) / (2 * np.pi)
        with np.errstate(invalid="ignore", divide="ignore"):
            v = 1 - np.arccos(np.clip(z / length, -1, 1)) / np.pi
        column = np.clip((u * self.res_x).astype(np.int64), 0, self.res_x - 1)
        row = np.clip((v * self.res_y).astype(np.int64), 0, self.res_y - 1)
        return self._cell_pdf(row, column, v)


class SunGuidedMap:
    """A world's map and a sun disc in it sampled on its own, as Cycles samples a Sky
    Texture's sun (``background_sun_sample``): with probability ``sun_probability`` a
    direction uniform in the cone of ``half_angle`` about ``direction``, else one drawn from
    ``environment`` (an EnvironmentMap); the density of either is the mixture of both, so
    that directions found by BSDF rays weigh the same way (one-sample multiple importance
    sampling).  Cycles weighs the sun 4 to the map's 1."""

    def __init__(self, environment: EnvironmentMap, direction, half_angle: float,
                 sun_probability: float = 0.8):
        self.environment = environment
        self.direction = np.asarray(direction, np.float64).reshape(3)
        self.cos_half_angle = float(np.cos(half_angle))
        self.sun_probability = float(sun_probability)
        # Two unit vectors across the sun's direction.
        helper = np.array([1.0, 0.0, 0.0]) if abs(self.direction[0]) < 0.9 else np.array(
            [0.0, 1.0, 0.0])
        across = np.cross(self.direction, helper)
        self.across = across / np.linalg.norm(across)
        self.up = np.cross(self.direction, self.across)

    def _cone_pdf(self, directions):
        inside = (self.direction @ directions) > self.cos_half_angle
        return np.where(inside, 1 / (2 * np.pi * (1 - self.cos_half_angle)), 0.0)

    def pdf(self, directions) -> np.ndarray:
        """(n,) the density per solid angle with which ``sample`` draws unit directions."""
        directions = np.asarray(directions, np.float64)
        p = self.sun_probability
        return p * self._cone_pdf(directions) + (1 - p) * self.environment.pdf(directions)

    def sample(self, u1, u2):
        """Directions for uniform numbers u1, u2 in [0, 1) (arrays of n): (directions (3, n),
        pdf (n,), None: the world's radiance there is its program's to give)."""
        u1 = np.asarray(u1, np.float64).reshape(-1)
        u2 = np.asarray(u2, np.float64).reshape(-1)
        p = self.sun_probability
        sun = u1 < p
        directions = np.empty((3, len(u1)))
        if sun.any():
            cos_theta = 1 - u1[sun] / p * (1 - self.cos_half_angle)
            sin_theta = np.sqrt(np.maximum(1 - cos_theta * cos_theta, 0))
            phi = 2 * np.pi * u2[sun]
            directions[:, sun] = (self.direction[:, None] * cos_theta
                                  + self.across[:, None] * (sin_theta * np.cos(phi))
                                  + self.up[:, None] * (sin_theta * np.sin(phi)))
        if (~sun).any():
            drawn, _, _ = self.environment.sample((u1[~sun] - p) / (1 - p), u2[~sun])
            directions[:, ~sun] = drawn
        return directions, self.pdf(directions), None
