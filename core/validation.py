"""Validation of scene data: the core's limits, and the checks every field of a scene
description (``core.scene``) goes through, each taking the field's full name so that an
error names the culprit and the offending value.

Scalars and triples are checked one at a time; arrays (sphere sets, meshes) in whole-array
operations, naming the first offending index.  The underscored checks are the description
modules' (``core.scene``); ``SceneError`` and the limits are public.
"""

from __future__ import annotations

import math
import numbers
from typing import Sequence

import numpy as np

Vec3 = tuple[float, float, float]


class SceneError(ValueError):
    """Invalid scene or settings; the message names the field and the offending value."""


# --------------------------------------------------------------------------------------------
# How messages show values.  Every error and warning that quotes a value of the scene goes
# through ``value_text``, so the user reads "got -1.0" whatever type the value came in and
# whatever NumPy version runs (NumPy 2's reprs are "np.float64(-1.0)"), on one line.

#: Items of a sequence or array a message shows before it elides the rest.
SHOWN_ITEMS = 6
#: Characters of any other object's repr a message shows.
SHOWN_CHARACTERS = 120


def value_text(value) -> str:
    """``value`` as a message shows it: numbers as Python writes them (-1.0, nan, 3, True),
    float32 ones in their shortest form (0.1, not 0.10000000149011612); 0-d arrays as their
    number; sequences and arrays as ``[a, b, ...]`` (tuples in parentheses), the first
    SHOWN_ITEMS items of each level and how many there are; text quoted; anything else as its
    repr, on one line and cut at SHOWN_CHARACTERS."""
    if isinstance(value, (str, np.str_)):
        return repr(str(value))
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, np.floating) and value.dtype.itemsize < 8:
        return _short_float_text(value)
    if isinstance(value, numbers.Real):
        return repr(float(value))
    if isinstance(value, numbers.Complex):
        return repr(complex(value))
    if isinstance(value, np.ndarray):
        return value_text(value[()]) if value.ndim == 0 else _items_text(value, "[", "]")
    if isinstance(value, list):
        return _items_text(value, "[", "]")
    if isinstance(value, tuple):
        return _items_text(value, "(", ",)" if len(value) == 1 else ")")
    text = " ".join(repr(value).split())
    return text if len(text) <= SHOWN_CHARACTERS else text[:SHOWN_CHARACTERS - 3] + "..."


def _short_float_text(value) -> str:
    """The fewest digits that read back as the same float32 (or float16), as a Python float's
    repr writes them."""
    number = float(value)
    if math.isfinite(number):
        for digits in range(1, 18):
            text = f"{number:.{digits}g}"
            if type(value)(text) == value:
                return repr(float(text))
    return repr(number)


def _items_text(items, opening: str, closing: str) -> str:
    shown = [value_text(item) for item in items[:SHOWN_ITEMS]]
    if len(items) > SHOWN_ITEMS:
        shown.append(f"... ({len(items)} items)")
    return opening + ", ".join(shown) + closing


# --------------------------------------------------------------------------------------------
# Limits.  Validation accepts only values whose every product and sum in the tracer stays
# finite, so no NaN or inf can reach an image from an accepted scene: lengths and coordinates
# up to 1e300 (``core.frame`` moves and scales every scene to about unit size before tracing,
# so differences of them never overflow), colours and light intensities up to 1e12 (a path
# adds a few products of two such factors, far below float32's 3.4e38), Blinn-Phong exponents
# up to 1e7 (Blender's roughness 0 maps to 8e6), and counts that bound the work per pixel.

MAX_MAGNITUDE = 1e300
MAX_COLOUR = 1e12
MAX_SHININESS = 1e7
MAX_SAMPLES = 16384
MAX_LIGHT_SAMPLES = 1024
MAX_DEPTH = 256
MAX_TILE_SIZE = 1024
MAX_THREADS = 1024


# --------------------------------------------------------------------------------------------
# Validation helpers: each takes the field's full name so that errors point at the culprit.

def _finite(name: str, value, limit: float = MAX_MAGNITUDE) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"{name} must be a number, got {value_text(value)}") from None
    if not math.isfinite(number):
        raise SceneError(f"{name} must be finite, got {value_text(value)}")
    if abs(number) > limit:
        raise SceneError(f"{name} must be at most {limit:g} in size, got {value_text(value)}")
    return number


def _positive(name: str, value) -> float:
    number = _finite(name, value)
    if number <= 0.0:
        raise SceneError(f"{name} must be > 0, got {value_text(value)}")
    return number


def _non_negative(name: str, value, limit: float = MAX_MAGNITUDE) -> float:
    number = _finite(name, value, limit)
    if number < 0.0:
        raise SceneError(f"{name} must be >= 0, got {value_text(value)}")
    return number


def _vec3(name: str, value, limit: float = MAX_MAGNITUDE) -> Vec3:
    try:
        items = tuple(value)
    except TypeError:
        raise SceneError(f"{name} must be 3 numbers, got {value_text(value)}") from None
    if len(items) != 3:
        raise SceneError(f"{name} must be 3 numbers, got {len(items)}: {value_text(value)}")
    return tuple(_finite(f"{name}[{i}]", v, limit) for i, v in enumerate(items))


def _colour(name: str, value) -> Vec3:
    rgb = _vec3(name, value, MAX_COLOUR)
    for i, channel in enumerate(rgb):
        if channel < 0.0:
            raise SceneError(f"{name}[{i}] must be >= 0, got {value_text(channel)}")
    return rgb


def _choice(name: str, value, allowed: Sequence[str]) -> str:
    if value not in allowed:
        raise SceneError(f"{name} must be one of {', '.join(map(value_text, allowed))}; "
                         f"got {value_text(value)}")
    return value


def _count(name: str, value, minimum: int = 1, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise SceneError(f"{name} must be a whole number >= {minimum}, got {value_text(value)}")
    if maximum is not None and value > maximum:
        raise SceneError(f"{name} must be at most {maximum}, got {value_text(value)}")
    return value


def _unit(name: str, value) -> Vec3:
    vector = _vec3(name, value)
    norm = math.sqrt(sum(c * c for c in vector))
    if norm < 1e-12:
        raise SceneError(f"{name} must be a non-zero direction, got {value_text(value)}")
    return tuple(c / norm for c in vector)


def _fraction(name: str, value) -> float:
    number = _finite(name, value)
    if not 0.0 <= number <= 1.0:
        raise SceneError(f"{name} must be in [0, 1], got {value_text(value)}")
    return number


# --------------------------------------------------------------------------------------------
# Arrays: whole-array checks, naming the set, the field and the first offending index.

def _frozen_array(where: str, field_name: str, value, dtype, shape: tuple) -> np.ndarray:
    """``value`` as a read-only C-contiguous copy of ``dtype`` whose shape matches ``shape``
    (None: any length).  Integer fields accept only integer arrays (no silent truncation)."""
    array = _checked_array(where, field_name, value, dtype, shape, copy=True)
    array.setflags(write=False)
    return array


def _checked_array(where: str, field_name: str, value, dtype, shape: tuple,
                   copy: bool = False) -> np.ndarray:
    """``value`` as a C-contiguous array of ``dtype``, checked as ``_frozen_array`` checks it;
    copy=False: a copy only where a conversion needs one, and not frozen (it may be the
    caller's array), for a field whose stored value is computed from it anew (the mesh's
    normalised corner normals)."""
    try:
        array = np.array(value, copy=copy)
    except (TypeError, ValueError):
        raise SceneError(f"{where}: {field_name} must be an array, got "
                         f"{value_text(value)}") from None
    if np.issubdtype(dtype, np.integer):
        if array.size and not np.issubdtype(array.dtype, np.integer):
            raise SceneError(f"{where}: {field_name} must hold integers, got {array.dtype}")
    elif array.size and not np.issubdtype(array.dtype, np.number):
        raise SceneError(f"{where}: {field_name} must hold numbers, got {array.dtype}")
    if array.size == 0 and array.ndim < len(shape):
        array = array.reshape(tuple(0 if s is None else s for s in shape))
    wanted = " x ".join("N" if s is None else str(s) for s in shape)
    if array.ndim != len(shape) or any(s is not None and a != s
                                       for a, s in zip(array.shape, shape)):
        raise SceneError(f"{where}: {field_name} must have shape ({wanted}), "
                         f"got {array.shape}")
    return np.ascontiguousarray(array, dtype)


#: Rows (a mesh's triangles) per block of whole-mesh arithmetic (``row_blocks``: here the
#: corner normals' normalisation, and the export's ``read_mesh``): a block's temporaries stay
#: a few MB, reused from malloc's heap, instead of whole-array ones (a million triangles:
#: about 0.2 GB of fresh pages in each of the two, at every export).
BLOCK_ROWS = 1 << 16


def row_blocks(count: int):
    """Slices of BLOCK_ROWS consecutive rows covering ``count`` rows."""
    return (slice(start, start + BLOCK_ROWS) for start in range(0, count, BLOCK_ROWS))


def _unit_rows(where: str, field_name: str, vectors: np.ndarray) -> np.ndarray:
    """(T, k, 3) ``vectors`` divided by their lengths, a new read-only array, block by
    block (the same values as whole); SceneError naming the first zero vector."""
    result = np.empty(vectors.shape, np.float64)
    for rows in row_blocks(len(vectors)):
        block = vectors[rows]
        lengths = np.sqrt((block * block).sum(axis=2))
        bad = _first_bad(lengths <= 1e-30)
        if bad is not None:
            bad = (bad[0] + rows.start, *bad[1:])
            raise SceneError(f"{where}: {field_name}{_index_text(bad)} must not be zero")
        np.divide(block, lengths[:, :, None], out=result[rows])
    result.setflags(write=False)
    return result


def _first_bad(mask: np.ndarray):
    """Index tuple of the first True element of ``mask``, or None."""
    flat = np.flatnonzero(mask)
    return None if len(flat) == 0 else np.unravel_index(flat[0], mask.shape)


def _index_text(index) -> str:
    return "".join(f"[{int(i)}]" for i in index)


def _require_finite(where: str, field_name: str, array: np.ndarray) -> None:
    bad = _first_bad(~np.isfinite(array))
    if bad is not None:
        raise SceneError(f"{where}: {field_name}{_index_text(bad)} must be finite, "
                         f"got {value_text(array[bad])}")


def _require_indices(where: str, field_name: str, array: np.ndarray, count: int,
                     what: str) -> None:
    bad = _first_bad((array < 0) | (array >= count))
    if bad is not None:
        raise SceneError(f"{where}: {field_name}{_index_text(bad)} must be in [0, {count}) "
                         f"({what}), got {value_text(array[bad])}")
