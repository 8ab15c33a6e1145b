"""Every random and low-discrepancy number a render draws: one sampler, deterministic.

A pixel's samples are points of a 4-dimensional Sobol sequence, Owen-scrambled and shuffled
per pixel (Burley 2020, "Practical Hash-based Owen Scrambling"), as Cycles' Sobol-Burley
sampler does: the first N samples of any pixel are well stratified in every 1D and 2D
projection of each group of 4 dimensions, and neighbouring pixels are decorrelated (no
pattern shows between them, the error is blue-ish noise).  A path needs more than 4
dimensions (the pixel position and the lens, then per bounce a light sample and a BSDF
sample): it draws them in groups of 4 (``DIMENSION``), each group with its own seed
("padding" by hashing, as Cycles does), so that the dimensions a pair is stratified in are
drawn from one group.

A number depends only on (pixel, sample index, dimension) and the frame's seed: never on
tiles, threads, processes or the order samples are traced in.  All arithmetic is on
uint32 arrays: wrap-around is the point, and NumPy does not warn about it on arrays.

The Direct integrator's fixed patterns live here too: a light's sample points
(``fibonacci_sphere``, ``concentric_disk`` over diagonal grids), the world's cosine
directions, and which of them each anti-aliasing sample of a pixel traces.

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
sphere's run from pole to pole, and the k x k grids (``diagonal_grid``) are numbered along
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

_U32 = np.uint32

#: Sobol generator matrices of the first 4 dimensions as 32 column vectors each, from the
#: primitive polynomials x + 1, x^2 + x + 1, x^3 + x + 1 with initial direction numbers
#: (Joe & Kuo 2008) 1; 1, 3; 1, 3, 1.  Dimension 0 is van der Corput's radical inverse.


def _direction_numbers(degree: int, coefficients: int, initial: tuple) -> np.ndarray:
    m = list(initial)
    for k in range(degree, 32):
        value = m[k - degree] ^ (m[k - degree] << degree)
        for i in range(1, degree):
            if (coefficients >> (degree - 1 - i)) & 1:
                value ^= m[k - i] << i
        m.append(value)
    return np.array([(m[k] << (31 - k)) & 0xFFFFFFFF for k in range(32)], np.uint64)


_MATRICES = np.stack([
    np.array([1 << (31 - k) for k in range(32)], np.uint64),
    _direction_numbers(1, 0, (1,)),
    _direction_numbers(2, 1, (1, 3)),
    _direction_numbers(3, 1, (1, 3, 1)),
]).astype(_U32)

#: The dimensions of a path's sample, group by group (4 each).  Group 0: the pixel
#: position and the lens; group 1 + 2 b and 2 + 2 b: bounce b's BSDF direction, light
#: position, then the choices (lobe, light, Russian roulette, spare).
PIXEL_GROUP = 0
GROUPS_PER_BOUNCE = 2


def bounce_groups(bounce: int) -> tuple[int, int]:
    """The two dimension groups of bounce ``bounce`` (0: the camera ray's first hit):
    (BSDF u, BSDF v, light u, light v) and (lobe, light choice, Russian roulette, spare)."""
    first = 1 + GROUPS_PER_BOUNCE * bounce
    return first, first + 1


def hash_u32(value) -> np.ndarray:
    """A 32-bit integer hash of uint32 values (array or scalar): Chris Wellons' lowbias32."""
    x = np.asarray(value, _U32).copy()
    x ^= x >> _U32(16)
    x *= _U32(0x7FEB352D)
    x ^= x >> _U32(15)
    x *= _U32(0x846CA68B)
    x ^= x >> _U32(16)
    return x


def pixel_seeds(cols, rows, frame_seed: int = 0) -> np.ndarray:
    """(n,) uint32 a seed per pixel (cols, rows) (n,), mixed with the frame's seed."""
    x = np.asarray(cols, np.int64).astype(_U32)
    y = np.asarray(rows, np.int64).astype(_U32)
    return hash_u32(hash_u32(x ^ hash_u32(np.uint32(frame_seed & 0xFFFFFFFF)))
                    ^ (y * _U32(0x9E3779B9)))


#: Each byte's bits reversed, for ``reverse_bits``.
_BYTE_REVERSED = np.array([int(f"{b:08b}"[::-1], 2) for b in range(256)], np.uint32)


def reverse_bits(x: np.ndarray) -> np.ndarray:
    """The 32 bits of each uint32 in reverse order: each byte reversed by a table, the
    bytes swapped (a third of the mask-and-shift steps' time)."""
    bytes_ = np.ascontiguousarray(x, _U32).view(np.uint8).reshape(np.shape(x) + (4,))
    table = _BYTE_REVERSED
    if np.little_endian:
        b0, b1, b2, b3 = (bytes_[..., i] for i in range(4))
    else:
        b3, b2, b1, b0 = (bytes_[..., i] for i in range(4))
    return ((table.take(b0) << _U32(24)) | (table.take(b1) << _U32(16))
            | (table.take(b2) << _U32(8)) | table.take(b3))


#: ``_MATRICES`` with each column's bits reversed.
_REVERSED_MATRICES = reverse_bits(_MATRICES)


def _reversed_owen(x: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Owen scrambling of bit-reversed values (Burley's hash, as Cycles'
    ``reversed_bit_owen``): each bit flipped by a hash of the bits above it in the
    unreversed value."""
    x = x ^ (x * _U32(0x3D20ADEA))
    x = x + seed
    x = x * ((seed >> _U32(16)) | _U32(1))
    x = x ^ (x * _U32(0x05526C56))
    return x ^ (x * _U32(0x53A22864))


def _sobol_reversed(reversed_index: np.ndarray, bits: int) -> np.ndarray:
    """(4, n) uint32 the first 4 Sobol dimensions of points below 2^bits, bit-reversed,
    from their indices ``reversed_index`` (n,) uint32 bit-reversed too: Owen scrambling
    works on reversed values, so the points never need reversing on the way in."""
    result = np.zeros((4, len(reversed_index)), _U32)
    for k in range(bits):
        bit = (reversed_index >> _U32(31 - k)) & _U32(1)
        result ^= _REVERSED_MATRICES[:, k:k + 1] * bit
    return result


def index_bits(samples: int) -> int:
    """How many bits a pixel's sample indices take for ``samples`` samples a pixel: the
    shuffled indices are masked to them, which keeps the first 2^bits points a permutation
    of themselves (the shuffle changes a bit only by the bits below it) and the Sobol loop
    short."""
    return max(1, int(samples - 1).bit_length())


def sample_group(seeds: np.ndarray, sample: np.ndarray, group: int, bits: int = 16,
                 dtype=np.float64) -> np.ndarray:
    """(4, n) numbers in [0, 1): dimension group ``group`` of sample ``sample`` (n,) of the
    pixels whose seeds are ``seeds`` (n,) (``pixel_seeds``); bits: ``index_bits`` of the
    render's samples a pixel."""
    seeds = np.asarray(seeds, _U32)
    group_seed = hash_u32(seeds ^ hash_u32(np.uint32(0x1F0D6A3B + group)))
    index = np.broadcast_to(np.asarray(sample, np.int64).astype(_U32), seeds.shape)
    # Shuffle the pixel's sample order (a nested uniform scramble of the index), so that the
    # pixels of an image do not draw the same points; the top ``bits`` bits of the reversed
    # shuffled index are the index's low bits.
    shuffled = _reversed_owen(reverse_bits(index), group_seed ^ _U32(0xBFF95BFE))
    points = _sobol_reversed(shuffled, bits)
    out = np.empty(points.shape, dtype)
    for dimension in range(4):
        seed = hash_u32(group_seed ^ _U32(0x635C77BD + dimension))
        scrambled = reverse_bits(_reversed_owen(points[dimension], seed))
        # The top 24 bits, so that a float32 never rounds up to 1.
        out[dimension] = (scrambled >> _U32(8)).astype(np.float64) * (1.0 / (1 << 24))
    return out


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


def diagonal_grid(count: int) -> np.ndarray:
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


def cosine_directions(count: int) -> np.ndarray:
    """(k^2, 3) directions over the hemisphere around +Z, k = ceil(sqrt(count)), spread with
    density cos(theta) / pi (Malley's method: a stratified disc lifted onto the hemisphere),
    so that their plain mean of visibility is the cosine-weighted share of the sky seen."""
    return _lifted(concentric_disk(diagonal_grid(count)))


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
    grid = diagonal_grid(count)
    grid.flags.writeable = False
    return grid


def _lifted(disk: np.ndarray) -> np.ndarray:
    """(n, 3) points of the unit disk (n, 2) lifted onto the hemisphere around +Z."""
    z = np.sqrt(np.maximum(1 - (disk ** 2).sum(axis=1), 0))
    return np.concatenate([disk, z[:, None]], axis=1)
