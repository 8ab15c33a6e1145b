"""The IES Texture node: a light's brightness by direction from an IES LM-63 photometric
file, as Cycles reads the file (``intern/cycles/util/ies.cpp``) and looks it up
(``kernel/util/ies.h``, ``kernel/svm/ies.h``).

``parse_ies`` turns the file's text into an ``IESProfile``: Cycles' angle tables (horizontal
angles over [0, 2 pi], vertical from the downward axis, radians) and intensities (candela
times the file's multipliers times 4 pi / 177.83, Cycles' candela to watt conversion with the
D65 luminous efficacy), the file's symmetric halves and quadrants mirrored out as Cycles does
for photometric types A, B and C.  The add-on parses at export; the core holds the arrays.

``ies_intensity`` is the lookup, a plain function of an array of directions, so that lights
can call it on the direction from the light to the lit point as well as the node does:
v = acos(-z), h = atan2(x, y) + pi of the normalised direction, then Catmull-Rom cubic
interpolation along v (four rows) and then along h, wrapping around the full circle and
reflecting at the poles where the table covers them, clamped at 0; directions outside the
table give 0.

The node's unlinked Vector is Cycles' default: the Geometry node's Incoming taken into the
object's space as a normal (``ShadingPoints``' 'object_incoming').  A file that cannot be
read or parsed gives 100 in every direction (so Fac = 100 x Strength), as Cycles' lookup of
an invalid slot does (``MISSING_INTENSITY``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .registry import FLOAT, VECTOR, node

#: Cycles' candela -> watt factor: 4 pi / 177.83 (the D65 illuminant's luminous efficacy).
CANDELA_TO_WATT = 0.0706650768394
#: What Cycles' lookup returns for a file it could not load, in every direction.
MISSING_INTENSITY = 100.0
#: LM-63 photometric types (the file's field).
TYPE_C, TYPE_B, TYPE_A = 1, 2, 3

_F32 = np.float32


class IESError(ValueError):
    """A text that is not an IES file Cycles can read (the message says what is wrong)."""


@dataclass(frozen=True, eq=False)
class IESProfile:
    """A parsed IES file as Cycles' kernel holds it.

    h_angles: (H,) float32 increasing horizontal angles, radians.
    v_angles: (V,) float32 increasing vertical angles from the downward axis, radians.
    intensity: (H, V) float32 watts per steradian times 4 pi, row i at h_angles[i].
    """

    h_angles: np.ndarray
    v_angles: np.ndarray
    intensity: np.ndarray

    def __post_init__(self):
        if self.intensity.shape != (len(self.h_angles), len(self.v_angles)):
            raise ValueError(f"IES profile: intensity {self.intensity.shape} for "
                             f"{len(self.h_angles)} x {len(self.v_angles)} angles")


# ---- Parsing (util/ies.cpp) --------------------------------------------------------------

# What C's strtod and strtol accept after leading white space.
_DOUBLE = re.compile(r"\s*([+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan))",
                     re.IGNORECASE)
_LONG = re.compile(r"\s*([+-]?\d+)")


class _Numbers:
    """Cycles' IESTextParser: numbers read one after another from where the text's
    "\\nTILT=" line starts, C's strtod / strtol style; reading past the end or what is not
    a number sets ``error``."""

    def __init__(self, text: str, position: int):
        self.text = text
        self.position = position
        self.error = False

    def _read(self, pattern, convert):
        if self.position is None or self.position >= len(self.text):
            self.error = True
            return convert("0")
        match = pattern.match(self.text, self.position)
        if match is None:
            self.position = None
            self.error = True
            return convert("0")
        self.position = match.end()
        return convert(match.group(1))

    def double(self) -> float:
        return self._read(_DOUBLE, float)

    def long(self) -> int:
        return self._read(_LONG, int)


def parse_ies(text: str) -> IESProfile:
    """The ``IESProfile`` of an IES file's ``text`` (Cycles' ``IESFile::load``); raises
    IESError naming what is wrong where Cycles would load nothing."""
    if not text:
        raise IESError("the file is empty")
    text = text.replace(",", " ")
    start = text.find("\nTILT=")
    if start < 0:
        raise IESError("no TILT= line")
    numbers = _Numbers(text, start)
    if text.startswith("\nTILT=INCLUDE", start):
        numbers.position = start + len("\nTILT=INCLUDE")
        numbers.double()                          # lamp to luminaire geometry
        for _ in range(2 * max(numbers.long(), 0)):
            numbers.double()                      # tilt angles and factors
    else:
        newline = text.find("\n", start + 1)
        numbers.position = None if newline < 0 else newline
    if numbers.position is None or numbers.position >= len(text):
        raise IESError("nothing after the TILT line")
    numbers.position += 1

    numbers.long()                                # number of lamps
    numbers.double()                              # lumens per lamp
    factor = numbers.double()                     # candela multiplier
    v_count = numbers.long()
    h_count = numbers.long()
    kind = numbers.long()                         # photometric type
    if kind not in (TYPE_A, TYPE_B, TYPE_C):
        raise IESError(f"photometric type {kind} is not 1 (C), 2 (B) or 3 (A)")
    numbers.long()                                # units
    for _ in range(3):
        numbers.double()                          # width, length, height
    factor *= numbers.double()                    # ballast factor
    factor *= numbers.double()                    # ballast-lamp photometric factor
    numbers.double()                              # input watts
    factor *= CANDELA_TO_WATT
    if v_count < 0 or h_count < 0 or v_count * h_count > len(text):
        raise IESError(f"{v_count} x {h_count} angles do not fit in the file")

    v_angles = [float(_F32(numbers.double())) for _ in range(v_count)]
    h_angles = [float(_F32(numbers.double())) for _ in range(h_count)]
    intensity = [[float(_F32(factor * numbers.double())) for _ in range(v_count)]
                 for _ in range(h_count)]
    if numbers.error:
        raise IESError("the file ends before its angles and candela values do")
    if not h_angles or not v_angles:
        raise IESError("no angles")
    process = {TYPE_A: _process_type_a, TYPE_B: _process_type_b, TYPE_C: _process_type_c}[kind]
    h_angles, v_angles, intensity = process(h_angles, v_angles, intensity)
    # Cycles converts in float32: angle * (M_PI_F / 180.f).
    to_radians = _F32(np.pi) / _F32(180.0)
    return IESProfile(np.asarray(h_angles, _F32) * to_radians,
                      np.asarray(v_angles, _F32) * to_radians,
                      np.asarray(intensity, _F32).reshape(len(h_angles), len(v_angles)))


def _close(a: float, b: float) -> bool:
    return abs(a - b) < 1e-4


def _mirrored_about_90(angles: list) -> list:
    """0..90 -> 0..180 by mirroring about 90 (90 - a for the reversed tail, then 90 + a)."""
    return [90.0 - a for a in angles[:0:-1]] + [90.0 + a for a in angles]


def _process_type_b(h_angles, v_angles, intensity):
    """Type B's polar axis is horizontal: Cycles transposes the table and treats it as A/C,
    mirroring a 0..90 half to 0..180 or shifting -90..90 by 90, in both directions."""
    intensity = [list(row) for row in zip(*intensity)]
    h_angles, v_angles = v_angles, h_angles
    if _close(h_angles[0], 0.0):
        intensity = intensity[:0:-1] + intensity
        h_angles = _mirrored_about_90(h_angles)
    else:
        h_angles = [a + 90.0 for a in h_angles]
    if _close(v_angles[0], 0.0):
        intensity = [row[:0:-1] + row for row in intensity]
        v_angles = _mirrored_about_90(v_angles)
    else:
        v_angles = [a + 90.0 for a in v_angles]
    return h_angles, v_angles, intensity


def _process_type_a(h_angles, v_angles, intensity):
    """Type A: vertical angles shift by 90; horizontal -90..90 maps to 270..90 (reversed,
    180 - a), a 0..90 half mirrored on to 180..270."""
    v_angles = [a + 90.0 for a in v_angles]
    new_h = [180.0 - a for a in h_angles[::-1]]
    new_intensity = list(intensity[::-1])
    if _close(h_angles[0], 0.0):
        new_h += [180.0 + a for a in h_angles[1:]]
        new_intensity += intensity[1:]
    return new_h, v_angles, new_intensity


def _process_type_c(h_angles, v_angles, intensity):
    """Type C: 90..270 files turn to 0..180; one angle covers the circle; a quadrant
    (0..90) and a half (0..180) are mirrored out to the full circle; a missing 360 entry is
    added where the spacing shows it."""
    h_angles, intensity = list(h_angles), list(intensity)
    if _close(h_angles[0], 90.0):
        h_angles = [a - 90.0 for a in h_angles]
    if len(h_angles) == 1:
        h_angles = [0.0, 360.0]
        intensity = [intensity[0], intensity[0]]
    if _close(h_angles[-1], 90.0):
        h_angles += [180.0 - a for a in h_angles[-2::-1]]
        intensity += intensity[-2::-1]
    if _close(h_angles[-1], 180.0):
        h_angles += [360.0 - a for a in h_angles[-2::-1]]
        intensity += intensity[-2::-1]
    if _close(h_angles[0], 0.0) and not _close(h_angles[-1], 360.0):
        # Cycles computes these steps in float32.
        last_step = float(_F32(h_angles[-1]) - _F32(h_angles[-2]))
        first_step = float(_F32(h_angles[1]) - _F32(h_angles[0]))
        gap = float(_F32(360.0) - _F32(h_angles[-1]))
        if _close(last_step, gap) or _close(first_step, gap):
            h_angles.append(360.0)
            intensity.append(intensity[0])
    return h_angles, v_angles, intensity


# ---- Lookup (kernel/util/ies.h) ----------------------------------------------------------

def _cubic(a, b, c, d, x):
    """Cycles' ``cubic_interp`` (float32): the Catmull-Rom spline through b (x = 0) and c
    (x = 1)."""
    half, two, three, four, five = (_F32(v) for v in (0.5, 2, 3, 4, 5))
    return half * (((d + three * (b - c) - a) * x + (two * a - five * b + four * c - d)) * x
                   + (c - a)) * x + b


def ies_intensity(profile: IESProfile | None, direction) -> np.ndarray:
    """(n,) the profile's intensity in each direction of ``direction`` (3, n) (any length
    but 0; z down is the vertical angle 0, +y the horizontal angle pi), as Cycles'
    ``svm_node_ies`` finds it before multiplying by Strength.  No profile (a file Cycles
    could not read) gives ``MISSING_INTENSITY`` everywhere; otherwise a zero or non-finite
    direction, or one outside the table, gives 0."""
    direction = np.asarray(direction)
    dtype = direction.dtype if direction.dtype in (np.float32, np.float64) else np.float64
    n = direction.shape[1]
    if profile is None:
        return np.full(n, MISSING_INTENSITY, dtype)
    if len(profile.h_angles) < 2 or len(profile.v_angles) < 2:
        return np.zeros(n, dtype)
    # In float32 as Cycles: the angles meet the table's float32 angles as they do there.
    x, y, z = direction.astype(_F32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        length = np.sqrt(x * x + y * y + z * z)
        usable = np.isfinite(length) & (length > 0)
        scale = np.where(usable, _F32(1) / np.where(usable, length, _F32(1)), _F32(0))
    x, y, z = x * scale, y * scale, z * scale
    v_angle = np.arccos(np.clip(-z, _F32(-1), _F32(1)))
    h_angle = np.arctan2(x, y) + _F32(np.pi)

    h_table, v_table = profile.h_angles, profile.v_angles
    h_num, v_num = len(h_table), len(v_table)
    inside = (usable & (v_angle >= v_table[0]) & (v_angle < v_table[-1])
              & (h_angle >= h_table[0]) & (h_angle < h_table[-1]))
    # Cycles walks the table to the last entry whose successor is not below the angle.
    h_i = np.minimum(np.searchsorted(h_table[1:], h_angle, side="left"), h_num - 2)
    v_i = np.minimum(np.searchsorted(v_table[1:], v_angle, side="left"), v_num - 2)
    h_frac = (h_angle - h_table[h_i]) / (h_table[h_i + 1] - h_table[h_i])
    v_frac = (v_angle - v_table[v_i]) / (v_table[v_i + 1] - v_table[v_i])

    # Cycles means a table over the whole circle to wrap around and one reaching a pole to
    # reflect there, and elsewhere a missing neighbour to repeat the nearest entry.  Its
    # float32 tests, though, (2 pi - 1e-7 and pi - 1e-7 round back to 2 pi and pi) find no
    # wrap at 360 degrees nor at the upper pole: only the lower pole reflects.
    epsilon = _F32(1e-7)
    wrap_h = bool(h_table[0] < epsilon and h_table[-1] > _F32(2 * np.pi) - epsilon)
    wrap_v_low = bool(v_table[0] < epsilon)
    wrap_v_high = bool(v_table[-1] > _F32(np.pi) - epsilon)
    v_rows = (np.where(v_i > 0, v_i - 1, 1 if wrap_v_low else v_i), v_i, v_i + 1,
              np.where(v_i + 2 < v_num, v_i + 2, v_num - 2 if wrap_v_high else v_i + 1))
    # Cycles falls back to the second entry (not the third) past the table's last column.
    h_columns = (np.where(h_i > 0, h_i - 1, h_num - 2 if wrap_h else h_i), h_i, h_i + 1,
                 np.where(h_i + 2 < h_num, h_i + 2, 1 if wrap_h else h_i))
    table = profile.intensity

    def vertical(column):
        return _cubic(*(table[column, row] for row in v_rows), v_frac)

    value = np.maximum(_cubic(*(vertical(column) for column in h_columns), h_frac), _F32(0))
    return np.where(inside, value, _F32(0)).astype(dtype)


@node("ShaderNodeTexIES", inputs=(("Vector", VECTOR), ("Strength", FLOAT)),
      outputs=(("Fac", FLOAT),), options=("profile",),
      implicit={"Vector": "object_incoming"})
def ies_texture(points, vector, strength, *, profile=None):
    """Fac = Strength x the profile's intensity towards Vector (``ies_intensity``)."""
    dtype = points.dtype if points is not None else np.float64
    vector = np.asarray(vector, dtype).reshape(3, -1)
    return (np.asarray(strength, dtype) * ies_intensity(profile, vector),)
