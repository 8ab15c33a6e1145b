"""Blender's converter and vector nodes over arrays of shading points, as Cycles evaluates
them (intern/cycles/kernel/svm: math_util.h, map_range.h, clamp.h, sepcomb_*.h,
vector_rotate.h, mapping_util.h, vector_transform.h): Math, Vector Math, Map Range, Clamp,
Separate/Combine XYZ and Color, Vector Rotate, Mapping and Vector Transform.

Each operation keeps Cycles' guards ("safe" divisions, powers, logarithms: 0 where the
plain expression has no value), so a program gives the numbers Cycles gives, not NaNs.
Blender 5 no longer defines the legacy Separate/Combine RGB and HSV nodes: files that have
them load them as Separate/Combine Color in RGB or HSV mode (Blender's versioning), so they
are not registered.
"""

from __future__ import annotations

import numpy as np

from ..vectors import cross, dot, safe_normalize
from .colour_models import hsl_to_rgb, hsv_to_rgb, rgb_to_hsl, rgb_to_hsv
from .point_data import ObjectFrame
from .registry import COLOR, FLOAT, VECTOR, node

#: The smallest difference Math's Compare treats as unequal (float32's epsilon, as Cycles).
FLT_EPSILON = float(np.finfo(np.float32).eps)


def _array(value):
    value = np.asarray(value)
    return value if value.dtype.kind == "f" else value.astype(np.float64)


def _zero_float(*like):
    return np.zeros((), np.result_type(*like))


def _zero_vector(*like):
    return np.zeros((3, 1), np.result_type(*like))


# --- Cycles' guarded scalar operations (util/math_base.h), element-wise ---------------------

def safe_divide(a, b):
    """a / b, 0 where b is 0."""
    nonzero = b != 0
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(nonzero, a / np.where(nonzero, b, 1), 0)


def safe_power(a, b):
    """a ** b, 0 for a negative base with a non-integer exponent."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        result = np.power(a, b)
    return np.where((a < 0) & (b != np.trunc(b)), 0, result)


def safe_log(a, b):
    """log base b of a, 0 unless both are positive."""
    valid = (a > 0) & (b > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(valid, safe_divide(np.log(np.where(valid, a, 1)),
                                           np.log(np.where(valid, b, 2))), 0)


def safe_modulo(a, b):
    """C's fmod (the sign of a), 0 where b is 0."""
    nonzero = b != 0
    with np.errstate(invalid="ignore"):
        return np.where(nonzero, np.fmod(a, np.where(nonzero, b, 1)), 0)


def floored_modulo(a, b):
    """a - floor(a / b) b (the sign of b), 0 where b is 0."""
    nonzero = b != 0
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(nonzero, a - np.floor(a / np.where(nonzero, b, 1)) * b, 0)


def wrap(value, high, low):
    """value wrapped into [low, high); low where the range is empty."""
    span = high - low
    nonzero = span != 0
    with np.errstate(invalid="ignore", divide="ignore"):
        wrapped = value - span * np.floor((value - low) / np.where(nonzero, span, 1))
    return np.where(nonzero, wrapped, low)


def ping_pong(a, b):
    """a bounced between 0 and b; 0 where b is 0."""
    nonzero = b != 0
    scale = np.where(nonzero, b, 1) * 2
    with np.errstate(invalid="ignore"):
        fraction = (a - b) / scale
        bounced = np.abs((fraction - np.floor(fraction)) * scale - b)
    return np.where(nonzero, bounced, 0)


def smooth_min(a, b, k):
    """The polynomial smooth minimum of distance k (the plain minimum for k = 0)."""
    nonzero = k != 0
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.maximum(k - np.abs(a - b), 0) / np.where(nonzero, k, 1)
    low = np.fmin(a, b)
    return np.where(nonzero, low - h * h * h * k * (1 / 6), low)


def _inverse_sqrt(a):
    positive = a > 0
    return np.where(positive, 1 / np.sqrt(np.where(positive, a, 1)), 0)


def _atan2(y, x):
    return np.where((x == 0) & (y == 0), 0, np.arctan2(y, x))


def _compare(a, b, c):
    return ((a == b) | (np.abs(a - b) <= np.fmax(c, FLT_EPSILON))).astype(np.result_type(a, b))


def _trig(function):
    def evaluate(a, b, c):
        with np.errstate(invalid="ignore", over="ignore"):
            return function(a)
    return evaluate


MATH_OPERATIONS = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: safe_power(a, b),
    "LOGARITHM": lambda a, b, c: safe_log(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0)),
    "INVERSE_SQRT": lambda a, b, c: _inverse_sqrt(a),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": _trig(np.exp),
    "MINIMUM": lambda a, b, c: np.fmin(a, b),
    "MAXIMUM": lambda a, b, c: np.fmax(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.result_type(a, b)),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.result_type(a, b)),
    "SIGN": lambda a, b, c: np.sign(a),
    "COMPARE": _compare,
    "SMOOTH_MIN": lambda a, b, c: smooth_min(a, b, c),
    "SMOOTH_MAX": lambda a, b, c: -smooth_min(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: safe_modulo(a, b),
    "FLOORED_MODULO": lambda a, b, c: floored_modulo(a, b),
    "WRAP": lambda a, b, c: wrap(a, b, c),
    "SNAP": lambda a, b, c: np.floor(safe_divide(a, b)) * b,
    "PINGPONG": lambda a, b, c: ping_pong(a, b),
    "SINE": _trig(np.sin),
    "COSINE": _trig(np.cos),
    "TANGENT": _trig(np.tan),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1, 1)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1, 1)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: _atan2(a, b),
    "SINH": _trig(np.sinh),
    "COSH": _trig(np.cosh),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: a * (np.pi / 180),
    "DEGREES": lambda a, b, c: a * (180 / np.pi),
}


def _operation(table, name, node_name):
    try:
        return table[name]
    except KeyError:
        raise ValueError(f"{node_name}: unknown operation {name!r}") from None


@node("ShaderNodeMath",
      inputs=(("Value", FLOAT), ("Value_001", FLOAT), ("Value_002", FLOAT)),
      outputs=(("Value", FLOAT),), options=("operation", "use_clamp"))
def math(points, a, b, c, *, operation="ADD", use_clamp=False):
    a, b, c = _array(a), _array(b), _array(c)
    result = np.asarray(_operation(MATH_OPERATIONS, operation, "Math")(a, b, c))
    if use_clamp:
        result = np.clip(result, 0, 1)
    return (result,)


# --- Vector Math ------------------------------------------------------------------------------

def project(a, b):
    squared = dot(b, b)
    return b * safe_divide(dot(a, b), squared)


def reflect(a, normal):
    return a - 2 * normal * dot(a, normal)


def refract(a, normal, eta):
    """Cycles' ``refract`` of the incident a about unit ``normal``: zero on total internal
    reflection."""
    cosine = dot(normal, a)
    k = 1 - eta * eta * (1 - cosine * cosine)
    inside = k >= 0
    refracted = eta * a - (eta * cosine + np.sqrt(np.where(inside, k, 0))) * normal
    return np.where(inside, refracted, 0)


def _vector_power(a, b, c, s):
    return safe_power(a, b)


VECTOR_OPERATIONS = {
    "ADD": lambda a, b, c, s: a + b,
    "SUBTRACT": lambda a, b, c, s: a - b,
    "MULTIPLY": lambda a, b, c, s: a * b,
    "DIVIDE": lambda a, b, c, s: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c, s: a * b + c,
    "CROSS_PRODUCT": lambda a, b, c, s: cross(a, b),
    "PROJECT": lambda a, b, c, s: project(a, b),
    "REFLECT": lambda a, b, c, s: reflect(a, safe_normalize(b)),
    "REFRACT": lambda a, b, c, s: refract(a, safe_normalize(b), s),
    "FACEFORWARD": lambda a, b, c, s: np.where(dot(c, b) < 0, a, -a),
    "SCALE": lambda a, b, c, s: a * s,
    "NORMALIZE": lambda a, b, c, s: safe_normalize(a),
    "ABSOLUTE": lambda a, b, c, s: np.abs(a),
    "POWER": _vector_power,
    "SIGN": lambda a, b, c, s: np.sign(a),
    "MINIMUM": lambda a, b, c, s: np.fmin(a, b),
    "MAXIMUM": lambda a, b, c, s: np.fmax(a, b),
    "ROUND": lambda a, b, c, s: np.floor(a + 0.5),   # Blender 5.3's, as Cycles rounds
    "FLOOR": lambda a, b, c, s: np.floor(a),
    "CEIL": lambda a, b, c, s: np.ceil(a),
    "FRACTION": lambda a, b, c, s: a - np.floor(a),
    "MODULO": lambda a, b, c, s: safe_modulo(a, b),
    "WRAP": lambda a, b, c, s: wrap(a, b, c),
    "SNAP": lambda a, b, c, s: np.floor(safe_divide(a, b)) * b,
    "SINE": lambda a, b, c, s: np.sin(a),
    "COSINE": lambda a, b, c, s: np.cos(a),
    "TANGENT": lambda a, b, c, s: np.tan(a),
}

#: Vector Math operations whose result is the Value output (the Vector output is then 0).
VECTOR_VALUE_OPERATIONS = {
    "DOT_PRODUCT": lambda a, b: dot(a, b),
    "DISTANCE": lambda a, b: np.sqrt(dot(a - b, a - b)),
    "LENGTH": lambda a, b: np.sqrt(dot(a, a)),
}


@node("ShaderNodeVectorMath",
      inputs=(("Vector", VECTOR), ("Vector_001", VECTOR), ("Vector_002", VECTOR),
              ("Scale", FLOAT)),
      outputs=(("Vector", VECTOR), ("Value", FLOAT)), options=("operation",))
def vector_math(points, a, b, c, scale, *, operation="ADD"):
    a, b, c, scale = _array(a), _array(b), _array(c), _array(scale)
    if operation in VECTOR_VALUE_OPERATIONS:
        return _zero_vector(a, b), np.asarray(VECTOR_VALUE_OPERATIONS[operation](a, b))
    vector = _operation(VECTOR_OPERATIONS, operation, "Vector Math")(a, b, c, scale)
    return np.asarray(vector), _zero_float(a, b)


# --- Map Range, Clamp -------------------------------------------------------------------------

def _smoothstep(edge0, edge1, x):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (x - edge0) / (edge1 - edge0)
    return np.where(x < edge0, 0, np.where(x >= edge1, 1, (3 - 2 * t) * t * t))


def _smootherstep(edge0, edge1, x):
    t = np.clip(safe_divide(x - edge0, edge1 - edge0), 0, 1)
    return t * t * t * (t * (t * 6 - 15) + 10)


def clamp_range(value, low, high):
    """value clamped between low and high in whichever order they come (Clamp's Range)."""
    return np.clip(value, np.minimum(low, high), np.maximum(low, high))


def _map_range_float(value, from_min, from_max, to_min, to_max, steps, interpolation):
    span = from_max - from_min
    mapped = span != 0
    with np.errstate(divide="ignore", invalid="ignore"):
        linear = (value - from_min) / np.where(mapped, span, 1)
    if interpolation == "LINEAR":
        factor = linear
    elif interpolation == "STEPPED":
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(steps > 0, np.floor(linear * (steps + 1)) / steps, 0)
    elif interpolation == "SMOOTHSTEP":
        factor = np.where(from_min > from_max, 1 - _smoothstep(from_max, from_min, value),
                          _smoothstep(from_min, from_max, value))
    elif interpolation == "SMOOTHERSTEP":
        factor = np.where(from_min > from_max, 1 - _smootherstep(from_max, from_min, value),
                          _smootherstep(from_min, from_max, value))
    else:
        raise ValueError(f"Map Range: unknown interpolation_type {interpolation!r}")
    return np.where(mapped, to_min + factor * (to_max - to_min), 0)


def _map_range_vector(value, from_min, from_max, to_min, to_max, steps, interpolation):
    factor = safe_divide(value - from_min, from_max - from_min)
    if interpolation == "STEPPED":
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(steps > 0, np.floor(factor * (steps + 1)) / steps, 0)
    elif interpolation == "SMOOTHSTEP":
        factor = np.clip(factor, 0, 1)
        factor = (3 - 2 * factor) * factor * factor
    elif interpolation == "SMOOTHERSTEP":
        factor = np.clip(factor, 0, 1)
        factor = factor * factor * factor * (factor * (factor * 6 - 15) + 10)
    elif interpolation != "LINEAR":
        raise ValueError(f"Map Range: unknown interpolation_type {interpolation!r}")
    return to_min + factor * (to_max - to_min)


@node("ShaderNodeMapRange",
      inputs=(("Value", FLOAT), ("From Min", FLOAT), ("From Max", FLOAT), ("To Min", FLOAT),
              ("To Max", FLOAT), ("Steps", FLOAT), ("Vector", VECTOR),
              ("From_Min_FLOAT3", VECTOR), ("From_Max_FLOAT3", VECTOR),
              ("To_Min_FLOAT3", VECTOR), ("To_Max_FLOAT3", VECTOR), ("Steps_FLOAT3", VECTOR)),
      outputs=(("Result", FLOAT), ("Vector", VECTOR)),
      options=("data_type", "interpolation_type", "clamp"))
def map_range(points, value, from_min, from_max, to_min, to_max, steps, vector, from_min3,
              from_max3, to_min3, to_max3, steps3, *, data_type="FLOAT",
              interpolation_type="LINEAR", clamp=True):
    if data_type == "FLOAT_VECTOR":
        vector, to_min3, to_max3 = _array(vector), _array(to_min3), _array(to_max3)
        result = _map_range_vector(vector, _array(from_min3), _array(from_max3), to_min3,
                                   to_max3, _array(steps3), interpolation_type)
        if clamp and interpolation_type in ("LINEAR", "STEPPED"):
            result = clamp_range(result, to_min3, to_max3)
        return _zero_float(vector), np.asarray(result)
    if data_type != "FLOAT":
        raise ValueError(f"Map Range: unknown data_type {data_type!r}")
    value, to_min, to_max = _array(value), _array(to_min), _array(to_max)
    result = _map_range_float(value, _array(from_min), _array(from_max), to_min, to_max,
                              _array(steps), interpolation_type)
    if clamp:
        result = clamp_range(result, to_min, to_max)
    return np.asarray(result), _zero_vector(value)


@node("ShaderNodeClamp", inputs=(("Value", FLOAT), ("Min", FLOAT), ("Max", FLOAT)),
      outputs=(("Result", FLOAT),), options=("clamp_type",))
def clamp(points, value, low, high, *, clamp_type="MINMAX"):
    value, low, high = _array(value), _array(low), _array(high)
    if clamp_type == "RANGE":
        return (np.asarray(clamp_range(value, low, high)),)
    if clamp_type != "MINMAX":
        raise ValueError(f"Clamp: unknown clamp_type {clamp_type!r}")
    return (np.asarray(np.minimum(np.maximum(value, low), high)),)


# --- Separate / Combine -----------------------------------------------------------------------

@node("ShaderNodeSeparateXYZ", inputs=(("Vector", VECTOR),),
      outputs=(("X", FLOAT), ("Y", FLOAT), ("Z", FLOAT)))
def separate_xyz(points, vector):
    vector = _array(vector)
    return vector[0], vector[1], vector[2]


@node("ShaderNodeCombineXYZ", inputs=(("X", FLOAT), ("Y", FLOAT), ("Z", FLOAT)),
      outputs=(("Vector", VECTOR),))
def combine_xyz(points, x, y, z):
    x, y, z = np.broadcast_arrays(_array(x), _array(y), _array(z))
    return (np.stack([x, y, z]).reshape((3, -1)),)


_FROM_RGB = {"RGB": lambda colour: colour, "HSV": rgb_to_hsv, "HSL": rgb_to_hsl}
_TO_RGB = {"RGB": lambda colour: colour, "HSV": hsv_to_rgb, "HSL": hsl_to_rgb}


@node("ShaderNodeSeparateColor", inputs=(("Color", COLOR),),
      outputs=(("Red", FLOAT), ("Green", FLOAT), ("Blue", FLOAT)), options=("mode",))
def separate_color(points, colour, *, mode="RGB"):
    separated = _operation(_FROM_RGB, mode, "Separate Color")(_array(colour))
    return separated[0], separated[1], separated[2]


@node("ShaderNodeCombineColor", inputs=(("Red", FLOAT), ("Green", FLOAT), ("Blue", FLOAT)),
      outputs=(("Color", COLOR),), options=("mode",))
def combine_color(points, red, green, blue, *, mode="RGB"):
    (colour,) = combine_xyz(points, red, green, blue)
    return (_operation(_TO_RGB, mode, "Combine Color")(colour),)


# --- Rotations: Vector Rotate, Mapping --------------------------------------------------------

def euler_matrix(rotation):
    """(3, 3, ...) rotation matrices of XYZ Euler angles (3, ...): Rz Ry Rx, as Blender and
    Cycles' ``euler_to_transform``."""
    rotation = _array(rotation)
    cx, cy, cz = np.cos(rotation)
    sx, sy, sz = np.sin(rotation)
    rows = ((cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz),
            (cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz),
            (-sy, cy * sx, cy * cx))
    return np.stack([np.stack(np.broadcast_arrays(*row)) for row in rows])


def apply_rotation(matrix, vector, transposed=False):
    """matrix (3, 3, ...) times vector (3, ...), or its transpose (the inverse rotation)."""
    if transposed:
        matrix = matrix.swapaxes(0, 1)
    return np.stack([matrix[row, 0] * vector[0] + matrix[row, 1] * vector[1]
                     + matrix[row, 2] * vector[2] for row in range(3)])


def rotate_about_axis(vector, axis, angle):
    """Rodrigues' rotation of vector about the unit axis by angle (right-handed)."""
    cosine, sine = np.cos(angle), np.sin(angle)
    return (vector * cosine + cross(axis, vector) * sine
            + axis * (dot(axis, vector) * (1 - cosine)))


_AXES = {"X_AXIS": (1.0, 0.0, 0.0), "Y_AXIS": (0.0, 1.0, 0.0), "Z_AXIS": (0.0, 0.0, 1.0)}


@node("ShaderNodeVectorRotate",
      inputs=(("Vector", VECTOR), ("Center", VECTOR), ("Axis", VECTOR), ("Angle", FLOAT),
              ("Rotation", VECTOR)),
      outputs=(("Vector", VECTOR),), options=("rotation_type", "invert"))
def vector_rotate(points, vector, centre, axis, angle, rotation, *, rotation_type="AXIS_ANGLE",
                  invert=False):
    vector, centre = _array(vector), _array(centre)
    if rotation_type == "EULER_XYZ":
        matrix = euler_matrix(rotation)
        return (apply_rotation(matrix, vector - centre, transposed=invert) + centre,)
    if rotation_type in _AXES:
        axis, size = np.asarray(_AXES[rotation_type], vector.dtype).reshape(3, 1), 1.0
    elif rotation_type == "AXIS_ANGLE":
        axis = _array(axis)
        size = np.sqrt(dot(axis, axis))
        axis = axis / np.where(size != 0, size, 1)
    else:
        raise ValueError(f"Vector Rotate: unknown rotation_type {rotation_type!r}")
    angle = -_array(angle) if invert else _array(angle)
    rotated = rotate_about_axis(vector - centre, axis, angle) + centre
    return (np.where(size != 0, rotated, vector),)


@node("ShaderNodeMapping",
      inputs=(("Vector", VECTOR), ("Location", VECTOR), ("Rotation", VECTOR),
              ("Scale", VECTOR)),
      outputs=(("Vector", VECTOR),), options=("vector_type",))
def mapping(points, vector, location, rotation, scale, *, vector_type="POINT"):
    vector, location, scale = _array(vector), _array(location), _array(scale)
    matrix = euler_matrix(rotation)
    if vector_type == "POINT":
        result = apply_rotation(matrix, vector * scale) + location
    elif vector_type == "TEXTURE":
        result = safe_divide(apply_rotation(matrix, vector - location, transposed=True), scale)
    elif vector_type == "VECTOR":
        result = apply_rotation(matrix, vector * scale)
    elif vector_type == "NORMAL":
        result = safe_normalize(apply_rotation(matrix, safe_divide(vector, scale)))
    else:
        raise ValueError(f"Mapping: unknown vector_type {vector_type!r}")
    return (result,)


# --- Vector Transform -------------------------------------------------------------------------

class CameraFrame:
    """World <-> camera space as Cycles defines camera space (x right, y up, z forward into
    the view: Blender's camera matrix with its z flipped), from the 3 x 4 row-major
    ``world_to_camera`` matrix the add-on gives (identity without one)."""

    def __init__(self, world_to_camera, dtype):
        matrix = np.asarray(world_to_camera if world_to_camera is not None
                            else np.eye(3, 4), np.float64).reshape(3, 4)
        self.rotation = matrix[:, :3]
        self.translation = matrix[:, 3]
        self.inverse = np.linalg.inv(self.rotation)
        self.dtype = dtype

    def _apply(self, matrix, v, offset=None):
        result = np.tensordot(matrix.astype(self.dtype), v, axes=1)
        if offset is not None:
            result = result + offset.astype(self.dtype).reshape((3,) + (1,) * (v.ndim - 1))
        return result

    def to_camera(self, v, kind):
        if kind == "NORMAL":
            # Normals go by the inverse transpose of the world -> camera rotation.
            return safe_normalize(self._apply(self.inverse.T, v))
        return self._apply(self.rotation, v, self.translation if kind == "POINT" else None)

    def to_world(self, v, kind):
        if kind == "NORMAL":
            return safe_normalize(self._apply(self.rotation.T, v))
        if kind == "POINT":
            v = v - self.translation.astype(self.dtype).reshape((3,) + (1,) * (v.ndim - 1))
        return self._apply(self.inverse, v)


SPACES = ("WORLD", "OBJECT", "CAMERA")


@node("ShaderNodeVectorTransform", inputs=(("Vector", VECTOR),), outputs=(("Vector", VECTOR),),
      options=("vector_type", "convert_from", "convert_to", "world_to_camera"), reads_points=True)
def vector_transform(points, vector, *, vector_type="VECTOR", convert_from="WORLD",
                     convert_to="OBJECT", world_to_camera=None):
    """Cycles' conversions: the object's at each hit (``point_data.ObjectFrame``), the
    camera's from the ``world_to_camera`` option."""
    if vector_type not in ("POINT", "VECTOR", "NORMAL"):
        raise ValueError(f"Vector Transform: unknown vector_type {vector_type!r}")
    for name, space in (("convert_from", convert_from), ("convert_to", convert_to)):
        if space not in SPACES:
            raise ValueError(f"Vector Transform: unknown {name} {space!r}")
    vector = _array(vector)
    if convert_from == convert_to:
        return (vector,)
    kind = vector_type
    camera = CameraFrame(world_to_camera, vector.dtype)
    frame = ObjectFrame(points)
    if convert_from == "CAMERA":
        vector = camera.to_world(vector, kind)
    elif convert_from == "OBJECT":
        vector = frame.to_world(vector, kind)
    if convert_to == "CAMERA":
        vector = camera.to_camera(vector, kind)
    elif convert_to == "OBJECT":
        vector = frame.to_object(vector, kind)
    return (np.asarray(vector),)
