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
the power and is used as is (scene-linear).  A light's node tree (``light_nodes``) multiplies
it as in Cycles: by its Emission's colour x strength where those are constant, else by a
program the path integrator evaluates where each light sample leaves the light (point, spot
and area lights; a sun takes its tree's value at rest).  Per-light visibility, area spread
and soft falloff are not read.  A negative power subtracts light, as in Cycles; a
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

import numpy as np

from ...core import AreaLight, PointLight, SphereLight, SpotLight, SunLight
from ...core.shader.points import ShadingPoints
from ...core.shader.program import ShaderProgram, constant_array, run
from ...core.validation import MAX_COLOUR, value_text
from ..compat import (LIGHT_NODES_ALWAYS, light_exposure, node_tree_in_use,
                      uses_light_temperature)
from .shader import ShaderCompiler, surface_socket
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


def _at_rest(program) -> np.ndarray:
    """(3,) a light program's emission at a point at rest: its centre, its normal and its
    incoming the light's -Z, where it shines (as ``core.path.light_at`` gives them)."""
    shining = np.array([[0.0], [0.0], [-1.0]])
    value = run(program, ShadingPoints(np.zeros((3, 1)), shining, shining, shining))
    return np.broadcast_to(value.emission, (3, 1))[:, 0]


def light_nodes(light, name: str, context=None):
    """(factor (3,) the light's colour is multiplied by, its program or None, note or None):
    what the light's node tree adds, as Cycles reads it.  No tree (or nodes off): nothing
    (factor 1).  A Light Output whose Surface nothing reaches: the light is dark, as in
    Cycles.  Otherwise its Surface is compiled like a material's (``shader``): an Emission
    of constant colour x strength folds to that factor; one whose colour or strength comes
    from nodes becomes a program (a sun, which has no point to evaluate it at, takes its
    value at rest, with a note)."""
    tree = node_tree_in_use(light, LIGHT_NODES_ALWAYS)
    if tree is None:
        return (1.0, 1.0, 1.0), None, None
    surface = surface_socket(tree)
    if surface is None or not surface.is_linked:
        return (0.0, 0.0, 0.0), None, (f"light {value_text(name)}: nothing reaches its Light "
                                       f"Output's Surface: it emits nothing, as in Cycles")
    compiler = ShaderCompiler(f"light {value_text(name)}", context)
    value = compiler.compile(surface)
    program = value if isinstance(value, ShaderProgram) else None
    if program is None:
        factor = np.broadcast_to(constant_array(value, np.float64).emission, (3, 1))[:, 0]
    elif light.type == 'SUN':
        factor, program = _at_rest(program), None
        compiler.note(f"light {value_text(name)}: a sun's node tree is taken at rest (its "
                      f"textures are not evaluated across the sky)")
    else:
        factor = np.ones(3)
    factor = tuple(float(min(max(c, 0.0), MAX_COLOUR)) for c in factor)
    return factor, program, "; ".join(compiler.notes) or None


def export_light(light, matrix_world, name: str, context=None):
    """The core light (Cycles' units) for a bpy Light placed by ``matrix_world`` (4x4), and
    a note on its node tree or None; context: the export context (its image cache)."""
    position = _column(matrix_world, 3)
    x_axis, y_axis, z_axis = (_column(matrix_world, c) for c in range(3))
    forward = tuple(-c for c in z_axis)
    factor, program, note = light_nodes(light, name, context)
    colour = tuple(c * f for c, f in zip(light_colour(light), factor))
    power = light_power(light)
    texture = {}
    if program is not None:
        texture = dict(program=program,
                       matrix=tuple(tuple(float(v) for v in row[:4]) for row in matrix_world[:3]))
    if light.type == 'POINT':
        return SphereLight(position, colour, power, float(light.shadow_soft_size), name,
                           **texture), note
    if light.type == 'SPOT':
        return SpotLight(position, forward, colour, power, float(light.shadow_soft_size),
                         float(light.spot_size), float(light.spot_blend), name,
                         **texture), note
    if light.type == 'SUN':
        return SunLight(forward, colour, power, float(light.angle), name), note
    if light.type == 'AREA':
        scale_x = math.sqrt(sum(c * c for c in x_axis))
        scale_y = math.sqrt(sum(c * c for c in y_axis))
        size_y = light.size_y if light.shape in ('RECTANGLE', 'ELLIPSE') else light.size
        shape = light.shape
        if shape in ('SQUARE', 'DISK') and not math.isclose(scale_x, scale_y, rel_tol=1e-6):
            shape = 'RECTANGLE' if shape == 'SQUARE' else 'ELLIPSE'
        return AreaLight(position, forward, x_axis, y_axis, shape, float(light.size) * scale_x,
                         float(size_y) * scale_y, colour, power, name, **texture), note
    raise ValueError(f"unknown light type {light.type!r}")
