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
"""

from __future__ import annotations

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
