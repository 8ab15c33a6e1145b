"""Cycles' Perlin noise (``kernel/svm/noise.h``) and the fractal sums of Blender's Noise
Texture (``kernel/svm/fractal_noise.h``, ``noisetex.h``), in float32 over arrays.

Points are (d, ...) float32 arrays, d = 1 to 4 the noise's dimensions, components on the
first axis; the fractal parameters are float32 arrays that broadcast with the points' other
axes (a node's linked Detail or Roughness differs per point) or Python numbers.

The operations follow the CPU kernel Blender's Cycles runs on an x86 machine with AVX2 (its
SSE noise in 2D, AVX in 3D and 4D): the same corner order, the same order of interpolation,
and the fused multiply-adds that kernel computes (``fused_multiply_add``: its explicit
madd()s, and the a * b + c its compiler contracts), so that Perlin noise comes out bit for
bit as Blender's on such a machine.  On a CPU without AVX2 Cycles runs its SSE kernel,
without fused multiply-adds, and values differ in their last bits.

Lattice cells are hashed once per run of consecutive points that share one (``cell_runs``):
a frame's shading points come in pixel order, so most neighbours share their cells.
"""

from __future__ import annotations

import numpy as np

from .hash import hash_float2_to_float, hash_float_to_float, hash_uint, \
    hash_uint2, hash_uint3, hash_uint4

#: Perlin noise repeats every 100000 units on each axis (Cycles' guard against float
#: precision loss far from the origin).
NOISE_PERIOD = np.float32(100000.0)
PRECISION_LIMIT = np.float32(1000000.0)

#: Cycles' scale of each dimension's Perlin noise to about [-1, 1].
_NOISE_SCALES = {1: np.float32(0.2500), 2: np.float32(0.6616), 3: np.float32(0.9820),
                 4: np.float32(0.8344)}

#: The Noise Texture's types (``noise_type``) and the fractal sum each names.
NOISE_TYPES = ("FBM", "MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL",
               "HETERO_TERRAIN")


def float32(x) -> np.ndarray:
    return np.asarray(x, dtype=np.float32)


def fused_multiply_add(a, b, c):
    """a * b + c rounded once to float32, as an FMA instruction computes it: the product of
    two float32 is exact in float64, and the sum's rounding to float64 then float32 differs
    from a single rounding only when it falls exactly halfway between two float32, which
    the 29 spare bits make vanishingly rare."""
    product = np.multiply(a, b, dtype=np.float64)
    if isinstance(product, np.ndarray) and product.shape == np.broadcast(product, c).shape:
        product += c  # in place: one temporary fewer
    else:
        product = product + c
    return np.asarray(product).astype(np.float32)


def fused_lerp(a, b, t):
    """Cycles' mix(a, b, t) = a + t * (b - a) as the AVX2 kernel computes it: fma(t, b - a,
    a)."""
    return fused_multiply_add(t, b - a, a)


def float_to_int(x) -> np.ndarray:
    """C's (int)x as x86 computes it: truncation, and INT_MIN for NaN and for values
    outside int's range (no warning)."""
    x = float32(x)
    inside = np.abs(x) < np.float32(2.0 ** 31)
    return np.where(inside, x, np.float32(-2.0 ** 31)).astype(np.int32)


def floorfrac(x) -> tuple[np.ndarray, np.ndarray]:
    """(x - floor(x), floor(x) as uint32 bits of the int Cycles hashes)."""
    cell = np.floor(x)
    return x - cell, float_to_int(cell).view(np.uint32)


def _fade_polynomial(t):
    """t * (t * 6 - 15) + 10 as two fused multiply-adds (SSE's madd()s, and what the
    compiler makes of the scalar expression)."""
    return fused_multiply_add(t, fused_multiply_add(t, np.float32(6.0), np.float32(-15.0)),
                              np.float32(10.0))


def _fade_scalar(t):
    """Cycles' scalar fade (1D): t * t * t * (...), the products left to right."""
    return t * t * t * _fade_polynomial(t)


def _fade(t):
    """Cycles' SSE fade (2D to 4D): (t * t) * (t * (...))."""
    return (t * t) * (t * _fade_polynomial(t))


def _cycles_gradient(h: int, d: int) -> list[float]:
    """The coefficients of Cycles' grad<d>(h, x, y, ...) on each of x, y, ... (each is one
    of u, v, s, up to sign: noise.h's grad1 to grad4 on one hash h, written out once)."""
    if d == 1:
        h &= 15
        return [(-1.0 if h & 8 else 1.0) * (1 + (h & 7))]
    if d == 2:
        h &= 7
        u, v = (0, 1) if h < 4 else (1, 0)
        terms = [(u, -1.0 if h & 1 else 1.0), (v, -2.0 if h & 2 else 2.0)]
    elif d == 3:
        h &= 15
        u = 0 if h < 8 else 1
        v = 1 if h < 4 else (0 if h in (12, 14) else 2)
        terms = [(u, -1.0 if h & 1 else 1.0), (v, -1.0 if h & 2 else 1.0)]
    else:
        h &= 31
        terms = [(0 if h < 24 else 1, -1.0 if h & 1 else 1.0),
                 (1 if h < 16 else 2, -1.0 if h & 2 else 1.0),
                 (2 if h < 8 else 3, -1.0 if h & 4 else 1.0)]
    coefficients = [0.0] * d
    for axis, sign in terms:
        coefficients[axis] = sign
    return coefficients


#: (d, hashes) each dimension's gradient coefficients for every value of its hash's low bits.
_GRADIENTS = {d: np.array([_cycles_gradient(h, d) for h in range(32 if d == 4 else 16)],
                          np.float32).T.copy() for d in (1, 2, 3, 4)}


def _gradient_dot(h, relative):
    """Cycles' grad<d>(h, relative...): the sum of the (up to three) signed components it
    picks, in axis order as Cycles adds them (products by 0, 1 or 2 are exact, and adding
    an exact 0 changes nothing)."""
    table = _GRADIENTS[len(relative)]
    index = (h & np.uint32(table.shape[1] - 1)).astype(np.intp)
    total = np.take(table[0], index) * relative[0]
    for axis in range(1, len(relative)):
        total = total + np.take(table[axis], index) * relative[axis]
    return total


def perlin_1d(x):
    """mix(g0 * fx, g1 * (fx - 1), u): the compiler fuses the product g0 * fx into both of
    the sums that use it, b - a and a + u * (b - a)."""
    fx, X = floorfrac(x)
    u = _fade_scalar(fx)
    slopes = _GRADIENTS[1][0]
    g0 = np.take(slopes, (hash_uint(X) & np.uint32(15)).astype(np.intp))
    g1 = np.take(slopes, (hash_uint(X + np.uint32(1)) & np.uint32(15)).astype(np.intp))
    difference = fused_multiply_add(-g0, fx, g1 * (fx - np.float32(1.0)))
    return fused_multiply_add(g0, fx, u * difference)


#: Hashing each run of points that share a cell once pays when runs average two points or
#: more (spatially coherent points, as a frame's pixels are in their order).
_RUN_SHARE = 0.5


def cell_runs(cells):
    """Runs of consecutive points that share a cell: (index of each run's first point, run
    of every point), over the flattened points of the d integer arrays ``cells``; None when
    the runs are too short for hashing per run to pay."""
    flat = [np.ravel(cell) for cell in cells]
    count = flat[0].size
    if count < 64:
        return None
    changes = np.zeros(count, bool)
    changes[0] = True
    for cell in flat:
        changes[1:] |= cell[1:] != cell[:-1]
    first = np.flatnonzero(changes)
    if first.size > _RUN_SHARE * count:
        return None
    return first, np.cumsum(changes) - 1


def _steps(offsets, ndim: int, dtype):
    """(d, corners, 1, ...) the corner offsets, shaped to broadcast against (d, 1, ...)."""
    table = np.array(offsets, dtype).T
    return table.reshape(table.shape + (1,) * ndim)


def _corner_hashes(cells, offsets, hash_function):
    """(corners, ...) the hash of each lattice corner around each point, corners in the
    order of ``offsets`` (a (corners, d) table of 0 and 1); cells are hashed once per run of
    points that share them (``cell_runs``)."""
    shape = np.shape(cells[0])
    runs = cell_runs(cells)
    if runs is not None:
        first, run = runs
        cells = [np.ravel(cell)[first] for cell in cells]
    # order="C": NumPy would otherwise follow the inputs' strides and put the corners last
    # in memory, making every later pass over them strided.
    lattice = np.add(np.stack(cells)[:, None], _steps(offsets, np.ndim(cells[0]), np.uint32),
                     order="C")
    hashes = hash_function(*lattice)
    if runs is None:
        return hashes
    return np.take(hashes, run, axis=1).reshape((len(offsets),) + shape)


def _corner_offsets(fractions, offsets):
    """(d, corners, ...) each point's position relative to each corner."""
    return np.subtract(np.stack(fractions)[:, None],
                       _steps(offsets, np.ndim(fractions[0]), np.float32), order="C")


#: SSE's 2D corner order: (X, Y), (X, Y + 1), (X + 1, Y), (X + 1, Y + 1).
_CORNERS_2D = ((0, 0), (0, 1), (1, 0), (1, 1))
#: AVX's 3D order: x slowest, then y, then z; 4D puts the eight w = W corners first.
_CORNERS_3D = tuple((x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1))
_CORNERS_4D = tuple((x, y, z, w) for w in (0, 1) for x in (0, 1) for y in (0, 1)
                    for z in (0, 1))


def perlin_2d(x, y):
    (fx, X), (fy, Y) = floorfrac(x), floorfrac(y)
    u, v = _fade(fx), _fade(fy)
    g = _gradient_dot(_corner_hashes((X, Y), _CORNERS_2D, hash_uint2),
                      _corner_offsets((fx, fy), _CORNERS_2D))
    # bi_mix: along x between (g0, g2) and (g1, g3), then along y.
    along_x = fused_lerp(g[0:2], g[2:4], u)
    return fused_lerp(along_x[0], along_x[1], v)


def _tri_mix(g, u, v, w):
    """SSE tri_mix of 8 corner values in the AVX order: along x, then y, then z."""
    s = fused_lerp(g[0:4], g[4:8], u)
    t = fused_lerp(s[0:2], s[2:4], v)
    return fused_lerp(t[0], t[1], w)


def perlin_3d(x, y, z):
    (fx, X), (fy, Y), (fz, Z) = floorfrac(x), floorfrac(y), floorfrac(z)
    u, v, w = _fade(fx), _fade(fy), _fade(fz)
    g = _gradient_dot(_corner_hashes((X, Y, Z), _CORNERS_3D, hash_uint3),
                      _corner_offsets((fx, fy, fz), _CORNERS_3D))
    return _tri_mix(g, u, v, w)


def perlin_4d(x, y, z, w):
    (fx, X), (fy, Y), (fz, Z), (fw, W) = floorfrac(x), floorfrac(y), floorfrac(z), floorfrac(w)
    u, v, t, s = _fade(fx), _fade(fy), _fade(fz), _fade(fw)
    g = _gradient_dot(_corner_hashes((X, Y, Z, W), _CORNERS_4D, hash_uint4),
                      _corner_offsets((fx, fy, fz, fw), _CORNERS_4D))
    # AVX quad_mix: along w first, then the 3D interpolation.
    return _tri_mix(fused_lerp(g[0:8], g[8:16], s), u, v, t)


_PERLIN = {1: perlin_1d, 2: perlin_2d, 3: perlin_3d, 4: perlin_4d}


def _perlin(p) -> tuple[np.float32, np.ndarray]:
    """(scale, Perlin noise at p wrapped to the noise's period): snoise without its scaling.
    Components of a million or more, whose float32 has at most a few fractional bits, are
    moved half a cell once wrapped, as Cycles does (else they would land on lattice points,
    where Perlin noise is 0)."""
    p = float32(p)
    correction = np.where(np.abs(p) >= PRECISION_LIMIT, np.float32(0.5), np.float32(0.0))
    p = np.fmod(p, NOISE_PERIOD) + correction
    dimensions = p.shape[0]
    return _NOISE_SCALES[dimensions], _PERLIN[dimensions](*p)


def snoise(p) -> np.ndarray:
    """Signed noise at the (d, ...) points p, about [-1, 1]: Cycles' snoise_1d to _4d."""
    scale, value = _perlin(p)
    return scale * value


def noise(p) -> np.ndarray:
    """Unsigned noise at the (d, ...) points p, in [0, 1]: Cycles' noise_1d to _4d."""
    return np.float32(0.5) * snoise(p) + np.float32(0.5)


def snoise_plus(p, offset) -> np.ndarray:
    """snoise(p) + offset as the compiler fuses it: fma(scale, perlin, offset)."""
    scale, value = _perlin(p)
    return fused_multiply_add(scale, value, offset)


def random_offset(seed: float, dimensions: int) -> np.ndarray:
    """(d, 1) Cycles' random_float_offset / random_float<d>_offset(seed): a fixed offset in
    [100, 200] per axis that makes an independent copy of the noise."""
    if dimensions == 1:
        values = [hash_float_to_float(np.float32(seed))]
    else:
        values = [hash_float2_to_float(np.float32(seed), np.float32(axis))
                  for axis in range(dimensions)]
    return np.float32(100.0) + np.stack(values).reshape(dimensions, 1) * np.float32(100.0)


def _update(active, new, old):
    """new where the octave is active (active is True, False or a bool array)."""
    if active is True:
        return new
    if active is False:
        return old
    return np.where(active, new, old)


def _octaves(detail):
    """(number of whole octaves per point, their maximum, fractional part per point)."""
    whole = float_to_int(detail)
    remainder = detail - np.floor(detail)
    return whole, int(whole.max(initial=0)), remainder


def _active(i, whole):
    """Whether octave i runs: a Python bool when every point has the same detail."""
    if whole.ndim == 0:
        return bool(i <= whole)
    return i <= whole


def _any(mask) -> bool:
    return bool(np.any(mask))


def noise_fbm(p, detail, roughness, lacunarity, normalize: bool):
    """Fractal Brownian motion: Cycles' noise_fbm."""
    whole, most, remainder = _octaves(detail)
    fscale, amp = np.float32(1.0), np.float32(1.0)
    maxamp, total = np.float32(0.0), np.float32(0.0)
    for i in range(most + 1):
        active = _active(i, whole)
        t = snoise(fscale * p)
        total = _update(active, fused_multiply_add(t, amp, total), total)
        maxamp = _update(active, maxamp + amp, maxamp)
        amp = _update(active, amp * roughness, amp)
        fscale = _update(active, fscale * lacunarity, fscale)
    half = np.float32(0.5)
    whole_sum = half * total / maxamp + half if normalize else total
    fractional = remainder != 0
    if not _any(fractional):
        return whole_sum
    t = snoise(fscale * p)
    total2 = fused_multiply_add(t, amp, total)
    if normalize:
        blended = fused_lerp(whole_sum, half * total2 / (maxamp + amp) + half, remainder)
    else:
        blended = fused_lerp(total, total2, remainder)
    return np.where(fractional, blended, whole_sum)


def noise_multi_fractal(p, detail, roughness, lacunarity):
    """Cycles' noise_multi_fractal."""
    whole, most, remainder = _octaves(detail)
    value, pwr = np.float32(1.0), np.float32(1.0)
    for i in range(most + 1):
        active = _active(i, whole)
        factor = fused_multiply_add(pwr, snoise(p), np.float32(1.0))
        value = _update(active, value * factor, value)
        pwr = _update(active, pwr * roughness, pwr)
        p = _update(active, p * lacunarity, p)
    fractional = remainder != 0
    if not _any(fractional):
        return value
    last = value * fused_multiply_add(remainder * pwr, snoise(p), np.float32(1.0))
    return np.where(fractional, last, value)


def noise_hetero_terrain(p, detail, roughness, lacunarity, offset):
    """Heterogeneous terrain: Cycles' noise_hetero_terrain."""
    whole, most, remainder = _octaves(detail)
    pwr = roughness
    value = snoise_plus(p, offset)
    p = p * lacunarity
    for i in range(1, most + 1):
        active = _active(i, whole)
        # value += (noise + offset) * pwr * value: the last product fuses into the sum.
        grown = fused_multiply_add(snoise_plus(p, offset) * pwr, value, value)
        value = _update(active, grown, value)
        pwr = _update(active, pwr * roughness, pwr)
        p = _update(active, p * lacunarity, p)
    fractional = remainder != 0
    if not _any(fractional):
        return value
    increment = snoise_plus(p, offset) * pwr * value
    return np.where(fractional, fused_multiply_add(remainder, increment, value), value)


_WEIGHT_FLOOR = np.float32(0.001)


def noise_hybrid_multi_fractal(p, detail, roughness, lacunarity, offset, gain):
    """Hybrid additive/multiplicative multifractal: Cycles' noise_hybrid_multi_fractal.
    Each point stops adding octaves once its weight falls to 0.001."""
    whole, most, remainder = _octaves(detail)
    pwr, value, weight = np.float32(1.0), np.float32(0.0), np.float32(1.0)
    one = np.float32(1.0)
    for i in range(most + 1):
        active = (weight > _WEIGHT_FLOOR) & np.asarray(_active(i, whole))
        if not _any(active):
            break
        weight = _update(active, np.minimum(weight, one), weight)
        signal = snoise_plus(p, offset) * pwr
        pwr = _update(active, pwr * roughness, pwr)
        value = _update(active, fused_multiply_add(weight, signal, value), value)
        weight = _update(active, weight * (gain * signal), weight)
        p = _update(active, p * lacunarity, p)
    last = (remainder != 0) & (weight > _WEIGHT_FLOOR)
    if not _any(last):
        return value
    signal = snoise_plus(p, offset) * pwr
    return np.where(last, fused_multiply_add(remainder * np.minimum(weight, one), signal, value),
                    value)


def noise_ridged_multi_fractal(p, detail, roughness, lacunarity, offset, gain):
    """Ridged multifractal: Cycles' noise_ridged_multi_fractal (no fractional octave)."""
    whole, most, _ = _octaves(detail)
    pwr = roughness
    signal = offset - np.abs(snoise(p))
    signal = signal * signal
    value = signal
    for i in range(1, most + 1):
        active = _active(i, whole)
        p = _update(active, p * lacunarity, p)
        weight = np.clip(signal * gain, np.float32(0.0), np.float32(1.0))
        new_signal = offset - np.abs(snoise(p))
        new_signal = new_signal * new_signal * weight
        signal = _update(active, new_signal, signal)
        value = _update(active, fused_multiply_add(new_signal, pwr, value), value)
        pwr = _update(active, pwr * roughness, pwr)
    return value


def fractal_noise(noise_type: str, p, detail, roughness, lacunarity, offset, gain,
                  normalize: bool):
    """Cycles' noise_select: the fractal sum ``noise_type`` (``NOISE_TYPES``) at p."""
    if noise_type == "FBM":
        return noise_fbm(p, detail, roughness, lacunarity, normalize)
    if noise_type == "MULTIFRACTAL":
        return noise_multi_fractal(p, detail, roughness, lacunarity)
    if noise_type == "HYBRID_MULTIFRACTAL":
        return noise_hybrid_multi_fractal(p, detail, roughness, lacunarity, offset, gain)
    if noise_type == "RIDGED_MULTIFRACTAL":
        return noise_ridged_multi_fractal(p, detail, roughness, lacunarity, offset, gain)
    if noise_type == "HETERO_TERRAIN":
        return noise_hetero_terrain(p, detail, roughness, lacunarity, offset)
    raise ValueError(f"noise type {noise_type!r} is not one of {', '.join(NOISE_TYPES)}")


def _seeds(dimensions: int) -> tuple[list[float], tuple[float, float]]:
    """random_offset seeds of the distortion (one per axis) and of the colour's green and
    blue channels."""
    distortion = [float(axis) for axis in range(dimensions)] if dimensions > 1 else [0.0]
    first = len(distortion)
    return distortion, (float(first), float(first + 1))


def noise_texture(p, detail, roughness, lacunarity, offset, gain, distortion, noise_type: str,
                  normalize: bool, colour: bool = True):
    """Cycles' noise_texture_1d to _4d at the (d, ...) scaled points p: (value, colour),
    colour (3, ...) being value and two more fractal sums at randomly offset points (None
    when ``colour`` is False)."""
    dimensions = p.shape[0]
    distortion_seeds, colour_seeds = _seeds(dimensions)
    if _any(distortion != 0):
        noises = np.stack([snoise(p + random_offset(seed, dimensions))
                           for seed in distortion_seeds])
        distorted = p + noises * distortion
        if dimensions <= 2:
            # Blender's build fuses p.x + noise * distortion (p a float or a float2 struct)
            # but not the float2's y, nor the float3 and float4 (SSE) sums: measured
            # against its renders, each other choice changes some values' last bit.
            distorted[0] = fused_multiply_add(noises[0], distortion, p[0])
        p = _update(distortion != 0, distorted, p) if np.ndim(distortion) else distorted

    def at(q):
        return fractal_noise(noise_type, q, detail, roughness, lacunarity, offset, gain,
                             normalize)

    value = at(p)
    if not colour:
        return value, None
    channels = [value] + [at(p + random_offset(seed, dimensions)) for seed in colour_seeds]
    return value, np.stack(np.broadcast_arrays(*channels))

