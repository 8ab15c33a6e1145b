"""Cycles' Voronoi texture (``kernel/svm/voronoi.h``) in float32 over arrays: the features
F1, F2, Smooth F1, Distance to Edge and N-Sphere Radius in 1D to 4D, with the four distance
metrics, and Blender's fractal Voronoi (Detail, Roughness, Lacunarity, Normalize).

Coordinates are (d, m) float32 arrays (components on the first axis); parameters are
float32 arrays that broadcast to (m,) or numbers.  A feature looks at the 3**d cells around
each point (5**d for Smooth F1): their random points are computed for all of them at once,
as (d, cells, m) arrays, and the nearest is chosen with ``argmin``, which keeps the first of
equal distances as Cycles' loop (``distance < best``) does, in Cycles' loop order (x
fastest).  As in Cycles, 1D cells are hashed as floats (lookup3 of their bits), 2D to 4D
cells as integers (PCG), and F1 and N-Sphere Radius compare squared Euclidean distances (or
the Minkowski sum before its root) and take the root of the winner only.  The neighbours'
hashes are computed once per run of consecutive points in the same cell (``cell_runs``), and
multiply-adds are fused where Blender's build fuses them.  Cycles' vector
helpers are followed where they round differently: a float2 or float4 divided by a float is
multiplied by its reciprocal, a float3 is divided.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .hash import hash_float_to_float, hash_float_to_float3, hash_int2_to_float2, \
    hash_int2_to_float3, hash_int3_to_float3, hash_int4_to_float3, hash_int4_to_float4
from .noise import cell_runs, float_to_int, fused_lerp, fused_multiply_add

FLT_MAX = np.float32(np.finfo(np.float32).max)
_ZERO, _HALF, _ONE = np.float32(0.0), np.float32(0.5), np.float32(1.0)

METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")


@dataclass(frozen=True)
class VoronoiParams:
    """Cycles' VoronoiParams after the node's clamping (numbers or float32 (m,) arrays)."""

    scale: object
    detail: object
    roughness: object
    lacunarity: object
    smoothness: object
    exponent: object
    randomness: object
    max_distance: object
    normalize: bool
    feature: str
    metric: str
    #: Whether the colour is wanted (False leaves it 0, and skips its hashes).
    colour: bool = True


def _offsets(dimensions: int, reach: int) -> np.ndarray:
    """(d, cells) the cell offsets -reach..reach per axis in Cycles' loop order (x fastest)."""
    steps = range(-reach, reach + 1)
    return np.array([combo[::-1] for combo in itertools.product(steps, repeat=dimensions)],
                    np.float32).T.copy()


_OFFSETS = {(d, reach): _offsets(d, reach) for d in (1, 2, 3, 4) for reach in (1, 2)}


def _cell_points(cells):
    """(d, ...) the random point of each cell, in [0, 1] per axis (before randomness): 1D
    cells are float32, the others int32."""
    d = cells.shape[0]
    if d == 1:
        return hash_float_to_float(cells[0])[None]
    if d == 2:
        return hash_int2_to_float2(*cells)
    if d == 3:
        return hash_int3_to_float3(*cells)
    return hash_int4_to_float4(*cells)


def _cell_colour(cells):
    """(3, ...) the colour of each cell."""
    return {1: hash_float_to_float3, 2: hash_int2_to_float3, 3: hash_int3_to_float3,
            4: hash_int4_to_float3}[cells.shape[0]](*cells)


def _cell_index(cell):
    """The cells Cycles hashes: floor(coord) itself in 1D, as int (make_int<d>) above."""
    return cell if cell.shape[0] == 1 else float_to_int(cell)


def _offset_index(offsets):
    return offsets if offsets.shape[0] == 1 else offsets.astype(np.int32)


def _sum(values):
    """Cycles' reduce_add / dot summation order: (x + y) + z, (x + y) + (z + w)."""
    d = values.shape[0]
    if d == 1:
        return values[0]
    if d == 2:
        return values[0] + values[1]
    if d == 3:
        return (values[0] + values[1]) + values[2]
    return (values[0] + values[1]) + (values[2] + values[3])


def _dot(a, b):
    """Cycles' dot: a float2's x * x + y * y fuses its first product into the sum; float3
    and float4 use SSE's dot-product instruction."""
    if a.shape[0] == 2:
        return fused_multiply_add(a[0], b[0], a[1] * b[1])
    return _sum(a * b)


def _power(base, exponent):
    """powf to float32 rounding (NumPy's own float32 power is a few ulps off glibc's)."""
    return np.power(np.asarray(base, np.float64), np.asarray(exponent, np.float64)).astype(
        np.float32)


def _length(a):
    return np.sqrt(_dot(a, a))


def _divide(vector, divisor):
    """vector / divisor as Cycles' float<d> operator/ rounds it: float3 divides, float2 and
    float4 multiply by 1 / divisor."""
    if vector.shape[0] == 3:
        return vector / divisor
    return vector * (_ONE / divisor)


def _normalize(vector):
    return _divide(vector, _length(vector))


def voronoi_distance(a, b, metric: str, exponent):
    """Cycles' voronoi_distance(a, b, params) between (d, ...) points; 1D ignores the
    metric."""
    difference = a - b
    if a.shape[0] == 1:
        return np.abs(difference[0])
    if metric == "EUCLIDEAN":
        return np.sqrt(_dot(difference, difference))
    if metric == "MANHATTAN":
        return _sum(np.abs(difference))
    if metric == "CHEBYCHEV":
        return np.max(np.abs(difference), axis=0)
    if metric == "MINKOWSKI":
        return _power(_sum(_power(np.abs(difference), exponent)), _ONE / exponent)
    raise ValueError(f"Voronoi distance {metric!r} is not one of {', '.join(METRICS)}")


def _position(point):
    """(4, ...) Cycles' voronoi_position: 1D (0, 0, 0, x), 2D (x, y, 0, 0), 3D (x, y, z, 1)
    (make_float4 of a float3 sets w to 1), 4D as is."""
    d = point.shape[0]
    zero = np.zeros_like(point[0])
    if d == 1:
        return np.stack([zero, zero, zero, point[0]])
    if d == 2:
        return np.stack([point[0], point[1], zero, zero])
    if d == 3:
        return np.stack([point[0], point[1], point[2], np.ones_like(zero)])
    return point


def _neighbour_hashes(function, index, offsets, runs):
    """(c, cells, m) function of each point's neighbouring cells (index (d, m) plus the
    offsets (d, cells, 1)), computed once per run of points that share a cell (``runs``,
    from ``cell_runs``, or None)."""
    if runs is None:
        return function(index[:, None] + _offset_index(offsets))
    first, run = runs
    return np.take(function(index[:, first][:, None] + _offset_index(offsets)), run, axis=-1)


def _neighbours(coord, reach, randomness):
    """The cell of each point (floor(coord), and the index Cycles hashes), its position in
    it, for each neighbouring cell (the offsets, (d, cells, 1)) its random point relative to
    the point's cell (d, cells, m), and the runs of points sharing a cell (``cell_runs``)."""
    cell = np.floor(coord)
    local = coord - cell
    index = _cell_index(cell)
    offsets = _OFFSETS[(coord.shape[0], reach)][:, :, None]
    runs = cell_runs(index) if index.ndim == 2 else None

    def random_points(cells):
        # offset + hash * randomness, fused as Blender's build computes it.
        return fused_multiply_add(_cell_points(cells), randomness, offsets)

    if np.ndim(randomness) == 0:  # the same for every point: once per run of points
        points = _neighbour_hashes(random_points, index, offsets, runs)
    else:
        points = fused_multiply_add(_neighbour_hashes(_cell_points, index, offsets, runs),
                                    randomness, offsets)
    return cell, index, local, offsets, points, runs


def _target_colour(params: VoronoiParams, index, offsets, target, found, runs):
    """(3, m) the colour of each point's chosen cell (offsets[:, target]; cell 0 where none
    was found): hashed per point, or per run of points when runs are long enough that
    hashing all of a run's neighbours costs less; 0 when the colour is not wanted."""
    if not params.colour:
        return np.zeros((3,) + index.shape[1:], np.float32)
    cells = offsets.shape[1]
    if runs is None or runs[0].size * cells > index.shape[-1]:
        return _cell_colour(index + _offset_index(_pick(offsets, target, found)))
    colours = _neighbour_hashes(_cell_colour, index, offsets, runs)
    chosen = np.take_along_axis(colours, target[None, None], axis=1)[:, 0]
    # Where nothing was found Cycles hashes the point's own cell (offset 0).
    own = np.flatnonzero(np.all(offsets[:, :, 0] == 0, axis=0))[0]
    return np.where(found, chosen, colours[:, own])


def _distance_bound(a, b, metric: str, exponent):
    """Cycles' voronoi_distance_bound: what orders distances as voronoi_distance does,
    cheaper (no root)."""
    difference = a - b
    if metric == "EUCLIDEAN":
        return _dot(difference, difference)
    if metric == "MINKOWSKI":
        return _sum(_power(np.abs(difference), exponent))
    return voronoi_distance(a, b, metric, exponent)


def _nearest(distances):
    """(index, distance, found) of the first smallest distance along axis 0, as Cycles' loop
    keeps it: only distances below FLT_MAX count (NaN never does)."""
    counted = np.where(distances < FLT_MAX, distances, np.float32(np.inf))
    index = np.argmin(counted, axis=0)
    best = np.take_along_axis(counted, index[None], axis=0)[0]
    return index, best, np.isfinite(best)


def _pick(values, index, found):
    """(c, m) values[:, index[j], j], zero where nothing was found."""
    values = np.broadcast_to(values, values.shape[:1] + (values.shape[1],) + index.shape)
    picked = np.take_along_axis(values, index[None, None], axis=1)[:, 0]
    return np.where(found, picked, _ZERO)


def voronoi_f1(params: VoronoiParams, coord):
    """(distance, colour (3, m), position (4, m)) of the nearest cell point (2D to 4D
    search by the distance bound, and measure the winner)."""
    cell, index, local, offsets, points, runs = _neighbours(coord, 1, params.randomness)
    one_d = coord.shape[0] == 1
    measure = voronoi_distance if one_d else _distance_bound
    nearest, best, found = _nearest(measure(points, local[:, None], params.metric,
                                            params.exponent))
    target_point = _pick(points, nearest, found)
    distance = best if one_d else voronoi_distance(target_point, local, params.metric,
                                                   params.exponent)
    return (np.where(found, distance, FLT_MAX),
            _target_colour(params, index, offsets, nearest, found, runs),
            _position(target_point + cell))


def voronoi_f2(params: VoronoiParams, coord):
    """(distance, colour, position) of the second nearest cell point."""
    cell, index, local, offsets, points, runs = _neighbours(coord, 1, params.randomness)
    distances = voronoi_distance(points, local[:, None], params.metric, params.exponent)
    first, _, _ = _nearest(distances)
    np.put_along_axis(distances, first[None], np.float32(np.inf), axis=0)
    second, best, found = _nearest(distances)
    target_point = _pick(points, second, found)
    return (np.where(found, best, FLT_MAX),
            _target_colour(params, index, offsets, second, found, runs),
            _position(target_point + cell))


def _smoothstep(x):
    """Cycles' smoothstep(0, 1, x)."""
    t = np.clip(x, _ZERO, _ONE)
    return np.where(x < _ZERO, _ZERO,
                    np.where(x >= _ONE, _ONE, (np.float32(3.0) - np.float32(2.0) * t) * (t * t)))


def voronoi_smooth_f1(params: VoronoiParams, coord):
    """(distance, colour, position) smoothly blended over the 5**d cells around each point,
    in Cycles' order (the blend is sequential, so it runs cell by cell)."""
    cell, index, local, offsets, points, runs = _neighbours(coord, 2, params.randomness)
    distances = voronoi_distance(points, local[:, None], params.metric, params.exponent)
    colours = _neighbour_hashes(_cell_colour, index, offsets, runs) if params.colour else None
    smoothness = params.smoothness
    damping = _ONE + np.float32(3.0) * smoothness
    distance, position = distances[0], points[:, 0]
    colour = colours[:, 0] if params.colour else np.zeros((3,) + distance.shape, np.float32)
    for k in range(1, distances.shape[0]):
        # Points whose smoothness is 0 take F1 instead (``_feature``); their 0 / 0 is unused.
        with np.errstate(divide="ignore", invalid="ignore"):
            h = _smoothstep(_HALF + _HALF * (distance - distances[k]) / smoothness)
        correction = smoothness * h * (_ONE - h)
        distance = fused_lerp(distance, distances[k], h) - correction
        correction = correction / damping
        if params.colour:
            colour = fused_lerp(colour, colours[:, k], h) - correction
        position = fused_lerp(position, points[:, k], h) - correction
    return distance, colour, _position(cell + position)


def voronoi_distance_to_edge(params: VoronoiParams, coord):
    """Distance from each point to the nearest edge of its Voronoi cell."""
    d = coord.shape[0]
    randomness = params.randomness
    if d == 1:
        cell = np.floor(coord[0])
        local = coord[0] - cell
        middle = hash_float_to_float(cell)
        left = fused_multiply_add(hash_float_to_float(cell - _ONE), randomness, -_ONE)
        right = fused_multiply_add(hash_float_to_float(cell + _ONE), randomness, _ONE)
        # The middle point's product fuses into both sums that use it.
        to_left = np.abs(fused_multiply_add(middle, randomness, left) * _HALF - local)
        to_right = np.abs(fused_multiply_add(middle, randomness, right) * _HALF - local)
        return np.minimum(to_left, to_right)
    _, _, local, _, points, _ = _neighbours(coord, 1, randomness)
    to_points = points - local[:, None]
    index, _, found = _nearest(_dot(to_points, to_points))
    to_closest = _pick(to_points, index, found)[:, None]
    across = to_points - to_closest
    # The closest point's own direction is 0 / 0; it is left out below, as Cycles skips it.
    with np.errstate(divide="ignore", invalid="ignore"):
        edge = _dot((to_closest + to_points) * _HALF, _normalize(across))
    counted = (_dot(across, across) > np.float32(0.0001)) & (edge < FLT_MAX)
    return np.min(np.where(counted, edge, FLT_MAX), axis=0)


def voronoi_n_sphere_radius(params: VoronoiParams, coord):
    """Half the distance from each point's nearest cell point to the point nearest to that
    one: the radius of the largest sphere around it that touches no other cell's sphere."""
    cell, index, local, offsets, points, _ = _neighbours(coord, 1, params.randomness)
    one_d = coord.shape[0] == 1
    # 1D compares distances, the others squared distances (Cycles' len_squared).
    measure = voronoi_distance if one_d else _distance_bound
    nearest, _, found = _nearest(measure(points, local[:, None], "EUCLIDEAN", None))
    closest = _pick(points, nearest, found)
    closest_offset = _pick(offsets, nearest, found)
    around = offsets[:, np.any(offsets[:, :, 0] != 0, axis=0)] + closest_offset[:, None]
    others = fused_multiply_add(_cell_points(index[:, None] + _offset_index(around)),
                                params.randomness, around)
    nearest, _, found = _nearest(measure(closest[:, None], others, "EUCLIDEAN", None))
    nearest_other = _pick(others, nearest, found)
    return voronoi_distance(nearest_other, closest, "EUCLIDEAN", None) / np.float32(2.0)


def _feature(params: VoronoiParams, coord):
    if params.feature == "F2":
        return voronoi_f2(params, coord)
    if params.feature == "SMOOTH_F1":
        smooth = params.smoothness != 0
        if np.all(smooth):
            return voronoi_smooth_f1(params, coord)
        nearest = voronoi_f1(params, coord)
        if not np.any(smooth):
            return nearest
        blended = voronoi_smooth_f1(params, coord)
        return tuple(np.where(smooth, b, n) for b, n in zip(blended, nearest))
    return voronoi_f1(params, coord)


def _when(mask, new, old):
    if mask is True:
        return new
    if mask is False:
        return old
    return np.where(mask, new, old)


def _mask(condition):
    """A Python bool for a 0-d condition (so that constant parameters skip np.where)."""
    condition = np.asarray(condition)
    return bool(condition) if condition.ndim == 0 else condition


def fractal_voronoi(params: VoronoiParams, coord):
    """Cycles' fractal_voronoi_x_fx: (distance, colour (3, m), position (4, m)) summed
    over Detail octaves."""
    detail = params.detail
    remainder = detail - np.floor(detail)
    zero_input = _mask((detail == 0) | (params.roughness == 0))
    octaves = int(np.ceil(np.max(detail)))
    amplitude, max_amplitude, scale = _ONE, _ZERO, _ONE
    distance, colour, position = _ZERO, np.zeros((3, 1), np.float32), np.zeros((4, 1), np.float32)
    first = None
    for i in range(octaves + 1):
        octave_distance, octave_colour, octave_position = _feature(params, coord * scale)
        if i == 0:
            first = (octave_distance, octave_colour, octave_position)
            if zero_input is True:
                break
        full = _mask(i <= detail)
        partial = _mask((i > detail) & (i <= np.ceil(detail)) & (remainder != 0))
        # The sums and lerps below fuse their products, as Blender's build does; the
        # position's lerp towards octave_position / scale (a float4 times 1 / scale) fuses
        # that product too: position + amplitude * fma(octave_position, 1 / scale, -position).
        summed_distance = fused_multiply_add(octave_distance, amplitude, distance)
        summed_colour = fused_multiply_add(octave_colour, amplitude, colour)
        towards = fused_multiply_add(octave_position, _ONE / scale, -position)
        moved_position = fused_multiply_add(amplitude, towards, position)
        if full is not False:
            max_amplitude = _when(full, max_amplitude + amplitude, max_amplitude)
            distance = _when(full, summed_distance, distance)
            colour = _when(full, summed_colour, colour)
            position = _when(full, moved_position, position)
        if partial is not False:
            max_amplitude = _when(partial, fused_lerp(max_amplitude, max_amplitude + amplitude,
                                                      remainder), max_amplitude)
            distance = _when(partial, fused_lerp(distance, summed_distance, remainder), distance)
            colour = _when(partial, fused_lerp(colour, summed_colour, remainder), colour)
            position = _when(partial, fused_lerp(position, moved_position, remainder), position)
        scale = _when(full, scale * params.lacunarity, scale)
        amplitude = _when(full, amplitude * params.roughness, amplitude)
    if zero_input is not False:
        max_amplitude = _when(zero_input, _ONE, max_amplitude)
        distance, colour, position = (_when(zero_input, f, v) for f, v in
                                      zip(first, (distance, colour, position)))
    if params.normalize:
        distance = distance / (max_amplitude * params.max_distance)
        colour = colour * (_ONE / max_amplitude)  # float3 /= float multiplies by 1 / float
    safe_scale = np.where(params.scale != 0, params.scale, _ONE)
    position = np.where(params.scale != 0, _divide(position, safe_scale), _ZERO)
    return distance, colour, position


def fractal_voronoi_distance_to_edge(params: VoronoiParams, coord):
    """Cycles' fractal_voronoi_distance_to_edge."""
    detail = params.detail
    remainder = detail - np.floor(detail)
    zero_input = _mask((detail == 0) | (params.roughness == 0))
    octaves = int(np.ceil(np.max(detail)))
    amplitude, scale = _ONE, _ONE
    max_amplitude = params.max_distance
    distance = np.float32(8.0)
    first = None
    for i in range(octaves + 1):
        octave_distance = voronoi_distance_to_edge(params, coord * scale)
        if i == 0:
            first = octave_distance
            if zero_input is True:
                break
        full = _mask(i <= detail)
        partial = _mask((i > detail) & (i <= np.ceil(detail)) & (remainder != 0))
        scaled_max = params.max_distance / scale
        nearer = fused_lerp(distance, np.minimum(distance, octave_distance / scale), amplitude)
        lower_amplitude = fused_lerp(max_amplitude, scaled_max, amplitude)
        if partial is not False:
            partial_amplitude = fused_lerp(max_amplitude, lower_amplitude, remainder)
            partial_distance = fused_lerp(distance, np.minimum(distance, nearer), remainder)
            max_amplitude = _when(partial, partial_amplitude, max_amplitude)
            distance = _when(partial, partial_distance, distance)
        if full is not False:
            max_amplitude = _when(full, lower_amplitude, max_amplitude)
            distance = _when(full, nearer, distance)
        scale = _when(full, scale * params.lacunarity, scale)
        amplitude = _when(full, amplitude * params.roughness, amplitude)
    if zero_input is not False:
        distance = _when(zero_input, first, distance)
    if params.normalize:
        distance = distance / max_amplitude
    return distance


def max_distance(feature: str, metric: str, dimensions: int, randomness, exponent):
    """Cycles' params.max_distance: the largest F1 (F2: twice it) distance a point can have,
    which Normalize divides by."""
    reach = fused_multiply_add(_HALF, randomness, _HALF)
    if feature == "DISTANCE_TO_EDGE":
        return reach
    factor = np.float32(2.0) if feature == "F2" else _ONE
    if dimensions == 1:
        return reach * factor
    corner = np.stack(np.broadcast_arrays(*([np.asarray(reach, np.float32)] * dimensions)))
    origin = np.zeros_like(corner)
    return voronoi_distance(origin, corner, metric, exponent) * factor
