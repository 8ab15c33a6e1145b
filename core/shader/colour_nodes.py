"""Blender's colour nodes over arrays of shading points, as Cycles evaluates them
(intern/cycles/kernel/svm: ramp.h, mix.h, color_util.h, invert.h, hsv.h, brightness.h,
gamma.h, convert.h, blackbody.h, wavelength.h): Color Ramp, RGB/Float/Vector Curves, Mix
and the legacy MixRGB, Invert, Hue/Saturation/Value, Brightness/Contrast, Gamma, RGB to BW,
Blackbody and Wavelength.

Color Ramp and the curves are looked up in tables as Cycles bakes them: RAMP_TABLE_SIZE
entries evaluated at evenly spaced positions, read with linear interpolation (none for a
constant ramp) and, for curves set to extrapolate, extended along the slope of their last
two entries.  The ramp's table is made here from its stops (``ramp_table``, Blender's
``BKE_colorband_evaluate``); a curve's table is evaluated by Blender itself in the add-on
(``addon.export.node_options``), as Cycles does, since a curve's shape is Blender's Bezier
code with its handle rules.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..vectors import dot
from .colour_models import (IDENTITY, REC709_LUMINANCE, XYZ_TO_REC709, apply_matrix,
                            blackbody_rec709, hsl_to_rgb, hsv_to_rgb, rgb_to_hsl, rgb_to_hsv,
                            wavelength_xyz)
from .registry import COLOR, FLOAT, VECTOR, node

#: Entries of a baked Color Ramp or curve table: positions 0, 1/256, ..., 1 (Cycles bakes
#: RAMP_TABLE_SIZE - 1 steps plus the end point).
RAMP_TABLE_SIZE = 257


def _array(value):
    value = np.asarray(value)
    return value if value.dtype.kind == "f" else value.astype(np.float64)


def table_lookup(table, position, interpolate=True, extrapolate=False):
    """(k, ...) rows of ``table`` (m, k) at ``position`` (...) in [0, 1] (Cycles'
    ``rgb_ramp_lookup``): clamped to the ends, or, with ``extrapolate``, continued outside
    [0, 1] along the slope of the two entries at that end."""
    position = _array(position)
    # One row per channel, so each channel's look-up is one gather of contiguous values.
    rows = np.ascontiguousarray(np.asarray(table, position.dtype).T)
    size = rows.shape[1]
    shape = (len(rows),) + (1,) * position.ndim
    # fmax first: a NaN position reads entry 0, as Cycles' clamp gives.
    scaled = np.fmin(np.fmax(position, 0), 1) * (size - 1)
    index = np.minimum(scaled.astype(np.intp), size - 1)
    values = np.take(rows, index, axis=1)
    if interpolate:
        fraction = scaled - index
        following = np.take(rows, np.minimum(index + 1, size - 1), axis=1)
        following -= values
        following *= fraction
        values += following
    if extrapolate:
        first, last = rows[:, 0].reshape(shape), rows[:, -1].reshape(shape)
        low = first + (first - rows[:, 1].reshape(shape)) * (-position * (size - 1))
        high = last + (last - rows[:, -2].reshape(shape)) * ((position - 1) * (size - 1))
        values = np.where(position < 0, low, np.where(position > 1, high, values))
    return values


# --- Color Ramp --------------------------------------------------------------------------------

def _key_weights(t, interpolation):
    """Blender's ``key_curve_position_weights`` (4, ...) for cardinal and B-spline ramps."""
    t2, t3 = t * t, t * t * t
    if interpolation == "CARDINAL":
        fc = 0.71
        return np.stack([-fc * t3 + 2 * fc * t2 - fc * t,
                         (2 - fc) * t3 + (fc - 3) * t2 + 1,
                         (fc - 2) * t3 + (3 - 2 * fc) * t2 + fc * t,
                         fc * t3 - fc * t2])
    sixth = 0.16666666
    return np.stack([-sixth * t3 + 0.5 * t2 - 0.5 * t + sixth,
                     0.5 * t3 - t2 + 0.66666666,
                     -0.5 * t3 + 0.5 * t2 + 0.5 * t + sixth,
                     sixth * t3])


def _hue_mix(h1, h2, fac, mode):
    """Blender's ``colorband_hue_interp``: the hue between h1 (fac 0) and h2 (fac 1) going
    the near, far, clockwise or counter-clockwise way round the hue circle."""
    h1 = np.where(h1 < 1, h1, h1 - 1)
    h2 = np.where(h2 < 1, h2, h2 - 1)
    if mode == "NEAR":
        first = (h1 < h2) & (h2 - h1 > 0.5)
        second = (h1 > h2) & (h2 - h1 < -0.5)
    elif mode == "FAR":
        first = (h1 == h2) | ((h1 < h2) & (h2 - h1 < 0.5))
        second = ~first & (h1 > h2) & (h2 - h1 > -0.5)
    elif mode == "CCW":
        first, second = np.zeros_like(h1, bool), h1 > h2
    elif mode == "CW":
        first, second = h1 < h2, np.zeros_like(h1, bool)
    else:
        raise ValueError(f"Color Ramp: unknown hue_interpolation {mode!r}")
    mixed = (1 - fac) * (h1 + first) + fac * (h2 + second)
    return np.where(first | second, np.where(mixed < 1, mixed, mixed - 1), mixed)


def _evaluate_ramp(positions, colours, x, interpolation, color_mode, hue_interpolation):
    """(m, 4) Blender's ``BKE_colorband_evaluate`` at x (m,) for sorted stops."""
    count = len(positions)
    if count == 1:
        return np.repeat(colours[:1], len(x), axis=0)
    # Blender interpolates HSV and HSL ramps linearly whatever their interpolation says.
    kind = interpolation if color_mode == "RGB" else "LINEAR"
    clamped_ends = kind in ("LINEAR", "EASE", "CONSTANT")
    after = np.searchsorted(positions, x, side="right")      # first stop past x
    # Right stop (Blender's cbd1) and left stop (cbd2); past the last stop the right one is
    # the last stop moved to 1, before the first the left one is the first moved to 0.
    right = np.minimum(after, count - 1)
    left = np.maximum(after - 1, 0)
    right_pos = np.where(after == count, 1.0, positions[right])
    left_pos = np.where(after == 0, 0.0, positions[left])
    right_colour, left_colour = colours[right], colours[left]
    with np.errstate(divide="ignore", invalid="ignore"):
        fac = (x - right_pos) / (left_pos - right_pos)
    fac = np.where(left_pos != right_pos, fac, np.where(after != count, 0.0, 1.0))
    if kind in ("CARDINAL", "B_SPLINE"):
        beyond = colours[np.where(after >= count - 1, right, np.minimum(after + 1, count - 1))]
        before = colours[np.where(after < 2, left, np.maximum(after - 2, 0))]
        weights = _key_weights(np.clip(fac, 0, 1), kind)[..., None]
        out = (weights[3] * before + weights[2] * left_colour + weights[1] * right_colour
               + weights[0] * beyond)
        out = np.clip(out, 0, 1)
    elif kind == "CONSTANT":
        out = left_colour
    else:
        if kind == "EASE":
            fac = 3 * fac * fac - 2 * fac * fac * fac
        f = fac[:, None]
        if color_mode in ("HSV", "HSL"):
            to_model, from_model = ((rgb_to_hsv, hsv_to_rgb) if color_mode == "HSV"
                                    else (rgb_to_hsl, hsl_to_rgb))
            m1, m2 = to_model(right_colour[:, :3].T), to_model(left_colour[:, :3].T)
            hue = _hue_mix(m1[0], m2[0], fac, hue_interpolation)
            mixed = np.stack([hue, (1 - fac) * m1[1] + fac * m2[1],
                              (1 - fac) * m1[2] + fac * m2[2]])
            rgb = from_model(mixed).T
            alpha = (1 - f) * right_colour[:, 3:] + f * left_colour[:, 3:]
            out = np.concatenate([rgb, alpha], axis=1)
        elif color_mode == "RGB":
            out = (1 - f) * right_colour + f * left_colour
        else:
            raise ValueError(f"Color Ramp: unknown color_mode {color_mode!r}")
    if clamped_ends:
        out = np.where((after == count)[:, None], colours[-1], out)
        out = np.where((x <= positions[0])[:, None], colours[0], out)
    return out


@lru_cache(maxsize=256)
def ramp_table(elements, interpolation="LINEAR", color_mode="RGB", hue_interpolation="NEAR"):
    """(RAMP_TABLE_SIZE, 4) float32 RGBA of a Color Ramp at positions i / (size - 1), as
    Cycles bakes it.  elements: ((position, (r, g, b, a)), ...) in any order."""
    if interpolation not in ("LINEAR", "EASE", "CONSTANT", "CARDINAL", "B_SPLINE"):
        raise ValueError(f"Color Ramp: unknown interpolation {interpolation!r}")
    if not elements:
        raise ValueError("Color Ramp: no elements")
    stops = sorted(elements, key=lambda element: element[0])
    positions = np.array([position for position, _ in stops], np.float64)
    colours = np.array([tuple(colour) for _, colour in stops], np.float64)
    if colours.shape[1] != 4:
        raise ValueError("Color Ramp: each element needs an RGBA colour")
    x = np.arange(RAMP_TABLE_SIZE, dtype=np.float64) / (RAMP_TABLE_SIZE - 1)
    table = _evaluate_ramp(positions, colours, x.astype(np.float32).astype(np.float64),
                           interpolation, color_mode, hue_interpolation)
    table = table.astype(np.float32)
    table.flags.writeable = False
    return table


@node("ShaderNodeValToRGB", inputs=(("Fac", FLOAT),),
      outputs=(("Color", COLOR), ("Alpha", FLOAT)),
      options=("elements", "interpolation", "color_mode", "hue_interpolation"))
def color_ramp(points, fac, *, elements=((0.0, (0.0, 0.0, 0.0, 1.0)), (1.0, (1.0, 1.0, 1.0, 1.0))),
               interpolation="LINEAR", color_mode="RGB", hue_interpolation="NEAR"):
    table = ramp_table(tuple((float(p), tuple(map(float, c))) for p, c in elements),
                       interpolation, color_mode, hue_interpolation)
    rgba = table_lookup(table, fac, interpolate=interpolation != "CONSTANT")
    return rgba[:3].reshape((3, -1)), rgba[3]


# --- Curves ------------------------------------------------------------------------------------

def _curve_position(value, curve_min, curve_max):
    span = curve_max - curve_min
    return (value - curve_min) / (span if span != 0 else 1)


def _curves(fac, colour, table, curve_min, curve_max, extrapolate):
    fac, colour = _array(fac), _array(colour)
    position = _curve_position(colour, curve_min, curve_max)
    table = np.asarray(table, np.float32)
    mapped = np.stack([table_lookup(table[:, channel:channel + 1], position[channel],
                                    extrapolate=extrapolate)[0] for channel in range(3)])
    return (1 - fac) * colour + fac * mapped.astype(colour.dtype, copy=False)


_IDENTITY_CURVE = tuple((i / (RAMP_TABLE_SIZE - 1),) * 3 for i in range(RAMP_TABLE_SIZE))


@node("ShaderNodeRGBCurve", inputs=(("Fac", FLOAT), ("Color", COLOR)),
      outputs=(("Color", COLOR),),
      options=("curve_table", "curve_min", "curve_max", "extrapolate"))
def rgb_curves(points, fac, colour, *, curve_table=_IDENTITY_CURVE, curve_min=0.0,
               curve_max=1.0, extrapolate=True):
    """curve_table: ((r, g, b), ...) the curves (with the combined curve applied under each)
    baked at RAMP_TABLE_SIZE positions from curve_min to curve_max."""
    return (_curves(fac, colour, curve_table, curve_min, curve_max, extrapolate),)


@node("ShaderNodeVectorCurve", inputs=(("Fac", FLOAT), ("Vector", VECTOR)),
      outputs=(("Vector", VECTOR),),
      options=("curve_table", "curve_min", "curve_max", "extrapolate"))
def vector_curves(points, fac, vector, *, curve_table=_IDENTITY_CURVE, curve_min=-1.0,
                  curve_max=1.0, extrapolate=True):
    """As RGB Curves, with the X, Y and Z curves."""
    return (_curves(fac, vector, curve_table, curve_min, curve_max, extrapolate),)


@node("ShaderNodeFloatCurve", inputs=(("Factor", FLOAT), ("Value", FLOAT)),
      outputs=(("Value", FLOAT),),
      options=("curve_table", "curve_min", "curve_max", "extrapolate"))
def float_curve(points, fac, value, *, curve_table=tuple((i / (RAMP_TABLE_SIZE - 1),)
                                                          for i in range(RAMP_TABLE_SIZE)),
                curve_min=0.0, curve_max=1.0, extrapolate=True):
    """curve_table: ((y,), ...) the curve baked at RAMP_TABLE_SIZE positions."""
    fac, value = _array(fac), _array(value)
    table = np.asarray(curve_table, np.float32).reshape(-1, 1)
    mapped = table_lookup(table, _curve_position(value, curve_min, curve_max),
                          extrapolate=extrapolate)[0]
    return ((1 - fac) * value + fac * mapped.astype(value.dtype, copy=False),)


# --- Mix ----------------------------------------------------------------------------------------

def _mix(a, b, t):
    return a + t * (b - a)


def _dodge(t, c1, c2):
    tmp = 1 - t * c2
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = c1 / np.where(tmp > 0, tmp, 1)
    dodged = np.where(tmp <= 0, 1, np.minimum(ratio, 1))
    return np.where(c1 != 0, dodged, c1)


def _burn(t, c1, c2):
    tmp = (1 - t) + t * c2
    with np.errstate(divide="ignore", invalid="ignore"):
        burned = 1 - (1 - c1) / np.where(tmp > 0, tmp, 1)
    return np.where(tmp <= 0, 0, np.clip(burned, 0, 1))


def _hue(t, c1, c2):
    hsv2 = rgb_to_hsv(c2)
    hsv = rgb_to_hsv(c1)
    shifted = hsv_to_rgb(np.stack(np.broadcast_arrays(hsv2[0], hsv[1], hsv[2])))
    return np.where(hsv2[1] != 0, _mix(c1, shifted, t), c1)


def _saturation(t, c1, c2):
    hsv, hsv2 = rgb_to_hsv(c1), rgb_to_hsv(c2)
    mixed = hsv_to_rgb(np.stack(np.broadcast_arrays(hsv[0], (1 - t) * hsv[1] + t * hsv2[1],
                                                    hsv[2])))
    return np.where(hsv[1] != 0, mixed, c1)


def _value(t, c1, c2):
    hsv, hsv2 = rgb_to_hsv(c1), rgb_to_hsv(c2)
    return hsv_to_rgb(np.stack(np.broadcast_arrays(hsv[0], hsv[1],
                                                   (1 - t) * hsv[2] + t * hsv2[2])))


def _colour(t, c1, c2):
    hsv, hsv2 = rgb_to_hsv(c1), rgb_to_hsv(c2)
    recoloured = hsv_to_rgb(np.stack(np.broadcast_arrays(hsv2[0], hsv2[1], hsv[2])))
    return np.where(hsv2[1] != 0, _mix(c1, recoloured, t), c1)


def _overlay(t, c1, c2):
    tm = 1 - t
    return np.where(c1 < 0.5, c1 * (tm + 2 * t * c2), 1 - (tm + 2 * t * (1 - c2)) * (1 - c1))


def _soft_light(t, c1, c2):
    screen = 1 - (1 - c2) * (1 - c1)
    return (1 - t) * c1 + t * ((1 - c1) * c2 * c1 + c1 * screen)


def _divide(t, c1, c2):
    with np.errstate(divide="ignore", invalid="ignore"):
        divided = (1 - t) * c1 + t * c1 / np.where(c2 != 0, c2, 1)
    return np.where(c2 != 0, divided, c1)


#: Blender's blend modes (the Mix node's blend_type) as Cycles' ``svm_mix``: (t, A, B) -> result.
BLEND_MODES = {
    "MIX": lambda t, a, b: _mix(a, b, t),
    "DARKEN": lambda t, a, b: _mix(a, np.minimum(a, b), t),
    "MULTIPLY": lambda t, a, b: _mix(a, a * b, t),
    "BURN": _burn,
    "LIGHTEN": lambda t, a, b: _mix(a, np.maximum(a, b), t),
    "SCREEN": lambda t, a, b: 1 - ((1 - t) + t * (1 - b)) * (1 - a),
    "DODGE": _dodge,
    "ADD": lambda t, a, b: _mix(a, a + b, t),
    "OVERLAY": _overlay,
    "SOFT_LIGHT": _soft_light,
    "LINEAR_LIGHT": lambda t, a, b: a + t * (2 * b - 1),
    "DIFFERENCE": lambda t, a, b: _mix(a, np.abs(a - b), t),
    "EXCLUSION": lambda t, a, b: np.maximum(_mix(a, a + b - 2 * a * b, t), 0),
    "SUBTRACT": lambda t, a, b: _mix(a, a - b, t),
    "DIVIDE": _divide,
    "HUE": _hue,
    "SATURATION": _saturation,
    "COLOR": _colour,
    "VALUE": _value,
}


def blend(blend_type, t, a, b):
    """(3, n) Cycles' ``svm_mix`` of colours a and b (3, ...) by factor t (...)."""
    try:
        function = BLEND_MODES[blend_type]
    except KeyError:
        raise ValueError(f"Mix: unknown blend_type {blend_type!r}") from None
    result = function(t, a, b)
    return np.stack(np.broadcast_arrays(*result)).reshape((3, -1))


@node("ShaderNodeMix",
      inputs=(("Factor_Float", FLOAT), ("Factor_Vector", VECTOR), ("A_Float", FLOAT),
              ("B_Float", FLOAT), ("A_Vector", VECTOR), ("B_Vector", VECTOR),
              ("A_Color", COLOR), ("B_Color", COLOR)),
      outputs=(("Result_Float", FLOAT), ("Result_Vector", VECTOR), ("Result_Color", COLOR)),
      options=("data_type", "factor_mode", "blend_type", "clamp_factor", "clamp_result"))
def mix(points, factor, factor_vector, a_float, b_float, a_vector, b_vector, a_colour,
        b_colour, *, data_type="FLOAT", factor_mode="UNIFORM", blend_type="MIX",
        clamp_factor=True, clamp_result=False):
    """The output of ``data_type`` is computed; the other two are zero (Blender hides them)."""
    if data_type == "VECTOR" and factor_mode == "NON_UNIFORM":
        factor = _array(factor_vector)
    else:
        factor = _array(factor)
    zero_float, zero_vector = np.zeros((), factor.dtype), np.zeros((3, 1), factor.dtype)
    if clamp_factor:
        factor = np.clip(factor, 0, 1)
    if data_type == "FLOAT":
        a, b = _array(a_float), _array(b_float)
        return np.asarray(a * (1 - factor) + b * factor), zero_vector, zero_vector
    if data_type == "VECTOR":
        a, b = _array(a_vector), _array(b_vector)
        return zero_float, np.asarray(a * (1 - factor) + b * factor), zero_vector
    if data_type != "RGBA":
        raise ValueError(f"Mix: data_type {data_type!r} is not supported in shaders")
    result = blend(blend_type, factor, _array(a_colour), _array(b_colour))
    if clamp_result:
        result = np.clip(result, 0, 1)
    return zero_float, zero_vector, result


@node("ShaderNodeMixRGB", inputs=(("Fac", FLOAT), ("Color1", COLOR), ("Color2", COLOR)),
      outputs=(("Color", COLOR),), options=("blend_type", "use_clamp"),
      note="the second colour's alpha (Use Alpha) is ignored, as in Cycles")
def mix_rgb(points, fac, colour1, colour2, *, blend_type="MIX", use_clamp=False):
    """The legacy MixRGB node: its factor is always clamped to [0, 1] (Cycles)."""
    result = blend(blend_type, np.clip(_array(fac), 0, 1), _array(colour1), _array(colour2))
    return (np.clip(result, 0, 1) if use_clamp else result,)


# --- Colour adjustments ----------------------------------------------------------------------

@node("ShaderNodeInvert", inputs=(("Fac", FLOAT), ("Color", COLOR)),
      outputs=(("Color", COLOR),))
def invert(points, fac, colour):
    fac, colour = _array(fac), _array(colour)
    return (fac * (1 - colour) + (1 - fac) * colour,)


@node("ShaderNodeHueSaturation",
      inputs=(("Hue", FLOAT), ("Saturation", FLOAT), ("Value", FLOAT), ("Fac", FLOAT),
              ("Color", COLOR)),
      outputs=(("Color", COLOR),))
def hue_saturation(points, hue, saturation, value, fac, colour):
    hue, saturation, value, fac, colour = map(_array, (hue, saturation, value, fac, colour))
    hsv = rgb_to_hsv(colour)
    shifted = hsv[0] + hue + 0.5
    adjusted = hsv_to_rgb(np.stack(np.broadcast_arrays(
        shifted - np.floor(shifted), np.clip(hsv[1] * saturation, 0, 1), hsv[2] * value)))
    # Oversaturation can make channels negative: Cycles clamps them to 0.
    return (np.maximum(fac * adjusted + (1 - fac) * colour, 0),)


@node("ShaderNodeBrightContrast", inputs=(("Color", COLOR), ("Bright", FLOAT),
                                          ("Contrast", FLOAT)),
      outputs=(("Color", COLOR),))
def brightness_contrast(points, colour, bright, contrast):
    colour, bright, contrast = _array(colour), _array(bright), _array(contrast)
    return (np.maximum((1 + contrast) * colour + (bright - contrast * 0.5), 0),)


@node("ShaderNodeGamma", inputs=(("Color", COLOR), ("Gamma", FLOAT)),
      outputs=(("Color", COLOR),))
def gamma(points, colour, gamma):
    """Positive channels raised to gamma, others kept; white for gamma 0 (Cycles)."""
    colour, gamma = _array(colour), _array(gamma)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        raised = np.where(colour > 0, np.power(np.maximum(colour, 0), gamma), colour)
    return (np.where(gamma == 0, 1, raised),)


@node("ShaderNodeRGBToBW", inputs=(("Color", COLOR),), outputs=(("Val", FLOAT),),
      options=("luminance",))
def rgb_to_bw(points, colour, *, luminance=REC709_LUMINANCE):
    """The working space's luminance (``luminance``: its RGB -> Y weights)."""
    colour = _array(colour)
    weights = np.asarray(luminance, colour.dtype).reshape((3,) + (1,) * (colour.ndim - 1))
    return (dot(colour, weights),)


@node("ShaderNodeBlackbody", inputs=(("Temperature", FLOAT),), outputs=(("Color", COLOR),),
      options=("rec709_to_scene",))
def blackbody(points, temperature, *, rec709_to_scene=IDENTITY):
    """Cycles' Rec.709 fit moved into the working space (``rec709_to_scene``, 3 x 3) and
    clamped to 0."""
    colour = apply_matrix(rec709_to_scene, blackbody_rec709(_array(temperature)))
    return (np.maximum(colour, 0).reshape((3, -1)),)


#: Cycles divides the Wavelength node's colour by this so that no channel exceeds 1.
WAVELENGTH_SCALE = 1 / 2.52


@node("ShaderNodeWavelength", inputs=(("Wavelength", FLOAT),), outputs=(("Color", COLOR),),
      options=("xyz_to_scene",))
def wavelength(points, wavelength, *, xyz_to_scene=XYZ_TO_REC709):
    """The CIE colour of the wavelength (nm) in the working space (``xyz_to_scene``: its
    XYZ -> RGB matrix), clamped to 0."""
    colour = apply_matrix(xyz_to_scene, wavelength_xyz(_array(wavelength))) * WAVELENGTH_SCALE
    return (np.maximum(colour, 0).reshape((3, -1)),)
