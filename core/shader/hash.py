"""Cycles' hashes (``intern/cycles/util/hash.h``) over arrays: Bob Jenkins' lookup3 on
32-bit unsigned integers, the float variants that hash a float32's bit pattern, and the PCG
hashes of integer vectors.

Every function takes arrays that broadcast together (Python numbers and 0-d arrays too) and
returns arrays of their broadcast shape: uint32 for the ``hash_uint*`` functions, float32 in
[0, 1] for the others; the ``*_to_float2/3/4`` ones stack their components on a new first
axis.  The arithmetic wraps modulo 2**32 exactly as C's ``uint`` does, silently: it runs on
uint32 arrays (never on NumPy scalars, which warn on overflow).  Floats are hashed through
their float32 bits, as Cycles hashes them: a float64 argument is rounded to float32 first,
and -0.0 and 0.0 hash differently.  The PCG hashes run on int32, whose products wrap
modulo 2**32 as Cycles' signed arithmetic does on every machine it runs on.
"""

from __future__ import annotations

import numpy as np

_U32 = np.uint32

#: lookup3's initial value, 0xdeadbeef + (length << 2) + 13, for 1 to 4 words.
_SEEDS = {count: (0xDEADBEEF + (count << 2) + 13) & 0xFFFFFFFF for count in (1, 2, 3, 4)}

#: (float)n * (1.0f / (float)0xFFFFFFFF): float32(2**32) is 2**32, so the factor is 2**-32.
_UINT_TO_UNIT = np.float32(1.0 / 4294967296.0)


def _words(*keys) -> tuple[tuple, list[np.ndarray]]:
    """The keys broadcast to one shape, as flat uint32 arrays (the caller's own arrays when
    they are contiguous uint32 already: the hashes only read them), and that shape."""
    arrays = np.broadcast_arrays(*[np.asarray(key) for key in keys])
    shape = arrays[0].shape
    words = []
    for array in arrays:
        if array.dtype.kind == "f":
            raise TypeError("hash_uint* take integers; hash floats with hash_float*")
        # Casting signed integers to uint32 wraps as C's cast does.
        words.append(np.ascontiguousarray(array).astype(_U32, copy=False).reshape(-1))
    return shape, words


def _rotate(x: np.ndarray, k: int, out: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """(x << k) | (x >> (32 - k)) into out."""
    np.left_shift(x, k, out=out)
    np.right_shift(x, 32 - k, out=scratch)
    np.bitwise_or(out, scratch, out=out)
    return out


def _final(a, b, c) -> np.ndarray:
    """lookup3's final(a, b, c), in place; returns c."""
    rotated, scratch = np.empty_like(a), np.empty_like(a)
    for x, y, k in ((c, b, 14), (a, c, 11), (b, a, 25), (c, b, 16), (a, c, 4), (b, a, 14),
                    (c, b, 24)):
        # x ^= y; x -= rot(y, k)
        np.bitwise_xor(x, y, out=x)
        np.subtract(x, _rotate(y, k, rotated, scratch), out=x)
    return c


def _mix(a, b, c) -> None:
    """lookup3's mix(a, b, c), in place."""
    rotated, scratch = np.empty_like(a), np.empty_like(a)
    for x, y, z, k in ((a, c, b, 4), (b, a, c, 6), (c, b, a, 8), (a, c, b, 16), (b, a, c, 19),
                       (c, b, a, 4)):
        # x -= y; x ^= rot(y, k); y += z
        np.subtract(x, y, out=x)
        np.bitwise_xor(x, _rotate(y, k, rotated, scratch), out=x)
        np.add(y, z, out=y)


def _seeded(count: int, word: np.ndarray) -> np.ndarray:
    """A new array: word + lookup3's initial value for count words."""
    return word + _U32(_SEEDS[count])


def hash_uint(kx) -> np.ndarray:
    shape, (x,) = _words(kx)
    a = _seeded(1, x)
    b, c = np.full_like(a, _SEEDS[1]), np.full_like(a, _SEEDS[1])
    return _final(a, b, c).reshape(shape)


def hash_uint2(kx, ky) -> np.ndarray:
    shape, (x, y) = _words(kx, ky)
    a, b = _seeded(2, x), _seeded(2, y)
    return _final(a, b, np.full_like(a, _SEEDS[2])).reshape(shape)


def hash_uint3(kx, ky, kz) -> np.ndarray:
    shape, (x, y, z) = _words(kx, ky, kz)
    return _final(_seeded(3, x), _seeded(3, y), _seeded(3, z)).reshape(shape)


def hash_uint4(kx, ky, kz, kw) -> np.ndarray:
    shape, (x, y, z, w) = _words(kx, ky, kz, kw)
    a, b, c = _seeded(4, x), _seeded(4, y), _seeded(4, z)
    _mix(a, b, c)
    a += w
    return _final(a, b, c).reshape(shape)


def uint_to_float_incl(n) -> np.ndarray:
    """[0, 2**32 - 1] -> [0, 1] as Cycles' uint_to_float_incl (float32)."""
    return np.asarray(n, _U32).astype(np.float32) * _UINT_TO_UNIT


def float_bits(k) -> np.ndarray:
    """The uint32 bit pattern of k as float32 (Cycles' __float_as_uint)."""
    return np.ascontiguousarray(k, dtype=np.float32).view(_U32)


def hash_uint_to_float(kx) -> np.ndarray:
    return uint_to_float_incl(hash_uint(kx))


def hash_uint2_to_float(kx, ky) -> np.ndarray:
    return uint_to_float_incl(hash_uint2(kx, ky))


def hash_uint3_to_float(kx, ky, kz) -> np.ndarray:
    return uint_to_float_incl(hash_uint3(kx, ky, kz))


def hash_uint4_to_float(kx, ky, kz, kw) -> np.ndarray:
    return uint_to_float_incl(hash_uint4(kx, ky, kz, kw))


def hash_float_to_float(k) -> np.ndarray:
    return hash_uint_to_float(float_bits(k))


def hash_float2_to_float(x, y) -> np.ndarray:
    return hash_uint2_to_float(float_bits(x), float_bits(y))


def hash_float3_to_float(x, y, z) -> np.ndarray:
    return hash_uint3_to_float(float_bits(x), float_bits(y), float_bits(z))


def hash_float4_to_float(x, y, z, w) -> np.ndarray:
    return hash_uint4_to_float(float_bits(x), float_bits(y), float_bits(z), float_bits(w))


def _stack(*components) -> np.ndarray:
    return np.stack(np.broadcast_arrays(*components))


def hash_float2_to_float2(x, y) -> np.ndarray:
    """(2, ...) as Cycles' hash_float2_to_float2."""
    return _stack(hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0))


def hash_float3_to_float3(x, y, z) -> np.ndarray:
    """(3, ...) as Cycles' hash_float3_to_float3."""
    return _stack(hash_float3_to_float(x, y, z), hash_float4_to_float(x, y, z, 1.0),
                  hash_float4_to_float(x, y, z, 2.0))


def hash_float4_to_float4(x, y, z, w) -> np.ndarray:
    """(4, ...) as Cycles' hash_float4_to_float4."""
    return _stack(hash_float4_to_float(x, y, z, w), hash_float4_to_float(w, x, y, z),
                  hash_float4_to_float(z, w, x, y), hash_float4_to_float(y, z, w, x))


def hash_float_to_float3(k) -> np.ndarray:
    """(3, ...) as Cycles' hash_float_to_float3 (the colour of 1D Voronoi and White Noise)."""
    return _stack(hash_float_to_float(k), hash_float2_to_float(k, 1.0),
                  hash_float2_to_float(k, 2.0))


def hash_float2_to_float3(x, y) -> np.ndarray:
    """(3, ...) as Cycles' hash_float2_to_float3."""
    return _stack(hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0),
                  hash_float3_to_float(x, y, 2.0))


def hash_float4_to_float3(x, y, z, w) -> np.ndarray:
    """(3, ...) as Cycles' hash_float4_to_float3."""
    return _stack(hash_float4_to_float(x, y, z, w), hash_float4_to_float(z, x, w, y),
                  hash_float4_to_float(w, z, y, x))


# ---- PCG hashes of integer vectors (Jarzynski and Olano, "Hash Functions for GPU
# Rendering", JCGT 2020), as Cycles' util/hash.h writes them on signed ints: what the Voronoi
# texture hashes its 2D to 4D cells with. ----

_PCG_MULTIPLIER = np.int32(1664525)
_PCG_INCREMENT = np.int32(1013904223)
#: 1.0f / (float)0x7FFFFFFF: float32(2**31 - 1) rounds to 2**31, so the factor is 2**-31.
_INT_TO_UNIT = np.float32(1.0 / 2147483648.0)


def _ints(*keys) -> tuple[tuple, list[np.ndarray]]:
    """The keys broadcast to one shape, as flat int32 arrays of their own."""
    arrays = np.broadcast_arrays(*[np.asarray(key) for key in keys])
    for array in arrays:
        if array.dtype.kind == "f":
            raise TypeError("hash_int* take integers")
    return arrays[0].shape, [array.astype(np.int32).reshape(-1) for array in arrays]


def _pcg_start(v):
    # v * 1664525 + 1013904223, wrapping as the int32 arithmetic Cycles relies on does.
    return [x * _PCG_MULTIPLIER + _PCG_INCREMENT for x in v]


def _pcg_end(v, shape):
    return np.stack([(x & np.int32(0x7FFFFFFF)).reshape(shape) for x in v])


def _shift_xor(v):
    # v ^ (v >> 16), an arithmetic shift of the signed ints.
    return [x ^ (x >> np.int32(16)) for x in v]


def hash_pcg2d_i(kx, ky) -> np.ndarray:
    """(2, ...) int32 in [0, 2**31): Cycles' hash_pcg2d_i."""
    shape, v = _ints(kx, ky)
    x, y = _pcg_start(v)
    for step in range(2):
        x = x + y * _PCG_MULTIPLIER
        y = y + x * _PCG_MULTIPLIER
        if step == 0:
            x, y = _shift_xor((x, y))
    return _pcg_end((x, y), shape)


def hash_pcg3d_i(kx, ky, kz) -> np.ndarray:
    """(3, ...) int32 in [0, 2**31): Cycles' hash_pcg3d_i."""
    shape, v = _ints(kx, ky, kz)
    x, y, z = _pcg_start(v)
    for step in range(2):
        x = x + y * z
        y = y + z * x
        z = z + x * y
        if step == 0:
            x, y, z = _shift_xor((x, y, z))
    return _pcg_end((x, y, z), shape)


def hash_pcg4d_i(kx, ky, kz, kw) -> np.ndarray:
    """(4, ...) int32 in [0, 2**31): Cycles' hash_pcg4d_i."""
    shape, v = _ints(kx, ky, kz, kw)
    x, y, z, w = _pcg_start(v)
    for step in range(2):
        x = x + y * w
        y = y + z * x
        z = z + x * y
        w = w + y * z
        if step == 0:
            x, y, z, w = _shift_xor((x, y, z, w))
    return _pcg_end((x, y, z, w), shape)


def hash_int2_to_float2(kx, ky) -> np.ndarray:
    """(2, ...) in [0, 1]: Cycles' hash_int2_to_float2."""
    return hash_pcg2d_i(kx, ky).astype(np.float32) * _INT_TO_UNIT


def hash_int3_to_float3(kx, ky, kz) -> np.ndarray:
    """(3, ...) in [0, 1]: Cycles' hash_int3_to_float3."""
    return hash_pcg3d_i(kx, ky, kz).astype(np.float32) * _INT_TO_UNIT


def hash_int4_to_float4(kx, ky, kz, kw) -> np.ndarray:
    """(4, ...) in [0, 1]: Cycles' hash_int4_to_float4."""
    return hash_pcg4d_i(kx, ky, kz, kw).astype(np.float32) * _INT_TO_UNIT


def hash_int2_to_float3(kx, ky) -> np.ndarray:
    """(3, ...): Cycles' hash_int2_to_float3, the 3D hash of (x, y, 0)."""
    return hash_int3_to_float3(kx, ky, 0)


def hash_int4_to_float3(kx, ky, kz, kw) -> np.ndarray:
    """(3, ...): the first three components of hash_int4_to_float4."""
    return hash_int4_to_float4(kx, ky, kz, kw)[:3]
