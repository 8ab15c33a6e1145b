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
spread and soft falloff are not read.

Article semantics (``export_article_light``): a POINT light becomes
``core.PointLight.from_power`` (every intensity colour * power / 1000 W, no falloff: Blender's
default 1000 W white light is the article's light); other types have no counterpart there.
"""

from __future__ import annotations

import math

from ...core import AreaLight, PointLight, SceneError, SphereLight, SpotLight, SunLight
from ...core.validation import MAX_COLOUR, value_text

#: The most power (W) or sun strength (W/m^2) a light may have: as for the article's lights
#: (``PointLight.from_power``), colour x power stays within the core's colour range.
MAX_POWER = MAX_COLOUR * PointLight.REFERENCE_POWER_W


def light_colour(light) -> tuple[float, float, float]:
    colour = tuple(light.color)
    if getattr(light, "use_temperature", False):
        colour = tuple(c * t for c, t in zip(colour, light.temperature_color))
    return colour


def light_power(light) -> float:
    return float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def _column(matrix, column: int) -> tuple[float, float, float]:
    return tuple(float(matrix[row][column]) for row in range(3))


def export_article_light(light, matrix_world, name: str) -> PointLight | None:
    """A core PointLight for a bpy PointLight placed by ``matrix_world`` (4x4), article
    semantics; None for other types."""
    if light.type != 'POINT':
        return None
    return PointLight.from_power(_column(matrix_world, 3), light_colour(light),
                                 light_power(light), radius=float(light.shadow_soft_size),
                                 name=name)


def check_light(light, name: str) -> None:
    """Raise SceneError naming Blender's field (energy, color) when a light's power or colour
    is not finite or too large, before the core would name its own."""
    where = f"light {value_text(name)}"
    power = light_power(light)
    if not math.isfinite(power):
        raise SceneError(f"{where}.energy must be finite, got {value_text(power)}")
    if abs(power) > MAX_POWER:
        raise SceneError(f"{where}.energy must be at most {MAX_POWER:g}, got {value_text(power)}")
    for i, channel in enumerate(light_colour(light)):
        if not math.isfinite(channel) or abs(channel) > MAX_COLOUR:
            raise SceneError(f"{where}.color[{i}] must be finite and at most "
                             f"{MAX_COLOUR:g}, got {value_text(channel)}")


def export_light(light, matrix_world, name: str):
    """The core light (Cycles' units) for a bpy Light placed by ``matrix_world`` (4x4)."""
    check_light(light, name)
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
