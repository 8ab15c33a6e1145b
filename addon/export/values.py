"""Values read from Blender that cannot be used as they are, and how Glint counts them
(docs/invalid-data.md)."""

from __future__ import annotations

import numpy as np

from ...core.validation import MAX_COLOUR


def counted(value, nan: float = 0.0):
    """A value read from Blender (a float or an array) as Glint counts it when it is not
    usable as is: NaN as ``nan``, what is infinite or past MAX_COLOUR in size as
    +-MAX_COLOUR; None when it is usable (docs/invalid-data.md: Cycles' own clamps drop a NaN
    to the low end of an input's range; infinite pixels are what Glint cannot write)."""
    array = np.asarray(value, float)
    if (np.abs(array) <= MAX_COLOUR).all():
        return None
    fixed = np.clip(np.where(np.isnan(array), nan, array), -MAX_COLOUR, MAX_COLOUR)
    return float(fixed) if fixed.ndim == 0 else fixed


def as_stored(value) -> np.ndarray:
    """A value read from Blender as the float32 Blender holds it, for a message to show as
    Blender's interface shows it (0.1, not 0.10000000149011612; past float32's range: inf)."""
    with np.errstate(over="ignore"):
        return np.asarray(value, np.float32)
