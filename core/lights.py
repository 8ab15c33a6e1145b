"""Blender's lights in Cycles' units: where each light is sampled and how much it delivers.

Every light is reduced to S deterministic samples.  For each shaded point P (normal N) and
sample j, ``sample_irradiance`` gives the unit direction w_j towards the light, the distance
and the irradiance e_j (W/m^2 per unit of ``PreparedLight.scale``) *including* the receiver's
cos(theta_i) = N.w_j, so that a Lambertian albedo a reflects radiance ``scale a sum_j e_j / pi``
(``core.bsdf``), as Cycles' direct light does.  The factors, light by light:

* Sphere (point) light of power P W and colour c.  Cycles spreads P evenly over the sphere of
  directions: radiant intensity I = P c / (4 pi) W/sr.  At distance d the irradiance on a
  surface turned theta from the light is E = I cos(theta) / d^2 (inverse square law, Lambert's
  cosine), and a Lambertian BRDF is a / pi, so L = a P cos(theta) / (4 pi^2 d^2): the
  factor 1/(4 pi) is the sphere's solid angle, the second 1/pi the diffuse BRDF's
  normalisation.  (Checked headless against Cycles with max_bounces = 0: 0.783 vs 0.792 for
  a = 0.5, P = 1000 W, d = 4, the pixels' cos(theta) accounting for the 1 %.)  A radius r
  makes the light a disc of radius r facing the point (Cycles' sampling of a sphere light):
  its solid angle pi r^2 / (d^2 + r^2) replaces pi r^2 / d^2, so E = I cos(theta) /
  (d^2 + r^2) (measured: r = 0.6 at d = 3.5 is 3 % dimmer in Cycles than the point formula,
  and (r / d)^2 = 2.9 %), and shadows are soft: visibility is the share of that disc the
  point sees, estimated from 2 S fixed points spread over the sphere (S Fibonacci points and
  their antipodes, so that their shadow
  rays share origins): each point j of the hemisphere facing P counts with weight
  n_j . w, w the unit direction from the light's centre to P, which turns the hemisphere's
  uniform spread into a uniform spread over the disc it projects to.
* Spot light: the sphere light times Cycles' ``spot_attenuation``,
  smoothstep(0, 1, (cos(phi) - cos(size / 2)) / ((1 - cos(size / 2)) blend)), phi the angle
  from the spot's axis (a hard edge for blend = 0).  The power is *not* concentrated into
  the cone: a spot is a masked point light, so inside the cone it equals a point light of
  the same power (checked headless: ratio 1.000 on the axis).
* Sun of strength S W/m^2: the irradiance of a surface facing it is S, so E = S c cos(theta)
  and L = a S cos(theta) / pi (checked headless: 0.475 vs 0.477).  An angle alpha spreads
  the samples over a disc of directions of half-angle alpha / 2 (soft shadows); E keeps the
  centre's cos(theta).
* Area light of power P and area A (square, rectangle, disk, ellipse; one-sided towards the
  light's -Z): a Lambertian emitter of radiance L_e = P c / (pi A) (Cycles'
  ``eval_fac = 0.25 invarea`` on a strength that Blender's light sync scales by 4 / pi;
  checked headless: a small square light gives 4.00x the point light of the same power at
  the same distance, and 4 = (1 / (pi A)) A / (1 / (4 pi))).  The irradiance
  E = integral L_e cos(theta_l) cos(theta_i) / d^2 dA is a sum over S stratified points of
  the light (equal areas A / S; disks by Shirley & Chiu's concentric map), each with its own
  direction, distance and visibility: e_j = cos(theta_l) cos(theta_i) / (S d_j^2), scale =
  P c / pi.

Shadow rays from a light's samples share an origin (a ``SharedOrigin`` per sample, as for the
article's lights); a sun's rays leave the points instead.

Sample shares.  A pixel given S anti-aliasing samples does not trace all of a light's F
samples from each of them (S F shadow rays per pixel and light): as a path tracer takes one
light sample per camera sample, its AA sample of slot s (``SampleShares``) traces only the
light samples j = s (mod S) when S <= F (about F / S of them), or the one sample
j = floor(s F / S) when S > F, each weighted so that the pixel's mean weighs every sample as
the full estimate does (``share_weights``).  The S slots cover the F samples, so the pixel as
a whole sees every stratum of the light (each once when S <= F), with max(F, S) shadow rays.

Adaptive AA stops many pixels after a prefix of their samples (4, 8, ...), so every prefix
must see the light evenly, not one end of it: sample k of a pixel takes slot
(``progressive_order(S)[k]`` + h) mod S, h a hash of the pixel (``pixel_shares``; the hash
makes which sub-pixel position sees which part of the light differ from pixel to pixel), so
the first 4 slots of any pixel lie in the 4 quarters of [0, S), the first 8 in its eighths;
and a light's samples are stored so that such slots pick spread samples: the Fibonacci
sphere's run from pole to pole, and the k x k grids (``_grid``) are numbered along
diagonals, so that the samples j = h + S t / 4 (t = 0..3) of a 4 x 4 grid hold one cell of
every row and every column.  (With consecutive slots, the first 4 samples of a pixel saw
only the pole of a sphere light nearest one end of the sequence: where that pole was hidden
or below a face's horizon, a pixel stopped there came out black.)  Pixel-centre passes (no
AA, adaptive AA's first pass) have no shares: every point traces every sample.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .light_sources import AreaLight, SphereLight, SpotLight, SunLight
from .vectors import dot, normalize


@dataclass(frozen=True)
class PreparedLight:
    """A light ready for shading (float64).

    kind: 'sphere' (point and spot: irradiance from the centre, visibility from the samples),
        'area' (every sample its own direction and irradiance) or 'sun' (samples are
        directions towards the light).
    scale: (3,) colour x the light's constant factor (module docstring).
    centre: (3,) position, or the unit direction towards the sun.
    samples: (S, 3) sample positions on the light, or unit directions towards the sun.
    terms: the geometry's ``SharedOrigin`` per sample position (empty for a sun).
    radius: a sphere light's radius; sample_normals (S, 3): its samples' outward normals.
    normal: (3,) an area light's emitting direction.  axis, cos_half, blend: a spot's cone.
    """

    kind: str
    scale: np.ndarray
    centre: np.ndarray
    samples: np.ndarray
    terms: tuple
    radius: float = 0.0
    sample_normals: np.ndarray | None = None
    normal: np.ndarray | None = None
    axis: np.ndarray | None = None
    cos_half: float = -1.0
    blend: float = 0.0


@dataclass(frozen=True)
class SampleShares:
    """Which share of every light's samples each of n rays' paths traces (module docstring):
    slot (n,) intp in [0, count), count the S >= 2 anti-aliasing samples of the ray's pixel
    (``pixel_shares``)."""

    slot: np.ndarray
    count: int

    def take(self, index) -> "SampleShares":
        """The shares of rays ``index`` (k,) (the paths that go on, the points shaded)."""
        return SampleShares(self.slot[index], self.count)


def progressive_order(count: int) -> np.ndarray:
    """(count,) a permutation of range(count) whose every prefix is spread evenly over
    [0, count): the van der Corput (bit-reversal) order, 0, 8, 4, 12, 2, 10, ... for 16, its
    values scaled to count (first occurrences) when count is not a power of two."""
    bits = max(1, (count - 1).bit_length())
    index = np.arange(1 << bits)
    reversed_bits = np.zeros_like(index)
    for bit in range(bits):
        reversed_bits |= ((index >> bit) & 1) << (bits - 1 - bit)
    position = (reversed_bits * count) >> bits
    _, first = np.unique(position, return_index=True)
    return position[np.sort(first)]


def pixel_shares(cols, rows, count: int) -> SampleShares | None:
    """The shares of ``count`` AA samples in each pixel (cols, rows) (n,), pixel by pixel
    (n * count rays, a pixel's samples side by side as ``core.render`` traces them): sample k
    of a pixel takes slot (progressive_order(count)[k] + h) mod count, h an integer hash of
    the pixel's position (so the slots do not depend on tiles, bundles or threads).  None for
    one sample per pixel: it traces every light sample, as a pixel centre does."""
    if count <= 1:
        return None
    shift = (_pixel_hash(cols, rows) % np.uint64(count)).astype(np.intp)
    slot = (progressive_order(count)[None, :] + shift[:, None]) % count
    return SampleShares(slot.ravel(), count)


def pixel_shifts(cols, rows) -> np.ndarray:
    """(n, 2) a point of [0, 1)^2 for each pixel (cols, rows) (n,), from a hash of its
    position: the Cranley-Patterson rotation by which the world's grid of occlusion
    directions differs from pixel to pixel (``shifted_cosine_direction``).  White noise
    rather than a low-discrepancy sequence over the pixels: an additive recurrence over
    the pixels' indices (the R2 sequence) drew a regular hatching where the world is
    partly hidden.  Deterministic, so the same for any tiling, bundle or thread."""
    h = _pixel_hash(cols, rows)
    h ^= h >> np.uint64(31)              # splitmix64's finaliser: bits apart from the slots'
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(27)
    h *= np.uint64(0x94D049BB133111EB)
    h ^= h >> np.uint64(31)
    scale = 1.0 / (1 << 24)
    return np.stack([(h >> np.uint64(40)).astype(np.float64) * scale,
                     ((h >> np.uint64(16)) & np.uint64(0xFFFFFF)).astype(np.float64) * scale],
                    axis=1)


def _pixel_hash(cols, rows) -> np.ndarray:
    """(n,) uint64 an integer hash of each pixel's position (cols, rows) (n,)."""
    x = np.asarray(cols, np.int64).astype(np.uint64)
    y = np.asarray(rows, np.int64).astype(np.uint64)
    h = x * np.uint64(0x9E3779B1) ^ y * np.uint64(0x85EBCA77)
    h ^= h >> np.uint64(15)
    h *= np.uint64(0x2C1B3C6D)
    h ^= h >> np.uint64(12)
    return h


def share_weights(shares: SampleShares, count: int) -> np.ndarray:
    """(count, m): how much each of a light's ``count`` samples j counts at each of m points
    whose shares are ``shares`` (m slots): 0 where the point does not trace it, else S / u_j,
    u_j the number of a pixel's S slots that trace sample j (module docstring: j = s mod S,
    or j = floor(s count / S) when S > count).  A sample weighted w_j in the full estimate
    then adds w_j S / u_j in each of the u_j samples of a pixel that trace it, so the
    pixel's mean weighs it w_j exactly, as a pixel centre tracing all samples does."""
    total = shares.count
    sample = np.arange(count)
    if total <= count:
        uses = np.ones(count)
        chosen = (sample % total)[:, None] == shares.slot[None, :]
    else:
        # Slots s with floor(s count / total) = j: from ceil(j total / count) on.
        starts = -(-np.arange(count + 1) * total // count)
        uses = np.diff(starts).astype(np.float64)
        chosen = sample[:, None] == (shares.slot * count // total)[None, :]
    return np.where(chosen, (total / uses)[:, None], 0.0)


def _grid(count: int) -> np.ndarray:
    """k x k cell centres (k^2, 2) in (-1, 1)^2, k = ceil(sqrt(count)) (>= count points),
    numbered along diagonals: sample k r + d is the cell of row r and column (r + d) mod k,
    so that samples d + k t of any fixed d (the strided slots of a pixel's first samples,
    module docstring) hold one cell of every row and every column."""
    k = max(1, math.ceil(math.sqrt(count)))
    cells = (np.arange(k) + 0.5) / k * 2.0 - 1.0
    row, diagonal = np.divmod(np.arange(k * k), k)
    return np.stack([cells[row], cells[(row + diagonal) % k]], axis=1)


def concentric_disk(square: np.ndarray) -> np.ndarray:
    """Shirley & Chiu's area-preserving map of (n, 2) points of [-1, 1]^2 onto the unit disk."""
    a, b = square[:, 0], square[:, 1]
    first = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, a, b)
        phi = np.where(first, (math.pi / 4) * b / a, math.pi / 2 - (math.pi / 4) * a / b)
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def fibonacci_sphere(count: int) -> np.ndarray:
    """count well-spread unit vectors (count, 3), deterministic."""
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    rho = np.sqrt(1.0 - z * z)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def _tangents(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    first = np.cross(direction, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(direction, first)


def prepare_light(light, light_samples: int, geometry) -> PreparedLight:
    """A SphereLight, SpotLight, SunLight or AreaLight as a PreparedLight; ``light_samples``
    samples for lights with an extent (radius, angle, area), one otherwise.  geometry: the
    scene's ``Aggregate``, which makes the shadow rays' shared-origin terms."""
    colour = np.asarray(light.colour, np.float64)
    terms_at = lambda points: tuple(geometry.shared_origin(p) for p in points)  # noqa: E731
    if isinstance(light, SunLight):
        towards = -np.asarray(light.direction, np.float64)
        if light.angle > 0:
            first, second = _tangents(towards)
            disk = concentric_disk(_grid(light_samples)) * math.tan(light.angle / 2)
            samples = towards + disk[:, :1] * first + disk[:, 1:] * second
            samples /= np.linalg.norm(samples, axis=1, keepdims=True)
        else:
            samples = towards[None, :]
        return PreparedLight("sun", colour * light.strength, towards, samples, ())
    if isinstance(light, AreaLight):
        centre = np.asarray(light.position, np.float64)
        grid = _grid(light_samples)
        if light.shape in ("DISK", "ELLIPSE"):
            grid = concentric_disk(grid)
        samples = (centre + 0.5 * light.size_x * grid[:, :1] * np.asarray(light.axis_x)
                   + 0.5 * light.size_y * grid[:, 1:] * np.asarray(light.axis_y))
        return PreparedLight("area", colour * light.power / math.pi, centre, samples,
                             terms_at(samples), normal=np.asarray(light.direction, np.float64))
    if isinstance(light, (SphereLight, SpotLight)):
        centre = np.asarray(light.position, np.float64)
        normals = None
        if light.radius > 0:
            # Samples j and j + S are antipodes, so a sample share (module docstring) of
            # j = s (mod S) always holds as many samples facing a point as not.
            normals = fibonacci_sphere(light_samples)
            normals = np.concatenate([normals, -normals])
        samples = centre[None, :] if normals is None else centre + light.radius * normals
        prepared = dict(kind="sphere", scale=colour * light.power / (4 * math.pi),
                        centre=centre, samples=samples, terms=terms_at(samples),
                        radius=light.radius, sample_normals=normals)
        if isinstance(light, SpotLight):
            prepared.update(axis=np.asarray(light.direction, np.float64),
                            cos_half=math.cos(light.spot_size / 2), blend=light.spot_blend)
        return PreparedLight(**prepared)
    raise TypeError(f"not a Blender light type: {type(light).__name__}")


def spot_attenuation(light: PreparedLight, from_light) -> np.ndarray:
    """(m,) Cycles' spot mask for unit directions (3, m) from the light towards the points."""
    cos_angle = dot(from_light, light.axis[:, None].astype(from_light.dtype))
    if light.blend <= 0:
        return (cos_angle > light.cos_half).astype(from_light.dtype)
    x = np.clip((cos_angle - light.cos_half) / ((1.0 - light.cos_half) * light.blend), 0, 1)
    return x * x * (3 - 2 * x)


def centre_irradiance(light: PreparedLight, points, normals):
    """For 'sphere' and 'sun' lights: (towards (3, m) unit, distance (m,), e (m,) irradiance
    per unit scale including cos(theta_i), 0 where the light is behind the surface)."""
    dtype = points.dtype
    if light.kind == "sun":
        towards = np.broadcast_to(light.centre.astype(dtype)[:, None], points.shape)
        cos_i = dot(normals, towards)
        return towards, np.full(points.shape[1], np.inf, dtype), np.maximum(cos_i, 0)
    towards, distance = normalize(light.centre.astype(dtype)[:, None] - points)
    cos_i = dot(normals, towards)
    e = np.maximum(cos_i, 0) / (distance * distance + light.radius ** 2)
    if light.axis is not None:
        e = e * spot_attenuation(light, -towards)
    return towards, distance, e


def area_sample_irradiance(light: PreparedLight, sample: int, points, normals):
    """For 'area' lights, sample j: (towards (3, m), distance (m,), e_j (m,)) (module doc)."""
    dtype = points.dtype
    towards, distance = normalize(light.samples[sample].astype(dtype)[:, None] - points)
    cos_i = np.maximum(dot(normals, towards), 0)
    cos_l = np.maximum(-dot(towards, light.normal.astype(dtype)[:, None]), 0)
    e = cos_i * cos_l / (len(light.samples) * distance * distance)
    return towards, distance, e



def cosine_directions(count: int) -> np.ndarray:
    """(k^2, 3) directions over the hemisphere around +Z, k = ceil(sqrt(count)), spread with
    density cos(theta) / pi (Malley's method: a stratified disc lifted onto the hemisphere),
    so that their plain mean of visibility is the cosine-weighted share of the sky seen."""
    return _lifted(concentric_disk(_grid(count)))


def shifted_cosine_direction(count: int, sample: int, shift: np.ndarray) -> np.ndarray:
    """(3, m) direction ``sample`` of ``cosine_directions(count)`` for m points, each moved
    within its cell of the k x k grid by its point's ``shift`` (m, 2) in [0, 1)^2 (0.5, 0.5:
    the cell's centre, the unshifted direction).  Every point's k^2 directions are then a
    grid shifted as a whole (a Cranley-Patterson rotation, ``pixel_shifts``): still one in
    every cell, with density cos(theta) / pi over the shifts, but not the same k^2 lines
    for every point of a flat surface, whose occluders would cast k^2 sharp copies of
    their shadows there."""
    grid = _shared_grid(count)
    side = math.isqrt(len(grid))
    return _lifted(concentric_disk(grid[sample] + (shift - 0.5) * (2.0 / side))).T


@functools.lru_cache(maxsize=16)
def _shared_grid(count: int) -> np.ndarray:
    grid = _grid(count)
    grid.flags.writeable = False
    return grid


def _lifted(disk: np.ndarray) -> np.ndarray:
    """(n, 3) points of the unit disk (n, 2) lifted onto the hemisphere around +Z."""
    z = np.sqrt(np.maximum(1 - (disk ** 2).sum(axis=1), 0))
    return np.concatenate([disk, z[:, None]], axis=1)
