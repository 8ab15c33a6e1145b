"""The sRGB transfer function (IEC 61966-2-1, the piecewise curve of Blender's "sRGB" display
with view transform "Standard"), for turning scene-linear radiance into display values and
back.  The core's default semantics computes scene-linear radiance; only a PNG written by the
core itself (``RenderResult.display``) needs display values, and Blender applies its own view
transform to what the add-on hands it."""

from __future__ import annotations

import numpy as np


def srgb_to_linear(values, dtype=np.float64):
    """sRGB-encoded values -> linear, element-wise (array in, array of ``dtype`` out: float32
    is 3x faster on a texture lookup's millions of values)."""
    kind = np.dtype(dtype).type
    values = np.asarray(values, kind)
    return np.where(values <= kind(0.04045), values / kind(12.92),
                    ((np.maximum(values, kind(0.04045)) + kind(0.055)) / kind(1.055))
                    ** kind(2.4))


def linear_to_srgb(values):
    """Linear values -> sRGB-encoded, element-wise (array in, float64 array out)."""
    values = np.asarray(values, np.float64)
    return np.where(values <= 0.0031308, values * 12.92,
                    1.055 * np.maximum(values, 0.0031308) ** (1 / 2.4) - 0.055)
