"""Blender lights -> core lights.

Default semantics (``export_light``): every type in Cycles' units (``core.lights`` derives
the factors):

* POINT -> ``SphereLight``: world position, power ``energy * 2 ** exposure`` W, colour,
  radius ``shadow_soft_size`` (soft shadows);
* SPOT -> ``SpotLight``: the same plus the light's -Z axis, ``spot_size`` and ``spot_blend``;
* SUN -> ``SunLight``: direction -Z, strength ``energy * 2 ** exposure`` W/m^2, ``angle``;
* AREA -> ``AreaLight``: centre, -Z, the world X and Y axes, shape, ``size`` (and ``size_y``
  for rectangles and ellipses) times the object's scale along each axis, power.

The colour is ``color`` times ``temperature_color`` when "Temperature" is on; it multiplies
the power and is used as is (scene-linear).  Light node trees, per-light visibility, area
spread and soft falloff are not read.  A negative power subtracts light, as in Cycles; a
light Cycles cannot use (a NaN power, an object scaled to 0, an area of size 0) emits
nothing, the core saying so (``core.light_sources``); a power past ``MAX_POWER`` is clamped to it
(``power_note``; docs/invalid-data.md).

Article semantics (``export_article_light``): a POINT light becomes
``core.PointLight.from_power`` (every intensity colour * power / 1000 W, no falloff: Blender's
default 1000 W white light is the article's light); other types have no counterpart there,
nor have lights of negative power or power and colour that are not finite
(``article_light_problem``).
"""

from __future__ import annotations

import math

from ...core import AreaLight, PointLight, SphereLight, SpotLight, SunLight
from ...core.validation import MAX_COLOUR, value_text
from ..compat import light_exposure, uses_light_temperature
from .values import as_stored

#: The most power (W) or sun strength (W/m^2) a light is exported with (past it, clamped): as
#: for the article's lights (``PointLight.from_power``), colour x power stays within the
#: core's colour range.
MAX_POWER = MAX_COLOUR * PointLight.REFERENCE_POWER_W


#: The largest float32: Cycles' light strength (colour x power) is float32, and a channel
#: past it is infinite there, which Cycles drops (measured: a colour channel of 3.4e38 on a
#: 1500 W light adds nothing to that channel without the light tree, and darkens every
#: light with it, as a NaN does).
FLOAT32_MAX = 3.4028234663852886e+38


def blender_colour(light) -> tuple[float, float, float]:
    """The light's colour as Blender holds it, times its temperature's when that is on."""
    colour = tuple(light.color)
    if uses_light_temperature(light):
        colour = tuple(c * t for c, t in zip(colour, light.temperature_color))
    return colour


def _overflowing(light) -> list[bool]:
    """Per channel: colour x power overflows Cycles' float32 strength."""
    power = abs(blender_power(light))
    return [abs(c) * power > FLOAT32_MAX for c in blender_colour(light)]


def light_colour(light) -> tuple[float, float, float]:
    """``blender_colour`` with the channels that ``_overflowing`` dark (``colour_note``)."""
    return tuple(0.0 if dark else c
                 for c, dark in zip(blender_colour(light), _overflowing(light)))


def colour_note(light, name: str) -> str | None:
    """The warning for the channels ``light_colour`` makes dark, or None."""
    if not any(_overflowing(light)):
        return None
    return (f"light {value_text(name)}: color {value_text(as_stored(blender_colour(light)))} "
            f"x energy overflows Cycles' float32 in some channels: they emit nothing, as in "
            f"Cycles")


def blender_power(light) -> float:
    """Power (W) or sun strength (W/m^2) as Blender holds it: energy x 2^exposure."""
    return float(light.energy) * 2.0 ** light_exposure(light)


def light_power(light) -> float:
    """``blender_power`` within +-MAX_POWER (NaN stays NaN: the core darkens the light)."""
    power = blender_power(light)
    return max(-MAX_POWER, min(power, MAX_POWER)) if not math.isnan(power) else power


def power_note(light, name: str) -> str | None:
    """The warning for a power ``light_power`` clamps, or None."""
    power = blender_power(light)
    if math.isnan(power) or abs(power) <= MAX_POWER:
        return None
    return (f"light {value_text(name)}: energy {value_text(as_stored(light.energy))} "
            f"(x 2^exposure) is clamped to {value_text(light_power(light))} W (Glint's limit; "
            f"Cycles' pixels are as blown out)")


def article_light_problem(light) -> str | None:
    """Why the article semantics leaves out a Blender light it would otherwise export, or
    None: its lights neither subtract light nor darken."""
    power = blender_power(light)
    if not math.isfinite(power) or not all(map(math.isfinite, blender_colour(light))):
        return "power or colour not finite"
    if power < 0:
        return "negative power, which the article's lights cannot subtract"
    return None


def _column(matrix, column: int) -> tuple[float, float, float]:
    return tuple(float(matrix[row][column]) for row in range(3))


def export_article_light(light, matrix_world, name: str) -> PointLight | None:
    """A core PointLight for a bpy PointLight placed by ``matrix_world`` (4x4), article
    semantics; None for other types and for ``article_light_problem``'s."""
    if light.type != 'POINT' or article_light_problem(light):
        return None
    return PointLight.from_power(_column(matrix_world, 3), light_colour(light),
                                 light_power(light), radius=float(light.shadow_soft_size),
                                 name=name)


def export_light(light, matrix_world, name: str):
    """The core light (Cycles' units) for a bpy Light placed by ``matrix_world`` (4x4)."""
    position = _column(matrix_world, 3)
    x_axis, y_axis, z_axis = (_column(matrix_world, c) for c in range(3))
    forward = tuple(-c for c in z_axis)
    colour, power = light_colour(light), light_power(light)
    if light.type == 'POINT':
        return SphereLight(position, colour, power, float(light.shadow_soft_size), name)
    if light.type == 'SPOT':
        return SpotLight(position, forward, colour, power, float(light.shadow_soft_size),
                         float(light.spot_size), float(light.spot_blend), name)
    if light.type == 'SUN':
        return SunLight(forward, colour, power, float(light.angle), name)
    if light.type == 'AREA':
        scale_x = math.sqrt(sum(c * c for c in x_axis))
        scale_y = math.sqrt(sum(c * c for c in y_axis))
        size_y = light.size_y if light.shape in ('RECTANGLE', 'ELLIPSE') else light.size
        shape = light.shape
        if shape in ('SQUARE', 'DISK') and not math.isclose(scale_x, scale_y, rel_tol=1e-6):
            shape = 'RECTANGLE' if shape == 'SQUARE' else 'ELLIPSE'
        return AreaLight(position, forward, x_axis, y_axis, shape, float(light.size) * scale_x,
                         float(size_y) * scale_y, colour, power, name)
    raise ValueError(f"unknown light type {light.type!r}")
