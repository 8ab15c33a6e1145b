"""Lights as a scene describes them: the article's ``PointLight`` and Blender's lights in
Cycles' units (``SphereLight``, ``SpotLight``, ``SunLight``, ``AreaLight``), validated on
construction as every part of a scene is (``core.scene``).  How the tracer samples them:
``core.lights`` (the Whitted integrator) and ``core.emitters`` (the path integrator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .validation import (MAX_COLOUR, Vec3, value_text, _at_most_pi, _choice, _colour,
                         _fraction, _LightFields, _non_negative, _positive, _set, _vec3)

AREA_SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")


@dataclass(frozen=True)
class PointLight:
    """A point light, as the article models it: no distance falloff.

    ambient, diffuse, specular: RGB intensities Ia, Id, Is (>= 0); the article's light is
        (1, 1, 1) for all three.
    radius: 0 for a point (hard shadows); > 0 makes a spherical light whose shadows are soft
        (visibility averaged over ``RenderSettings.light_samples`` points on it).
    ``PointLight.from_power`` maps a Blender light's watts onto this model (what the
    article semantics exports); ``SphereLight`` is Blender's point light in Cycles' units.
    """

    position: Vec3
    ambient: Vec3 = (1.0, 1.0, 1.0)
    diffuse: Vec3 = (1.0, 1.0, 1.0)
    specular: Vec3 = (1.0, 1.0, 1.0)
    radius: float = 0.0
    name: str = ""

    #: Blender's default point light power; it maps to the article's white light (1, 1, 1).
    REFERENCE_POWER_W = 1000.0

    def __post_init__(self):
        where = f"light {value_text(self.name)}" if self.name else "light"
        _set(self, "position", _vec3(f"{where}.position", self.position))
        for name in ("ambient", "diffuse", "specular"):
            _set(self, name, _colour(f"{where}.{name}", getattr(self, name)))
        _set(self, "radius", _non_negative(f"{where}.radius", self.radius))

    @classmethod
    def from_power(cls, position, colour, power_w: float, radius: float = 0.0,
                   name: str = "") -> "PointLight":
        """A light from Blender's watts and colour: every intensity is colour * power / 1000 W.

        Blender's point light radiates ``P * colour / (4 pi)`` W/sr and falls off as 1/d^2; the
        article's light has no falloff and unit intensity.  Glint keeps the article's model and
        scales it linearly with power, so Blender's default 1000 W white light *is* the
        article's light, 500 W is half as bright, and a red light tints all three terms.
        """
        where = f"light {value_text(name)}" if name else "light"
        rgb = _colour(f"{where}.color", colour)
        scale = _non_negative(f"{where}.energy", power_w,
                              MAX_COLOUR * cls.REFERENCE_POWER_W) / cls.REFERENCE_POWER_W
        intensity = tuple(c * scale for c in rgb)
        return cls(position=position, ambient=intensity, diffuse=intensity,
                   specular=intensity, radius=radius, name=name)


# Blender's lights take whatever Blender holds, as Cycles renders it (docs/invalid-data.md): a
# negative power or strength subtracts light; a light whose position, direction, colour or
# power is not finite, whose object is scaled to 0 (a zero direction or axis) or whose area
# is 0 emits nothing (its power or strength is stored as 0); ``warnings`` holds the one line
# that names those fields.

#: What a light's node tree adds (SphereLight, SpotLight, AreaLight): ``program``, its
#: Light Output's Surface compiled (``core.shader``) where an Emission's colour or strength
#: comes from nodes, whose emission at the point a light sample leaves multiplies the
#: light's colour (Cycles' light shaders); ``matrix``, the light object's 3 x 4 world
#: matrix (rows), for the program's Object and Normal texture coordinates.

@dataclass(frozen=True)
class SphereLight:
    """Blender's point light in Cycles' units: ``power`` W of ``colour`` from a sphere of
    ``radius`` (0: a point).  Radiant intensity P colour / (4 pi) W/sr, falling off as 1/d^2;
    a radius gives soft shadows (``core.lights``)."""

    position: Vec3
    colour: Vec3 = (1.0, 1.0, 1.0)
    power: float = 1000.0
    radius: float = 0.0
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)
    program: object = field(default=None, repr=False, compare=False)
    matrix: tuple = None

    def __post_init__(self):
        fields = _LightFields(f"light {value_text(self.name)}" if self.name else "light")
        _set(self, "position", fields.position(self.position))
        _set(self, "colour", fields.colour(self.colour))
        _set(self, "power", fields.amount("power", self.power))
        _set(self, "radius", _non_negative(f"{fields.where}.radius", self.radius))
        _finish_light(self, fields, "power")

    @property
    def emits(self) -> bool:
        return self.power != 0.0


@dataclass(frozen=True)
class SpotLight:
    """Blender's spot light: a SphereLight masked to a cone around ``direction`` (where the
    light points, the light's -Z), of full angle ``spot_size`` (radians, in (0, pi]) whose
    edge is softened over the fraction ``spot_blend`` in [0, 1] (Cycles' smoothstep)."""

    position: Vec3
    direction: Vec3
    colour: Vec3 = (1.0, 1.0, 1.0)
    power: float = 1000.0
    radius: float = 0.0
    spot_size: float = math.radians(45.0)
    spot_blend: float = 0.15
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)
    program: object = field(default=None, repr=False, compare=False)
    matrix: tuple = None

    def __post_init__(self):
        fields = _LightFields(f"light {value_text(self.name)}" if self.name else "light")
        where = fields.where
        _set(self, "position", fields.position(self.position))
        _set(self, "direction", fields.direction("direction", self.direction))
        _set(self, "colour", fields.colour(self.colour))
        _set(self, "power", fields.amount("power", self.power))
        _set(self, "radius", _non_negative(f"{where}.radius", self.radius))
        _set(self, "spot_size", _at_most_pi(f"{where}.spot_size",
                                            _positive(f"{where}.spot_size", self.spot_size)))
        _set(self, "spot_blend", _fraction(f"{where}.spot_blend", self.spot_blend))
        _finish_light(self, fields, "power")

    @property
    def emits(self) -> bool:
        return self.power != 0.0


@dataclass(frozen=True)
class SunLight:
    """Blender's sun: ``strength`` W/m^2 of ``colour`` arriving along ``direction`` (where the
    light travels, the light's -Z) from a disc of full angle ``angle`` (radians, >= 0: soft
    shadows).  Irradiance on a surface: strength cos(theta)."""

    direction: Vec3
    colour: Vec3 = (1.0, 1.0, 1.0)
    strength: float = 1.0
    angle: float = 0.0
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        fields = _LightFields(f"light {value_text(self.name)}" if self.name else "light")
        _set(self, "direction", fields.direction("direction", self.direction))
        _set(self, "colour", fields.colour(self.colour))
        _set(self, "strength", fields.amount("strength", self.strength))
        _set(self, "angle", _at_most_pi(f"{fields.where}.angle",
                                        _non_negative(f"{fields.where}.angle", self.angle)))
        _finish_light(self, fields, "strength")

    @property
    def emits(self) -> bool:
        return self.strength != 0.0

    # A sun has no place; these let code that measures the scene's extent treat all lights
    # alike (``core.precision``).
    position = (0.0, 0.0, 0.0)
    radius = 0.0


@dataclass(frozen=True)
class AreaLight:
    """Blender's area light: a one-sided ``shape`` ('SQUARE', 'RECTANGLE', 'DISK',
    'ELLIPSE') centred at ``position``, spanning ``size_x`` along ``axis_x`` and ``size_y``
    along ``axis_y`` (world units; SQUARE and DISK use size_x for both), emitting ``power`` W
    of ``colour`` towards ``direction`` (the light's -Z) as a Lambertian emitter of radiance
    P colour / (pi A), A its area (Cycles' normalisation, checked in ``core.lights``)."""

    position: Vec3
    direction: Vec3
    axis_x: Vec3
    axis_y: Vec3
    shape: str = "SQUARE"
    size_x: float = 1.0
    size_y: float = 1.0
    colour: Vec3 = (1.0, 1.0, 1.0)
    power: float = 1000.0
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)
    program: object = field(default=None, repr=False, compare=False)
    matrix: tuple = None

    def __post_init__(self):
        fields = _LightFields(f"light {value_text(self.name)}" if self.name else "light")
        where = fields.where
        _set(self, "position", fields.position(self.position))
        for name in ("direction", "axis_x", "axis_y"):
            _set(self, name, fields.direction(name, getattr(self, name)))
        _choice(f"{where}.shape", self.shape, AREA_SHAPES)
        _set(self, "size_x", fields.size("size_x", self.size_x))
        if self.shape in ("SQUARE", "DISK"):
            _non_negative(f"{where}.size_y", self.size_y)
            _set(self, "size_y", self.size_x)
        else:
            _set(self, "size_y", fields.size("size_y", self.size_y))
        _set(self, "colour", fields.colour(self.colour))
        _set(self, "power", fields.amount("power", self.power))
        _finish_light(self, fields, "power")

    @property
    def emits(self) -> bool:
        return self.power != 0.0

    @property
    def area(self) -> float:
        full = self.size_x * self.size_y
        return full * math.pi / 4.0 if self.shape in ("DISK", "ELLIPSE") else full

    @property
    def radius(self) -> float:
        """Half the diagonal: how far the light reaches from its centre."""
        return 0.5 * math.hypot(self.size_x, self.size_y)


def _finish_light(light, fields: _LightFields, amount: str) -> None:
    """A dark light's power (or strength) is 0; its warning, if any, is kept."""
    if fields.dark:
        _set(light, amount, 0.0)
    _set(light, "warnings", fields.warnings())


#: The light types a Scene holds: the article's, and Blender's in Cycles' units.
LIGHT_TYPES = (PointLight, SphereLight, SpotLight, SunLight, AreaLight)
