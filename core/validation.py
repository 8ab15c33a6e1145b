"""Validation of scene data: the core's limits, and the checks every field of a scene
description (``core.scene`` and its parts' modules) goes through, each taking the field's
full name so that an error names the culprit and the offending value.

Scalars and triples are checked one at a time; arrays (sphere sets, meshes) in whole-array
operations, naming the first offending index.  The underscored checks are the description
modules' (``core.scene``, ``core.materials``, ``core.light_sources``, ``core.camera``,
``core.settings``); ``SceneError`` and the limits are public.
"""

from __future__ import annotations

import math
import numbers
import re
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
        # (A text just past the type's largest value reads back as inf: no warning.)
        with np.errstate(over="ignore"):
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
MAX_FILTER_WIDTH = 100.0


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
    return tuple(_finite(f"{name}[{i}]", v, limit) for i, v in enumerate(_three(name, value)))


def _three(name: str, value) -> tuple:
    try:
        items = tuple(value)
    except TypeError:
        raise SceneError(f"{name} must be 3 numbers, got {value_text(value)}") from None
    if len(items) != 3:
        raise SceneError(f"{name} must be 3 numbers, got {len(items)}: {value_text(value)}")
    return items


def _three_numbers(name: str, value) -> Vec3:
    """3 floats, finite or not (a SceneError for anything else)."""
    items = _three(name, value)
    try:
        return tuple(float(v) for v in items)
    except (TypeError, ValueError):
        return _vec3(name, items)  # raises, naming an item that is not a number


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


def _fraction(name: str, value) -> float:
    number = _finite(name, value)
    if not 0.0 <= number <= 1.0:
        raise SceneError(f"{name} must be in [0, 1], got {value_text(value)}")
    return number


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)  # frozen dataclasses store their normalised values


def _set_label(kind: str, name: str) -> str:
    return f"{kind} {value_text(name)}" if name else kind


#: A Dask scheduler's address (``RenderSettings.cluster``, ``core.cluster``).
_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def check_address(name: str, address) -> str:
    """``address`` if it is empty (render locally) or a Dask scheduler address
    (``tcp://HOST:PORT`` or ``tls://HOST:PORT``), else a SceneError naming ``name``."""
    if not isinstance(address, str):
        raise SceneError(f"{name} must be a string, got {type(address).__name__}")
    address = address.strip()
    if address and (_ADDRESS.match(address) is None
                    or not 0 < int(_ADDRESS.match(address).group(3)) < 65536):
        raise SceneError(f"{name} must be a Dask scheduler address such as "
                         f"tcp://HOST:8786 or tls://HOST:8786, got {address!r}")
    return address


# --------------------------------------------------------------------------------------------
# Lights: values Blender holds and Cycles renders in its own way (docs/invalid-data.md).  A
# light whose place, direction, size, colour or power Cycles cannot use emits nothing, and a
# negative power subtracts light; each light says so in one warning.

class _LightFields:
    """Checks a Blender light's fields one by one, as Cycles renders them: what makes the
    light dark (``dark``), and the one warning that names those fields (``warnings``).
    Cycles with its light tree (the default) renders every light dark for one whose power or
    colour is NaN; without it, as here, only that light (measured)."""

    def __init__(self, where: str):
        self.where = where
        self.dark: list[str] = []
        self.notes: list[str] = []

    def _finite_or_dark(self, field: str, value):
        """``value``'s float, or None (the light goes dark) when it is not finite."""
        number = _finite(f"{self.where}.{field}", value) if _is_finite(value) else None
        if number is None:
            self.dark.append(f"{field} is {value_text(value)}")
        return number

    def position(self, value) -> Vec3:
        if all(map(math.isfinite, _three_numbers(f"{self.where}.position", value))):
            return _vec3(f"{self.where}.position", value)
        self.dark.append(f"position is {value_text(value)}")
        return (0.0, 0.0, 0.0)

    def direction(self, field: str, value) -> Vec3:
        """A unit vector, or zero (dark) for a zero or non-finite one: the light's object
        scaled to 0 along it."""
        vector = _three_numbers(f"{self.where}.{field}", value)
        if not all(map(math.isfinite, vector)):
            self.dark.append(f"{field} is {value_text(value)}")
            return (0.0, 0.0, 0.0)
        vector = _vec3(f"{self.where}.{field}", vector)
        norm = math.sqrt(sum(c * c for c in vector))
        if norm < 1e-12:
            self.dark.append(f"{field} is {value_text(value)} (the light is scaled to 0)")
            return (0.0, 0.0, 0.0)
        return tuple(c / norm for c in vector)

    def colour(self, value) -> Vec3:
        """A colour >= 0 whose channels that are not finite emit nothing (as Cycles renders
        them without its light tree; with it, a NaN darkens every light)."""
        rgb = _three_numbers(f"{self.where}.colour", value)
        if not all(map(math.isfinite, rgb)):
            rgb = tuple(c if math.isfinite(c) else 0.0 for c in rgb)
            self.notes.append(f"colour is {value_text(value)}: channels that are not finite "
                              f"emit nothing")
        for i, channel in enumerate(rgb):
            if channel < 0.0:
                raise SceneError(f"{self.where}.colour[{i}] must be >= 0, got "
                                 f"{value_text(channel)}")
        if max(rgb) > MAX_COLOUR:
            self.notes.append(f"colour {value_text(value)} is clamped to {MAX_COLOUR:g}")
            rgb = tuple(min(c, MAX_COLOUR) for c in rgb)
        return rgb

    def amount(self, field: str, value) -> float:
        """A power (W) or strength (W/m^2): any sign (a negative light subtracts light, as
        in Cycles), dark when not finite."""
        number = self._finite_or_dark(field, value)
        return 0.0 if number is None else number

    def size(self, field: str, value) -> float:
        """A length >= 0; 0 (an area light of no area) or not finite makes the light dark."""
        number = self._finite_or_dark(field, value)
        if number is None:
            return 0.0
        if number < 0.0:
            raise SceneError(f"{self.where}.{field} must be >= 0, got {value_text(value)}")
        if number == 0.0:
            self.dark.append(f"{field} is 0")
        return number

    def warnings(self) -> tuple[str, ...]:
        """One line naming every field that made the light dark or was changed."""
        reasons = self.notes + ([f"{', '.join(self.dark)}: it emits nothing"]
                                if self.dark else [])
        return (f"{self.where}: {'; '.join(reasons)}",) if reasons else ()


def _is_finite(value) -> bool:
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return True  # not a number at all: ``_finite`` names it


def _at_most_pi(name: str, value: float) -> float:
    """An angle, refused past pi as float32 compares them (Blender stores angles in float32:
    its 180 degrees, 3.1415927410125732, is float32 pi, above Python's), capped at pi."""
    if np.float32(value) > np.float32(math.pi):
        raise SceneError(f"{name} must be at most pi, got {value_text(value)}")
    return min(value, math.pi)


# --------------------------------------------------------------------------------------------
# Arrays: whole-array checks, naming the set, the field and the first offending index.

def _frozen_array(where: str, field_name: str, value, dtype, shape: tuple) -> np.ndarray:
    """``value`` as a read-only C-contiguous copy of ``dtype`` whose shape matches ``shape``
    (None: any length).  Integer fields accept only integer arrays (no silent truncation)."""
    array = _checked_array(where, field_name, value, dtype, shape, copy=True)
    array.setflags(write=False)
    return array


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (a set's arrays cannot change under the tracer)."""
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


def usable_triangles(vertices: np.ndarray, triangles: np.ndarray, limit: float = MAX_MAGNITUDE
                     ) -> tuple[np.ndarray, np.ndarray | None, str | None]:
    """(vertices, keep, why) for a mesh's vertices (V, 3) and triangles (T, 3) (indices in
    range), leaving out the triangles that touch a vertex that is not finite or past
    ``limit`` in size, as Cycles leaves them out (measured: docs/invalid-data.md): keep, the
    triangles kept, (T,) bool, or None for all; the vertices with those vertices replaced by
    a usable one (no triangle uses them any more, and the mesh's bounds stay those of what it
    draws); why, one sentence saying what was left out, or None."""
    # Compared this way round, NaN is unusable too, and no NumPy warning is raised.
    unusable = ~(np.abs(vertices) <= limit).all(axis=1)
    if not unusable.any():
        return vertices, None, None
    keep = ~unusable[triangles].any(axis=1)
    usable = np.flatnonzero(~unusable)
    replaced = vertices.copy()
    replaced[unusable] = vertices[usable[0]] if len(usable) else 0.0
    if keep.all():
        return replaced, None, None
    touched = triangles[~keep].ravel()
    first = int(touched[unusable[touched]].min())
    why = (f"{int((~keep).sum())} of {len(triangles)} triangles dropped: they touch a vertex "
           f"not finite or past {limit:g} in size (vertices[{first}] is "
           f"{value_text(vertices[first])})")
    return replaced, keep, why

