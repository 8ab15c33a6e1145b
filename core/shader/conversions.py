"""Blender's implicit conversions between socket types, as nodes the compiler inserts where a
link joins sockets of different types (Cycles' ``svm_node_convert``)."""

from __future__ import annotations

import numpy as np

from .bsdf_nodes import LobeSum
from .registry import CLOSURE, COLOR, FLOAT, VECTOR, node

#: Rec.709 luminance: Cycles' colour-to-float weights in Blender's default colour space.
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@node("GlintFloatToColor", inputs=(("Value", FLOAT),), outputs=(("Color", COLOR),))
def float_to_colour(points, value):
    value = np.asarray(value)
    return (np.broadcast_to(value, (3,) + value.shape[-1:] if value.ndim else (3, 1)).copy(),)


@node("GlintColorToFloat", inputs=(("Color", COLOR),), outputs=(("Value", FLOAT),))
def colour_to_float(points, colour):
    return ((_LUMINANCE.astype(np.asarray(colour).dtype)[:, None] * colour).sum(axis=0),)


@node("GlintVectorToFloat", inputs=(("Vector", VECTOR),), outputs=(("Value", FLOAT),))
def vector_to_float(points, vector):
    return (np.asarray(vector).mean(axis=0),)


@node("GlintColorToEmission", inputs=(("Color", COLOR),), outputs=(("Emission", CLOSURE),))
def colour_to_emission(points, colour):
    lobes = LobeSum.none()
    lobes.emission = np.asarray(colour)
    return (lobes,)


@node("GlintFloatToEmission", inputs=(("Value", FLOAT),), outputs=(("Emission", CLOSURE),))
def float_to_emission(points, value):
    return colour_to_emission(points, float_to_colour(points, value)[0])
