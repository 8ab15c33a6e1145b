"""Blender lights -> core point lights.

A POINT light becomes ``core.PointLight.from_power(position, colour, power, radius)``:

* position: the light's world position (instance matrix translation);
* power: ``energy * 2 ** exposure`` watts (Blender's light exposure is a power of two);
* colour: ``color``, times ``temperature_color`` when "Temperature" is on.  The colour
  multiplies the power (both are intensities, so it is used linearly, not sRGB-encoded);
* radius: ``shadow_soft_size`` ("Radius" in the UI): 0 gives the article's hard shadows, more
  gives soft shadows in the default semantics.

``from_power`` makes every intensity colour * power / 1000 W: Blender's default 1000 W white
point light is exactly the article's light (ambient = diffuse = specular = (1, 1, 1)), and the
core keeps the article's model with no distance falloff (see ``core.scene.PointLight``).

Sun, spot and area lights have no counterpart in the core; the export names them in a warning.
"""

from __future__ import annotations

from ...core import PointLight


def light_colour(light) -> tuple[float, float, float]:
    colour = tuple(light.color)
    if getattr(light, "use_temperature", False):
        colour = tuple(c * t for c, t in zip(colour, light.temperature_color))
    return colour


def light_power(light) -> float:
    return float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def export_point_light(light, matrix_world, name: str) -> PointLight:
    """A core PointLight for a bpy PointLight datablock placed by ``matrix_world`` (4x4)."""
    position = tuple(float(matrix_world[row][3]) for row in range(3))
    return PointLight.from_power(position, light_colour(light), light_power(light),
                                 radius=float(light.shadow_soft_size), name=name)
