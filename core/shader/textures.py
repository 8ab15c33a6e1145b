"""Blender's procedural texture nodes, as Cycles evaluates them (``intern/cycles/kernel/svm``):
Noise, Voronoi, Wave, Magic, Gradient, Checker, Brick and White Noise, registered in
``core.shader.registry``.

Each node function takes its inputs by Blender's socket identifiers and its options by
property name, as the registry describes, and computes in float32 as Cycles does, so that
the same coordinates give the same values as Blender's renders (to float32 rounding: Cycles
builds its kernels with fused multiply-adds and fast-math).  Points are evaluated in blocks
(``blockwise``) that keep each block's temporaries small.

A texture's unlinked Vector is the Generated coordinate, except White Noise's, which is its
socket value (Cycles links no coordinate to it).  Every texture but White Noise takes the
option ``texture_mapping``: the node's Texture Mapping (the sidebar's translation, rotation,
scale, vector type and axis mapping, as ``addon.export.node_options`` reads it; None or an
identity mapping leave the Vector as it is), applied to the Vector first as Cycles does.
Cycles reads neither its Min/Max clamp nor the node's Color Mapping, nor does Glint.
"""

from __future__ import annotations

import numpy as np

from .hash import hash_float2_to_float, hash_float2_to_float3, hash_float3_to_float, \
    hash_float3_to_float3, hash_float4_to_float, hash_float4_to_float3, hash_float_to_float, \
    hash_float_to_float3
from .noise import NOISE_TYPES, float_to_int, fused_multiply_add, noise_fbm, noise_texture
from .registry import COLOR, FLOAT, VECTOR, node
from .voronoi import FEATURES, METRICS, VoronoiParams, fractal_voronoi, \
    fractal_voronoi_distance_to_edge, max_distance, voronoi_n_sphere_radius

#: Array elements a block of points may spread over (points x cells or corners): about a
#: megabyte per float32 temporary, so that a block's many temporaries stay in cache.
BLOCK_ELEMENTS = 1 << 18

_F32 = np.float32
_DIMENSIONS = {"1D": 1, "2D": 2, "3D": 3, "4D": 4}
_OUTPUT_SHAPES = {FLOAT: (), VECTOR: (3,), COLOR: (3,)}

#: Cycles' M_PI_2_F and M_2PI_F, and what Blender's build (fast-math) divides by 2 pi with:
#: a product by its float32 reciprocal.
_HALF_PI = _F32(1.5707963267948966)
_TWO_PI = _F32(6.2831853071795864)
_ONE_OVER_TWO_PI = _F32(1.0) / _TWO_PI


def _option(node_type: str, name: str, value, allowed):
    if value not in allowed:
        raise ValueError(f"{node_type}: option {name}={value!r} is not one of "
                         f"{', '.join(map(str, allowed))}")
    return value


def _dimensions(node_type: str, name: str, value) -> int:
    return _DIMENSIONS[_option(node_type, name, value, tuple(_DIMENSIONS))]


def _floats(*values) -> list[np.ndarray]:
    return [np.asarray(value, dtype=_F32) for value in values]


def float32_vector(value) -> np.ndarray:
    vector = np.asarray(value, dtype=_F32)
    return vector.reshape(3, -1) if vector.ndim < 2 else vector


def _point_count(arrays) -> int:
    return max([array.shape[-1] for array in arrays if array.ndim] + [1])


def blockwise(kernel, arrays, outputs, cost: int = 1):
    """kernel(*arrays) over blocks of points: each array whose last axis is the points'
    (the longest last axis) is sliced, the others (constants) passed whole.  outputs: the
    socket types of the kernel's results, which are broadcast to (n,) or (3, n).  cost:
    array elements per point in the kernel's largest temporaries (cells, corners)."""
    count = _point_count(arrays)
    block = max(256, BLOCK_ELEMENTS // cost)
    results = [np.empty(_OUTPUT_SHAPES[kind] + (count,), _F32) for kind in outputs]
    for start in range(0, count, block):
        stop = min(count, start + block)
        part = [array[..., start:stop] if array.ndim and array.shape[-1] == count else array
                for array in arrays]
        for result, value in zip(results, kernel(*part)):
            result[..., start:stop] = value
    return tuple(results)


def _coordinates(dimensions: int, vector, w) -> np.ndarray:
    """(d, m) the texture's point: W (1D), the Vector's x and y (2D), the Vector (3D), or the
    Vector and W (4D)."""
    if dimensions == 1:
        return w[None] if w.ndim else w.reshape(1, 1)
    if dimensions == 2:
        return vector[:2]
    if dimensions == 3:
        return vector
    x, y, z, w = np.broadcast_arrays(vector[0], vector[1], vector[2], w)
    return np.stack([x, y, z, w])


# ---- Texture Mapping ---------------------------------------------------------------------

MAPPING_TYPES = ("POINT", "TEXTURE", "VECTOR", "NORMAL")
MAPPING_AXES = ("NONE", "X", "Y", "Z")


def _rotation(angle: float, axis: int) -> np.ndarray:
    """Cycles' transform_rotate about a coordinate axis (Rodrigues' formula)."""
    k = np.eye(3)[axis]
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return (np.cos(angle) * np.eye(3) + np.sin(angle) * cross
            + (1.0 - np.cos(angle)) * np.outer(k, k))


def _euler_matrix(rotation) -> np.ndarray:
    """Cycles' transform_euler: Rz @ Ry @ Rx (X applies first)."""
    return _rotation(rotation[2], 2) @ _rotation(rotation[1], 1) @ _rotation(rotation[0], 0)


def texture_mapping_transform(mapping) -> np.ndarray | None:
    """(3, 4) float32: Cycles' TextureMapping::compute_transform of a texture node's mapping
    (a dict of translation, rotation, scale, vector_type, mapping_x, mapping_y, mapping_z), or
    None when Cycles skips it (no mapping, or an identity one; the vector type alone does not
    count).  Computed in float64 and rounded once: Cycles builds it in float32, so an entry may
    differ from Cycles' in the last bit."""
    if not mapping:
        return None
    translation = np.array(mapping.get("translation", (0.0, 0.0, 0.0)), np.float64)
    rotation = np.array(mapping.get("rotation", (0.0, 0.0, 0.0)), np.float64)
    scale = np.array(mapping.get("scale", (1.0, 1.0, 1.0)), np.float64)
    kind = _option("texture_mapping", "vector_type", mapping.get("vector_type", "POINT"),
                   MAPPING_TYPES)
    axes = [_option("texture_mapping", name, mapping.get(name, default), MAPPING_AXES)
            for name, default in (("mapping_x", "X"), ("mapping_y", "Y"), ("mapping_z", "Z"))]
    if (not translation.any() and not rotation.any() and (scale == 1).all()
            and axes == ["X", "Y", "Z"]):
        return None
    projection = np.zeros((3, 3))
    for row, axis in enumerate(axes):
        if axis != "NONE":
            projection[row, MAPPING_AXES.index(axis) - 1] = 1.0
    if kind in ("TEXTURE", "NORMAL"):  # keep the matrix invertible
        scale = np.where(np.abs(scale) < 1e-5, np.where(scale < 0, -1e-5, 1e-5), scale)
    linear = _euler_matrix(rotation) @ np.diag(scale)
    offset = translation if kind in ("POINT", "TEXTURE") else np.zeros(3)
    if kind == "TEXTURE":  # the inverse on the coordinate moves the texture forward
        linear = np.linalg.inv(linear)
        offset = -linear @ translation
    elif kind == "NORMAL":
        linear = np.linalg.inv(linear).T
    return np.concatenate([linear @ projection, offset[:, None]], axis=1).astype(_F32)


def mapped(vector, mapping):
    """The (3, m) vector through the node's texture mapping (Cycles' transform_point, with its
    fused multiply-adds; NORMAL then normalizes)."""
    matrix = texture_mapping_transform(mapping)
    if matrix is None:
        return vector
    columns = matrix[:, :, None]
    result = fused_multiply_add(vector[2], columns[:, 2], columns[:, 3])
    result = fused_multiply_add(vector[1], columns[:, 1], result)
    result = fused_multiply_add(vector[0], columns[:, 0], result)
    if mapping.get("vector_type") == "NORMAL":
        length = np.sqrt((result[0] * result[0] + result[1] * result[1]) + result[2] * result[2])
        result = np.where(length != 0, result * (_F32(1.0) / np.where(length != 0, length, 1)),
                          result)
    return result


def _grey(value):
    return np.broadcast_to(value, (3,) + np.shape(value))


def _sin(x):
    """sinf to float32 rounding: NumPy's own float32 sine is a few ulps off glibc's."""
    return np.sin(x.astype(np.float64)).astype(_F32)


def _cos(x):
    return np.cos(x.astype(np.float64)).astype(_F32)


# ---- Noise -------------------------------------------------------------------------------

@node("ShaderNodeTexNoise",
      inputs=(("Vector", VECTOR), ("W", FLOAT), ("Scale", FLOAT), ("Detail", FLOAT),
              ("Roughness", FLOAT), ("Lacunarity", FLOAT), ("Offset", FLOAT), ("Gain", FLOAT),
              ("Distortion", FLOAT)),
      outputs=(("Fac", FLOAT), ("Color", COLOR)),
      options=("noise_dimensions", "noise_type", "normalize", "texture_mapping"),
      implicit={"Vector": "generated"})
def noise_texture_node(points, vector, w, scale, detail, roughness, lacunarity, offset, gain,
                       distortion, *, noise_dimensions="3D", noise_type="FBM", normalize=True,
                       texture_mapping=None, needed=None):
    """Fractal Perlin noise (Cycles' svm_node_tex_noise): Fac, and Color, Fac with two more
    fractal sums at offset points (three times the work: ``needed``, the identifiers of the
    outputs the program reads, None for all, skips it when Color is not among them; an
    output not needed comes back as 0)."""
    dimensions = _dimensions("ShaderNodeTexNoise", "noise_dimensions", noise_dimensions)
    _option("ShaderNodeTexNoise", "noise_type", noise_type, NOISE_TYPES)

    def kernel(vector, w, scale, detail, roughness, lacunarity, offset, gain, distortion):
        detail = np.clip(detail, _F32(0.0), _F32(15.0))
        roughness = np.maximum(roughness, _F32(0.0))
        p = _coordinates(dimensions, vector * scale, w * scale)
        value, colour = noise_texture(p, detail, roughness, lacunarity, offset, gain,
                                      distortion, noise_type, bool(normalize), colour=coloured)
        return value, (_F32(0.0) if colour is None else colour)

    coloured = needed is None or "Color" in needed

    return blockwise(kernel, [mapped(float32_vector(vector), texture_mapping)]
                     + _floats(w, scale, detail, roughness, lacunarity, offset, gain,
                               distortion),
                     (FLOAT, COLOR), cost=2 ** (dimensions + 1))


# ---- Voronoi -----------------------------------------------------------------------------

@node("ShaderNodeTexVoronoi",
      inputs=(("Vector", VECTOR), ("W", FLOAT), ("Scale", FLOAT), ("Detail", FLOAT),
              ("Roughness", FLOAT), ("Lacunarity", FLOAT), ("Smoothness", FLOAT),
              ("Exponent", FLOAT), ("Randomness", FLOAT)),
      outputs=(("Distance", FLOAT), ("Color", COLOR), ("Position", VECTOR), ("W", FLOAT),
               ("Radius", FLOAT)),
      options=("voronoi_dimensions", "distance", "feature", "normalize", "texture_mapping"),
      implicit={"Vector": "generated"})
def voronoi_texture_node(points, vector, w, scale, detail, roughness, lacunarity, smoothness,
                         exponent, randomness, *, voronoi_dimensions="3D", distance="EUCLIDEAN",
                         feature="F1", normalize=False, texture_mapping=None, needed=None):
    """Worley noise (Cycles' svm_node_tex_voronoi).  Distance to Edge sets only Distance,
    N-Sphere Radius only Radius; the other outputs are 0 as in Cycles.  needed: as Noise's
    (the colour's hashes are skipped when Color is not read)."""
    node_type = "ShaderNodeTexVoronoi"
    dimensions = _dimensions(node_type, "voronoi_dimensions", voronoi_dimensions)
    _option(node_type, "distance", distance, METRICS)
    _option(node_type, "feature", feature, FEATURES)
    cells = (5 if feature == "SMOOTH_F1" else 3) ** dimensions

    def kernel(vector, w, scale, detail, roughness, lacunarity, smoothness, exponent,
               randomness):
        randomness = np.clip(randomness, _F32(0.0), _F32(1.0))
        params = VoronoiParams(
            scale=scale, detail=np.clip(detail, _F32(0.0), _F32(15.0)),
            roughness=np.clip(roughness, _F32(0.0), _F32(1.0)), lacunarity=lacunarity,
            smoothness=np.clip(smoothness / _F32(2.0), _F32(0.0), _F32(0.5)),
            exponent=exponent, randomness=randomness,
            max_distance=max_distance(feature, distance, dimensions, randomness, exponent),
            normalize=bool(normalize), feature=feature, metric=distance,
            colour=needed is None or "Color" in needed)
        coord = _coordinates(dimensions, vector * scale, w * scale)
        zero = np.zeros(coord.shape[1:], _F32)
        if feature == "DISTANCE_TO_EDGE":
            return (fractal_voronoi_distance_to_edge(params, coord), _grey(zero), _grey(zero),
                    zero, zero)
        if feature == "N_SPHERE_RADIUS":
            return zero, _grey(zero), _grey(zero), zero, voronoi_n_sphere_radius(params, coord)
        found, colour, position = fractal_voronoi(params, coord)
        return found, colour, position[:3], position[3], zero

    return blockwise(kernel, [mapped(float32_vector(vector), texture_mapping)]
                     + _floats(w, scale, detail, roughness, lacunarity, smoothness, exponent,
                               randomness),
                     (FLOAT, COLOR, VECTOR, FLOAT, FLOAT), cost=4 * cells)


# ---- Wave --------------------------------------------------------------------------------

WAVE_TYPES = ("BANDS", "RINGS")
BANDS_DIRECTIONS = ("X", "Y", "Z", "DIAGONAL")
RINGS_DIRECTIONS = ("X", "Y", "Z", "SPHERICAL")
WAVE_PROFILES = ("SIN", "SAW", "TRI")


def wave(p, wave_type, bands_direction, rings_direction, wave_profile, distortion, detail,
         detail_scale, detail_roughness, phase):
    """Cycles' svm_wave at the scaled (3, m) points p.  Multiply-adds are fused where
    Blender's build fuses them (measured against its renders), and the division by 2 pi is
    its product by 1 / 2 pi."""
    p = (p + _F32(0.000001)) * _F32(0.999999)
    if wave_type == "BANDS":
        if bands_direction == "DIAGONAL":
            n = (p[0] + p[1] + p[2]) * _F32(10.0)
        else:
            n = p["XYZ".index(bands_direction)] * _F32(20.0)
    else:
        rp = p if rings_direction == "SPHERICAL" else p * np.array(
            [[axis != rings_direction] for axis in "XYZ"], _F32)
        length = np.sqrt((rp[0] * rp[0] + rp[1] * rp[1]) + rp[2] * rp[2])
        n = length * _F32(20.0)
    n = n + phase
    distorted = distortion != 0
    if np.any(distorted):
        fbm = noise_fbm(p * detail_scale, detail, detail_roughness, _F32(2.0), True)
        shifted = fused_multiply_add(distortion, fused_multiply_add(fbm, _F32(2.0), _F32(-1.0)),
                                     n)
        n = np.where(distorted, shifted, n)
    if wave_profile == "SIN":
        return fused_multiply_add(_F32(0.5), _sin(n - _HALF_PI), _F32(0.5))
    n_turns = n * _ONE_OVER_TWO_PI
    if wave_profile == "SAW":
        return n_turns - np.floor(n_turns)
    # The build fuses the product into n + 0.5 (not into the difference).
    nearest = np.floor(fused_multiply_add(n, _ONE_OVER_TWO_PI, _F32(0.5)))
    return np.abs(n_turns - nearest) * _F32(2.0)


@node("ShaderNodeTexWave",
      inputs=(("Vector", VECTOR), ("Scale", FLOAT), ("Distortion", FLOAT), ("Detail", FLOAT),
              ("Detail Scale", FLOAT), ("Detail Roughness", FLOAT), ("Phase Offset", FLOAT)),
      outputs=(("Color", COLOR), ("Fac", FLOAT)),
      options=("wave_type", "bands_direction", "rings_direction", "wave_profile",
               "texture_mapping"),
      implicit={"Vector": "generated"})
def wave_texture_node(points, vector, scale, distortion, detail, detail_scale, detail_roughness,
                      phase_offset, *, wave_type="BANDS", bands_direction="X",
                      rings_direction="X", wave_profile="SIN", texture_mapping=None):
    """Bands or rings (Cycles' svm_node_tex_wave); Color is Fac in grey."""
    node_type = "ShaderNodeTexWave"
    _option(node_type, "wave_type", wave_type, WAVE_TYPES)
    _option(node_type, "bands_direction", bands_direction, BANDS_DIRECTIONS)
    _option(node_type, "rings_direction", rings_direction, RINGS_DIRECTIONS)
    _option(node_type, "wave_profile", wave_profile, WAVE_PROFILES)

    def kernel(vector, scale, distortion, detail, detail_scale, detail_roughness, phase):
        fac = wave(vector * scale, wave_type, bands_direction, rings_direction, wave_profile,
                   distortion, detail, detail_scale, detail_roughness, phase)
        return _grey(fac), fac

    return blockwise(kernel, [mapped(float32_vector(vector), texture_mapping)]
                     + _floats(scale, distortion, detail, detail_scale, detail_roughness,
                               phase_offset),
                     (COLOR, FLOAT), cost=16)


# ---- Magic -------------------------------------------------------------------------------

@node("ShaderNodeTexMagic",
      inputs=(("Vector", VECTOR), ("Scale", FLOAT), ("Distortion", FLOAT)),
      outputs=(("Color", COLOR), ("Fac", FLOAT)),
      options=("turbulence_depth", "texture_mapping"),
      implicit={"Vector": "generated"})
def magic_texture_node(points, vector, scale, distortion, *, turbulence_depth=2,
                       texture_mapping=None):
    """Psychedelic sines (Cycles' svm_node_tex_magic); Fac is the colour's average."""
    depth = int(turbulence_depth)

    def kernel(vector, scale, distortion):
        colour = magic(vector, scale, depth, distortion)
        return colour, (colour[0] + colour[1] + colour[2]) * _F32(1.0 / 3.0)

    return blockwise(kernel, [mapped(float32_vector(vector), texture_mapping)]
                     + _floats(scale, distortion), (COLOR, FLOAT))


def magic(p, scale, depth: int, distortion):
    """Cycles' svm_magic: the (3, m) colour at the (3, m) points p, which are wrapped into
    (-2 pi, 2 pi) before Scale applies, as Cycles does."""
    px, py, pz = (np.fmod(p[axis], _TWO_PI) for axis in range(3))
    x = _sin((px + py + pz) * _F32(5.0) * scale)
    y = _cos((-px + py - pz) * _F32(5.0) * scale)
    z = -_cos((-px - py + pz) * _F32(5.0) * scale)
    if depth > 0:
        x = x * distortion
        y = y * distortion
        z = z * distortion
        y = -_cos(x - y + z) * distortion
        # Each further level rewrites one component from all three, as Cycles' nested ifs.
        steps = ((0, lambda x, y, z: _cos(x - y - z)),
                 (2, lambda x, y, z: _sin(-x - y - z)),
                 (0, lambda x, y, z: -_cos(-x + y - z)),
                 (1, lambda x, y, z: -_sin(-x + y + z)),
                 (1, lambda x, y, z: -_cos(-x + y + z)),
                 (0, lambda x, y, z: _cos(x + y + z)),
                 (2, lambda x, y, z: _sin(x + y - z)),
                 (0, lambda x, y, z: -_cos(-x - y + z)),
                 (1, lambda x, y, z: -_sin(x - y + z)))
        for level, (axis, step) in enumerate(steps, start=2):
            if depth < level:
                break
            value = step(x, y, z) * distortion
            x, y, z = (value if axis == 0 else x, value if axis == 1 else y,
                       value if axis == 2 else z)
    distorted = distortion != 0
    if np.any(distorted):
        # x /= 2 distortion, and y and z: the build divides once and multiplies thrice.
        inverse = _F32(1.0) / np.where(distorted, distortion * _F32(2.0), _F32(1.0))
        x, y, z = (np.where(distorted, c * inverse, c) for c in (x, y, z))
    half = _F32(0.5)
    return np.stack(np.broadcast_arrays(half - x, half - y, half - z))


# ---- Gradient ----------------------------------------------------------------------------

GRADIENT_TYPES = ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "SPHERICAL", "QUADRATIC_SPHERE",
                  "RADIAL")


def gradient(p, gradient_type: str):
    """Cycles' svm_gradient, saturated, at the (3, m) points p."""
    x, y, z = p
    zero, one = _F32(0.0), _F32(1.0)
    if gradient_type == "LINEAR":
        f = x
    elif gradient_type == "QUADRATIC":
        r = np.maximum(x, zero)
        f = r * r
    elif gradient_type == "EASING":
        r = np.clip(x, zero, one)
        t = r * r
        f = fused_multiply_add(_F32(3.0), t, -(_F32(2.0) * t * r))
    elif gradient_type == "DIAGONAL":
        f = (x + y) * _F32(0.5)
    elif gradient_type == "RADIAL":
        angle = np.arctan2(y.astype(np.float64), x.astype(np.float64)).astype(_F32)
        f = fused_multiply_add(angle, _ONE_OVER_TWO_PI, _F32(0.5))
    else:
        length = np.sqrt(fused_multiply_add(z, z, fused_multiply_add(x, x, y * y)))
        r = np.maximum(_F32(0.999999) - length, zero)
        f = r * r if gradient_type == "QUADRATIC_SPHERE" else r
    return np.clip(f, zero, one)


@node("ShaderNodeTexGradient",
      inputs=(("Vector", VECTOR),),
      outputs=(("Color", COLOR), ("Fac", FLOAT)),
      options=("gradient_type", "texture_mapping"),
      implicit={"Vector": "generated"})
def gradient_texture_node(points, vector, *, gradient_type="LINEAR", texture_mapping=None):
    """A ramp along x, its variants and spheres (Cycles' svm_node_tex_gradient); Color is
    Fac in grey."""
    _option("ShaderNodeTexGradient", "gradient_type", gradient_type, GRADIENT_TYPES)
    fac = gradient(mapped(float32_vector(vector), texture_mapping), gradient_type)
    return _grey(fac), fac


# ---- Checker -----------------------------------------------------------------------------

def checker(p):
    """Cycles' svm_checker: 1 on the squares where the parities of floor(x), floor(y) and
    floor(z) agree as Cycles counts them, else 0."""
    p = (p + _F32(0.000001)) * _F32(0.999999)
    xi, yi, zi = (np.abs(float_to_int(np.floor(p[axis]))) & 1 for axis in range(3))
    return ((xi == yi) == (zi == 1)).astype(_F32)


@node("ShaderNodeTexChecker",
      inputs=(("Vector", VECTOR), ("Color1", COLOR), ("Color2", COLOR), ("Scale", FLOAT)),
      outputs=(("Color", COLOR), ("Fac", FLOAT)),
      options=("texture_mapping",),
      implicit={"Vector": "generated"})
def checker_texture_node(points, vector, color1, color2, scale, *, texture_mapping=None):
    """Checkerboard (Cycles' svm_node_tex_checker)."""
    vector = mapped(float32_vector(vector), texture_mapping)
    color1, color2 = float32_vector(color1), float32_vector(color2)
    fac = checker(vector * np.asarray(scale, _F32))
    return np.where(fac == 1, color1, color2), fac


# ---- Brick -------------------------------------------------------------------------------

def _brick_noise(n):
    """Cycles' brick_noise: a fast integer hash of uint32 n to [0, 1)."""
    n = (n + np.uint32(1013)) & np.uint32(0x7FFFFFFF)
    n = (n >> np.uint32(13)) ^ n
    nn = (n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)) \
        & np.uint32(0x7FFFFFFF)
    return _F32(0.5) * (nn.astype(_F32) / _F32(1073741824.0))


def _smoothstepf(f):
    """Cycles' smoothstepf: 3 f^2 - 2 f^3 on [0, 1], clamped outside."""
    ff = f * f
    cubic = fused_multiply_add(_F32(3.0), ff, -(_F32(2.0) * ff * f))
    return np.where(f <= 0, _F32(0.0), np.where(f >= 1, _F32(1.0), cubic))


def brick(p, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount,
          offset_frequency: int, squash_amount, squash_frequency: int):
    """Cycles' svm_brick at the scaled (3, m) points p: (tint, mortar)."""
    rownum = float_to_int(np.floor(p[1] / row_height))
    offset = _F32(0.0)
    if offset_frequency and squash_frequency:
        squashed = np.fmod(rownum, squash_frequency) == 0
        brick_width = np.where(squashed, brick_width * squash_amount, brick_width)
        shifted = np.fmod(rownum, offset_frequency) == 0
        offset = np.where(shifted, brick_width * offset_amount, _F32(0.0))
    bricknum = float_to_int(np.floor((p[0] + offset) / brick_width))
    x = (p[0] + offset) - brick_width * bricknum.astype(_F32)
    y = p[1] - row_height * rownum.astype(_F32)
    key = (rownum.view(np.uint32) << np.uint32(16)) + (bricknum & 0xFFFF).view(np.uint32)
    tint = np.clip(_brick_noise(key) + bias, _F32(0.0), _F32(1.0))
    min_dist = np.minimum(np.minimum(x, y), np.minimum(brick_width - x, row_height - y))
    with np.errstate(divide="ignore", invalid="ignore"):
        smooth = _smoothstepf((_F32(1.0) - min_dist / mortar_size) / mortar_smooth)
    mortar = np.where(min_dist >= mortar_size, _F32(0.0),
                      np.where(mortar_smooth == 0, _F32(1.0), smooth))
    return tint, mortar


@node("ShaderNodeTexBrick",
      inputs=(("Vector", VECTOR), ("Color1", COLOR), ("Color2", COLOR), ("Mortar", COLOR),
              ("Scale", FLOAT), ("Mortar Size", FLOAT), ("Mortar Smooth", FLOAT), ("Bias", FLOAT),
              ("Brick Width", FLOAT), ("Row Height", FLOAT)),
      outputs=(("Color", COLOR), ("Fac", FLOAT)),
      options=("offset", "offset_frequency", "squash", "squash_frequency", "texture_mapping"),
      implicit={"Vector": "generated"})
def brick_texture_node(points, vector, color1, color2, mortar, scale, mortar_size,
                       mortar_smooth, bias, brick_width, row_height, *, offset=0.5,
                       offset_frequency=2, squash=1.0, squash_frequency=2,
                       texture_mapping=None):
    """Bricks and mortar (Cycles' svm_node_tex_brick): Fac is the mortar's weight, Color
    each brick's random mix of Color1 and Color2 blended with Mortar by it."""

    def kernel(vector, color1, color2, mortar_colour, scale, mortar_size, mortar_smooth, bias,
               brick_width, row_height):
        tint, fac = brick(vector * scale, mortar_size, mortar_smooth, bias, brick_width,
                          row_height, _F32(offset), int(offset_frequency), _F32(squash),
                          int(squash_frequency))
        # Each sum of two products fuses its second product (evaluated first).
        tinted = fused_multiply_add(tint, color2, (_F32(1.0) - tint) * color1)
        brick_colour = np.where(fac != 1, tinted, color1)
        return fused_multiply_add(mortar_colour, fac, brick_colour * (_F32(1.0) - fac)), fac

    return blockwise(kernel, [mapped(float32_vector(vector), texture_mapping),
                              float32_vector(color1), float32_vector(color2),
                              float32_vector(mortar)]
                     + _floats(scale, mortar_size, mortar_smooth, bias, brick_width,
                               row_height),
                     (COLOR, FLOAT))


# ---- White Noise -------------------------------------------------------------------------

@node("ShaderNodeTexWhiteNoise",
      inputs=(("Vector", VECTOR), ("W", FLOAT)),
      outputs=(("Value", FLOAT), ("Color", COLOR)),
      options=("noise_dimensions",))
def white_noise_texture_node(points, vector, w, *, noise_dimensions="3D"):
    """A random value and colour per input coordinate (Cycles' svm_node_tex_white_noise):
    the coordinate's float32 bits hashed."""
    dimensions = _dimensions("ShaderNodeTexWhiteNoise", "noise_dimensions", noise_dimensions)
    p = _coordinates(dimensions, float32_vector(vector), np.asarray(w, _F32))
    value = (hash_float_to_float, hash_float2_to_float, hash_float3_to_float,
             hash_float4_to_float)[dimensions - 1](*p)
    colour = (hash_float_to_float3, hash_float2_to_float3, hash_float3_to_float3,
              hash_float4_to_float3)[dimensions - 1](*p)
    return value, colour
