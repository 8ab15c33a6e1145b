"""What a scene is: spheres, triangle meshes, materials, point lights, a camera, a background.

Everything here is plain, immutable data with units and conventions spelled out; the tracer
turns it into arrays (``core.arrays``).  Construction validates every field, so a scene that
exists is a scene the tracer can render: bad input fails here, naming the field and the
value, before any ray is traced (the checks and limits: ``core.validation``; the reflectance
formulas the materials use: ``core.reflectance``).

Conventions
-----------
* World space is Blender's: right-handed, Z up.  (The article's scene uses Y up; that is
  just a different choice of numbers, the tracer does not care.)
* Lengths are in scene units (Blender units / metres), angles in radians, colours are linear
  RGB triples.
* Colours and intensities follow the article for its types (``Material``, ``PointLight``): a
  pixel's colour is the sum of Blinn-Phong terms, clipped to [0, 1] at the end (article
  semantics).  The physically based types (``SurfaceMaterial``, ``SphereLight``,
  ``SpotLight``, ``SunLight``, ``AreaLight``) use Cycles' units: scene-linear Rec.709 radiance
  in W / (m^2 sr), light power in W, sun strength in W/m^2; default semantics hands the
  unclipped radiance to Blender (see ``core.lights`` and ``core.bsdf`` for the formulas).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Union

import numpy as np

from .choices import (ANTI_ALIASING, FILMS, INTEGRATORS, PARALLELISM,  # noqa: F401
                      PIXEL_FILTERS, PRECISIONS, SEMANTICS)   # (defined once there)
from .reflectance import (MIN_ALPHA, blinn_exponent, dielectric_f0,  # noqa: F401
                          ior_from_f0, principled_fresnel)
from .terminator import DEFAULT_GEOMETRY_OFFSET
from .validation import (BLOCK_ROWS, MAX_COLOUR, MAX_DEPTH, MAX_LIGHT_SAMPLES,  # noqa: F401
                         MAX_FILTER_WIDTH, MAX_MAGNITUDE, MAX_SAMPLES, MAX_SHININESS,
                         MAX_THREADS, MAX_TILE_SIZE, check_address,
                         SceneError, Vec3, row_blocks, usable_triangles, value_text, _at_most_pi,
                         _checked_array, _choice, _colour, _count, _finite, _first_bad, _fraction,
                         _frozen, _frozen_array, _index_text, _LightFields, _non_negative,
                         _positive, _require_finite, _require_indices, _unit_rows, _vec3)

PROJECTIONS = ("PERSP", "ORTHO")
SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")
AREA_SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")


def _is_program(value) -> bool:
    from .shader.program import ShaderProgram
    return isinstance(value, ShaderProgram)


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)  # frozen dataclasses store their normalised values


# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Material:
    """The article's Blinn-Phong material.

    ambient, diffuse, specular: RGB reflectances ka, kd, ks (>= 0).
    shininess: Blinn-Phong exponent as the article writes it; the shading uses
        ``(N.H) ** (shininess / 4)``, the article's Phong-to-Blinn conversion.
    reflection: mirror weight in [0, 1]; 0 means the material never spawns a reflection ray.
    """

    ambient: Vec3 = (0.1, 0.1, 0.1)
    diffuse: Vec3 = (0.6, 0.6, 0.6)
    specular: Vec3 = (1.0, 1.0, 1.0)
    shininess: float = 100.0
    reflection: float = 0.5

    def validate(self, where: str = "material") -> "Material":
        for name in ("ambient", "diffuse", "specular"):
            _set(self, name, _colour(f"{where}.{name}", getattr(self, name)))
        _set(self, "shininess",
             _non_negative(f"{where}.shininess", self.shininess, MAX_SHININESS))
        reflection = _finite(f"{where}.reflection", self.reflection)
        if not 0.0 <= reflection <= 1.0:
            raise SceneError(f"{where}.reflection must be in [0, 1], got "
                             f"{value_text(self.reflection)}")
        _set(self, "reflection", reflection)
        return self

    def __post_init__(self):
        self.validate()


@dataclass(frozen=True)
class SurfaceMaterial:
    """A physically based surface as a sum of lobes, in Cycles' units (scene-linear colours).

    diffuse: Lambertian albedo a (radiance a E / pi under irradiance E).
    layer, layer_f0: the share (in [0, 1]) of ``diffuse`` that lies under a dielectric
        specular layer (a Principled BSDF's: 1; a Diffuse BSDF's: 0) and that layer's
        reflectance at normal incidence (its f90 is 1, as in Cycles).  Cycles' Principled
        BSDF weights its diffuse by 1 - A(N.V), A the specular layer's directional albedo
        (``closure_layering_weight``), so seen at a grazing angle it shows less diffuse and
        more gloss.  ``diffuse`` holds that lobe as base x (1 - f0) (the normal-incidence
        value, which view-independent code uses); ``core.bsdf.diffuse_seen`` turns the
        layered share into base x (1 - A(N.V)).  layer_f0 = 0: no layer (Cycles makes no
        specular closure for a Principled BSDF whose f0 is 0).
    specular_f0, specular_f90: the glossy lobe's reflectance at normal and grazing incidence;
        Schlick's curve F(c) = f0 + (f90 - f0) (1 - c)^5 between them.  A Glossy BSDF of colour
        c is f0 = f90 = c; Principled's dielectric layer f0 = ((ior - 1) / (ior + 1))^2.
    specular_dielectric, specular_ior: the share (in [0, 1]) of the lobe's rise from f0 to f90
        that follows the exact Fresnel curve of a dielectric of index specular_ior (>= 1)
        instead of Schlick's: Cycles' Principled specular layer (its generalized Schlick with
        exponent -ior; ``core.bsdf.dielectric_rise``), whose albedo is up to 20 % above
        Schlick's at N.V 0.3-0.7.  Metals and the Glossy BSDF keep Schlick's (share 0).
    roughness: Blender's roughness (alpha = roughness^2).  Lights give a GGX highlight
        (``core.bsdf``); surfaces with roughness <= ``MIRROR_ROUGHNESS`` also trace a mirror
        ray.
    transmission: colour of the light refracted through the surface (Snell's law, ``ior``);
        ``transmission_fresnel`` in [0, 1]: how much of it Fresnel takes away (1: glass, whose
        reflected part is the specular lobe; 0: Cycles' Refraction BSDF, all refracted).
    ior: index of refraction (inside / outside), > 0.
    emission: emitted radiance (colour x strength), seen by camera and reflection rays.
    transparency: colour of the light passing straight through (1 - alpha, Transparent BSDF).
    translucency: diffuse transmission (Translucent BSDF): radiance translucency E / pi for
        irradiance E arriving through the surface from the other side (its back hemisphere),
        each light's shadow ray crossing the surface.
    holdout: weight h of a Holdout shader, as in Cycles: a camera ray (or one that reached
        the surface straight through Transparent BSDFs only) makes h x its weight of the pixel
        transparent (alpha, ``RenderSettings.film``); every ray sees the holdout part black
        (the other lobes are scaled by 1 - h by whoever mixed them in).
    holdout_object: the object is a holdout (Blender's Object > Visibility > Holdout, or a
        holdout collection): camera rays (and rays straight through Transparent BSDFs) see
        it as a holdout except for its transparency, which they pass through; every other
        ray (mirrors, refraction, shadows) sees the material as it is.
    program: the material's shader program (``core.shader.program.ShaderProgram``), which
        the path integrator evaluates per hit; the fields above are then its value at a
        point at rest (what the Whitted integrator shades with).  None: the fields are the
        material.
    """

    diffuse: Vec3 = (0.8, 0.8, 0.8)
    layer: float = 0.0
    layer_f0: float = 0.0
    specular_f0: Vec3 = (0.0, 0.0, 0.0)
    specular_f90: Vec3 = (0.0, 0.0, 0.0)
    specular_dielectric: float = 0.0
    specular_ior: float = 1.5
    roughness: float = 0.5
    transmission: Vec3 = (0.0, 0.0, 0.0)
    transmission_fresnel: float = 1.0
    ior: float = 1.5
    emission: Vec3 = (0.0, 0.0, 0.0)
    transparency: Vec3 = (0.0, 0.0, 0.0)
    translucency: Vec3 = (0.0, 0.0, 0.0)
    holdout: float = 0.0
    holdout_object: bool = False
    program: object = None

    #: Roughness up to which a sharp mirror (and the world seen in it) is traced.
    MIRROR_ROUGHNESS = 0.2

    def validate(self, where: str = "surface material") -> "SurfaceMaterial":
        for name in ("diffuse", "specular_f0", "specular_f90", "transmission", "emission",
                     "transparency", "translucency"):
            _set(self, name, _colour(f"{where}.{name}", getattr(self, name)))
        _set(self, "roughness", _fraction(f"{where}.roughness", self.roughness))
        _set(self, "layer", _fraction(f"{where}.layer", self.layer))
        _set(self, "layer_f0", _fraction(f"{where}.layer_f0", self.layer_f0))
        _set(self, "specular_dielectric",
             _fraction(f"{where}.specular_dielectric", self.specular_dielectric))
        _set(self, "specular_ior", _finite(f"{where}.specular_ior", self.specular_ior))
        if self.specular_ior < 1.0:
            raise SceneError(f"{where}.specular_ior must be >= 1, got "
                             f"{value_text(self.specular_ior)}")
        _set(self, "transmission_fresnel",
             _fraction(f"{where}.transmission_fresnel", self.transmission_fresnel))
        _set(self, "ior", _positive(f"{where}.ior", self.ior))
        _set(self, "holdout", _fraction(f"{where}.holdout", self.holdout))
        if not isinstance(self.holdout_object, (bool, np.bool_)):
            raise SceneError(f"{where}.holdout_object must be True or False, got "
                             f"{value_text(self.holdout_object)}")
        _set(self, "holdout_object", bool(self.holdout_object))
        if self.program is not None and not _is_program(self.program):
            raise SceneError(f"{where}.program must be a core.shader ShaderProgram or None, "
                             f"got {type(self.program).__name__}")
        return self

    def __post_init__(self):
        self.validate()

    @classmethod
    def principled(cls, base_color=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, ior=1.5,
                   specular=0.5, specular_tint=(1.0, 1.0, 1.0), transmission=0.0,
                   emission=(0.0, 0.0, 0.0), alpha=1.0) -> "SurfaceMaterial":
        """Blender's Principled BSDF (its main inputs) as lobes.

        Metallic m and transmission t split the surface: a metal (weight m) reflects with
        f0 = base colour, f90 = white; the dielectric rest (1 - m) has a specular layer
        f0 = ((ior - 1) / (ior + 1))^2 * 2 specular * tint (Blender's Specular IOR Level 0.5
        leaves the IOR's reflectance unchanged), f90 = white, over glass (t: refracts the
        base colour) and diffuse (1 - t: base colour, minus the f0 the layer reflects at
        normal incidence).  alpha scales every lobe and lets 1 - alpha pass straight through.
        emission: colour x strength, added as is (not scaled by alpha here).
        """
        base = _colour("principled.base_color", base_color)
        tint = _colour("principled.specular_tint", specular_tint)
        m = _fraction("principled.metallic", metallic)
        t = _fraction("principled.transmission", transmission)
        a = _fraction("principled.alpha", alpha)
        level = _non_negative("principled.specular", specular)
        ior = _positive("principled.ior", ior)
        f0_dielectric = min(1.0, dielectric_f0(ior) * 2.0 * level)
        dielectric = (1.0 - m) * a
        share, specular_ior = principled_fresnel(base, tint, m, a, level, f0_dielectric)
        return cls(
            diffuse=tuple(dielectric * (1.0 - t) * (1.0 - f0_dielectric) * c for c in base),
            layer=1.0 if f0_dielectric > 0 else 0.0,
            layer_f0=min(1.0, f0_dielectric * max(tint)),
            specular_f0=tuple(dielectric * f0_dielectric * k + m * a * c
                              for c, k in zip(base, tint)),
            specular_f90=tuple(dielectric * min(1.0, 2.0 * level) * k + m * a
                               for k in tint),
            specular_dielectric=share, specular_ior=specular_ior,
            roughness=roughness,
            transmission=tuple(dielectric * t * c for c in base),
            ior=ior,
            emission=emission,
            transparency=(1.0 - a,) * 3,
        )

    # The article's Blinn-Phong terms of this surface, for code that shades every material
    # with them (``core.arrays``, the article's point lights in default semantics): ambient
    # light is reflected with the albedo, the highlight is a normalised Blinn-Phong lobe of
    # the matching exponent at normal incidence, and reflection rays are spawned by
    # ``core.bsdf`` (so 0 here).
    @property
    def ambient(self) -> Vec3:
        return self.diffuse

    @property
    def shininess(self) -> float:
        return 4.0 * blinn_exponent(self.roughness)

    @property
    def specular(self) -> Vec3:
        scale = (blinn_exponent(self.roughness) + 8.0) / 8.0
        return tuple(scale * c for c in self.specular_f0)

    @property
    def reflection(self) -> float:
        return 0.0


@dataclass(frozen=True)
class Sphere:
    """A sphere in world space: ``center`` (3,), ``radius`` > 0, a material and a name."""

    center: Vec3
    radius: float
    material: Material = field(default_factory=Material)
    name: str = ""

    def __post_init__(self):
        where = f"sphere {value_text(self.name)}" if self.name else "sphere"
        _set(self, "center", _vec3(f"{where}.center", self.center))
        _set(self, "radius", _positive(f"{where}.radius", self.radius))
        if not isinstance(self.material, (Material, SurfaceMaterial)):
            raise SceneError(f"{where}.material must be a Material or SurfaceMaterial, "
                             f"got {value_text(self.material)}")
        # Named here: a material shared by many spheres is checked again for each, so an
        # invalid one (built past its own check) names the sphere that uses it.
        self.material.validate(f"{where}.material")


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


@dataclass(frozen=True)
class ScreenCamera:
    """The article's camera: an eye looking through a screen rectangle on a plane.

    eye: (3,) position.  The screen lies on the plane z = ``screen_z`` and spans
    [left, right] x [bottom, top].  Pixel positions are ``linspace(left, right, width)`` and
    ``linspace(top, bottom, height)``: both ends included, so pixel centres sit ON the screen's
    edges (unlike Blender's (i + 0.5) / W).  Row 0 is the top.
    """

    width: int
    height: int
    eye: Vec3 = (0.0, 0.0, 1.0)
    left: float = -1.0
    right: float = 1.0
    top: float | None = None      # None: 1 / (width / height), the article's choice
    bottom: float | None = None   # None: -1 / (width / height)
    screen_z: float = 0.0

    def __post_init__(self):
        _count("camera.width", self.width)
        _count("camera.height", self.height)
        _set(self, "eye", _vec3("camera.eye", self.eye))
        ratio = self.width / self.height
        if self.top is None:
            _set(self, "top", 1.0 / ratio)
        if self.bottom is None:
            _set(self, "bottom", -1.0 / ratio)
        for name in ("left", "right", "top", "bottom", "screen_z"):
            _set(self, name, _finite(f"camera.{name}", getattr(self, name)))


@dataclass(frozen=True)
class BlenderCamera:
    """Blender's camera, with Blender's own conventions (``BKE_camera_params_compute_viewplane``).

    matrix_world: 4x4 camera-to-world matrix, rows of 4 (Blender's ``Object.matrix_world``
        as nested tuples); any scale in it is removed, as Blender does for the view.
        The camera looks down its local -Z with +Y up.
    projection: 'PERSP' or 'ORTHO'.  lens: focal length in mm (perspective);
        ortho_scale: the view's width or height in scene units (orthographic).
    sensor_width, sensor_height: mm; sensor_fit: 'AUTO', 'HORIZONTAL' or 'VERTICAL'.
    shift_x, shift_y: in units of the fitted view size, like Blender.
    clip_start, clip_end: distances along the view axis (depth planes, as in Cycles and
        Workbench, not distances along each ray).
    resolution_x, resolution_y, resolution_percentage: the output is
        ``int(resolution_x * percentage / 100)`` by ``int(resolution_y * percentage / 100)``.
    pixel_aspect_x, pixel_aspect_y: non-square pixels.
    Pixel (i, j) with j = 0 at the bottom has its centre at ((i + 0.5) / W, (j + 0.5) / H).
    aperture_radius, focus_distance, aperture_blades, aperture_rotation: a thin lens
        (Cycles' depth of field): rays leave a disc (or, with 3 or more blades, a regular
        polygon turned by the rotation) of that radius around the eye (orthographic: around
        the pixel's point on the camera plane) and meet at the plane at focus_distance along
        the view axis; 0 radius is a pinhole.
    name: the camera object's name, for warnings.

    A camera through which Cycles renders a black frame (measured: its matrix scaled to 0,
    clip_end not past clip_start, an orthographic camera of ortho_scale 0, depth of field
    focused at 0; alpha 1, or 0 with a transparent film) renders one too (``sees_nothing``:
    ``core.render`` renders nothing through it), with one warning naming the fields; its
    stored values are then stand-ins that let the view be worked out (an unscaled matrix, a
    clip range, a scale and a focus of 1).
    """

    matrix_world: tuple
    resolution_x: int = 1920
    resolution_y: int = 1080
    resolution_percentage: int = 100
    projection: Literal["PERSP", "ORTHO"] = "PERSP"
    lens: float = 50.0
    ortho_scale: float = 6.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: Literal["AUTO", "HORIZONTAL", "VERTICAL"] = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    pixel_aspect_x: float = 1.0
    pixel_aspect_y: float = 1.0
    aperture_radius: float = 0.0     # thin lens: 0 is a pinhole
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    name: str = ""
    sees_nothing: bool = field(default=False, init=False, repr=False, compare=False)
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        try:
            rows = tuple(tuple(row) for row in self.matrix_world)
        except TypeError:
            raise SceneError(f"camera.matrix_world must be 4x4, got "
                             f"{value_text(self.matrix_world)}") from None
        if len(rows) != 4 or any(len(row) != 4 for row in rows):
            raise SceneError(f"camera.matrix_world must be 4x4, got "
                             f"{value_text(self.matrix_world)}")
        _set(self, "matrix_world", tuple(
            tuple(_finite(f"camera.matrix_world[{r}][{c}]", v) for c, v in enumerate(row))
            for r, row in enumerate(rows)))
        _count("camera.resolution_x", self.resolution_x)
        _count("camera.resolution_y", self.resolution_y)
        _count("camera.resolution_percentage", self.resolution_percentage)
        _choice("camera.projection", self.projection, PROJECTIONS)
        _choice("camera.sensor_fit", self.sensor_fit, SENSOR_FITS)
        for name in ("lens", "sensor_width", "sensor_height", "pixel_aspect_x",
                     "pixel_aspect_y", "clip_start"):
            _set(self, name, _positive(f"camera.{name}", getattr(self, name)))
        for name in ("shift_x", "shift_y", "aperture_rotation"):
            _set(self, name, _finite(f"camera.{name}", getattr(self, name)))
        _set(self, "aperture_radius", _non_negative("camera.aperture_radius",
                                                    self.aperture_radius))
        if self.aperture_blades != 0:
            _count("camera.aperture_blades", self.aperture_blades, minimum=3)
        if self.width < 1 or self.height < 1:
            raise SceneError(
                f"camera resolution {self.resolution_x}x{self.resolution_y} at "
                f"{self.resolution_percentage}% gives a {self.width}x{self.height} image")
        blind = []   # why Cycles renders this camera's frame black
        rows = [list(row) for row in self.matrix_world]
        axes = [[rows[r][c] for r in range(3)] for c in range(3)]
        if any(math.sqrt(sum(v * v for v in axis)) < 1e-12 for axis in axes):
            blind.append("matrix_world is scaled to 0")
            for r in range(3):
                rows[r][:3] = [float(r == c) for c in range(3)]
            _set(self, "matrix_world", tuple(tuple(row) for row in rows))
        _set(self, "clip_end", _positive("camera.clip_end", self.clip_end))
        if self.clip_end <= self.clip_start:
            blind.append(f"clip_end {value_text(self.clip_end)} is not past clip_start "
                         f"{value_text(self.clip_start)}")
            _set(self, "clip_end", self.clip_start + 1.0)
        _set(self, "ortho_scale", _non_negative("camera.ortho_scale", self.ortho_scale))
        if self.ortho_scale == 0.0:
            if self.projection == "ORTHO":
                blind.append("ortho_scale is 0")
            _set(self, "ortho_scale", 1.0)
        _set(self, "focus_distance", _non_negative("camera.focus_distance",
                                                   self.focus_distance))
        if self.focus_distance == 0.0:
            if self.aperture_radius > 0.0:
                blind.append("focus_distance is 0 with depth of field")
            _set(self, "focus_distance", 1.0)
        if blind:
            _set(self, "sees_nothing", True)
            _set(self, "warnings", (f"{_set_label('camera', self.name)}: {', '.join(blind)}: "
                                    f"the frame renders black, as in Cycles",))

    @property
    def width(self) -> int:
        return int(self.resolution_x * self.resolution_percentage / 100)

    @property
    def height(self) -> int:
        return int(self.resolution_y * self.resolution_percentage / 100)


Camera = Union[ScreenCamera, BlenderCamera]


# --------------------------------------------------------------------------------------------
# Array sets: many primitives described as arrays, validated in whole-array operations (a
# million spheres validate in milliseconds).  Errors name the set, the field and the first
# offending index.  The arrays are copied and made read-only, so a set, once built, cannot
# change under the tracer.  (eq=False: equality is identity; comparing arrays element-wise
# is not what ``==`` on a scene should mean.)

#: The material types the tracer shades; the geometry treats them as opaque table entries.
MATERIAL_TYPES = (Material, SurfaceMaterial)


def _set_label(kind: str, name: str) -> str:
    return f"{kind} {value_text(name)}" if name else kind


def _materials(where: str, materials) -> tuple:
    try:
        table = tuple(materials)
    except TypeError:
        raise SceneError(f"{where}: materials must be a sequence of materials, "
                         f"got {value_text(materials)}") from None
    if not table:
        raise SceneError(f"{where}: materials must hold at least one material")
    for i, material in enumerate(table):
        if not isinstance(material, MATERIAL_TYPES):
            raise SceneError(f"{where}: materials[{i}] must be a material, got "
                             f"{value_text(material)}")
    return table


@dataclass(frozen=True, eq=False)
class SphereSet:
    """N spheres as arrays (point clouds, particles, molecules): world-space ``centers``
    (N, 3), ``radii`` (N,), ``material_indices`` (N,) into ``materials`` (at least one).

    Spheres that draw nothing in Cycles, of radius <= 0 or a centre or radius that is not
    finite, are left out (``warnings`` counts them, in one line)."""

    centers: np.ndarray
    radii: np.ndarray
    material_indices: np.ndarray
    materials: tuple
    name: str = ""
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        where = _set_label("sphere set", self.name)
        centers = _frozen_array(where, "centers", self.centers, np.float64, (None, 3))
        count = len(centers)
        radii = _frozen_array(where, "radii", self.radii, np.float64, (count,))
        indices = _frozen_array(where, "material_indices", self.material_indices, np.int64,
                                (count,))
        materials = _materials(where, self.materials)
        _require_indices(where, "material_indices", indices, len(materials), "materials")
        # Compared this way round, NaN radii are left out too, without a NumPy warning.
        drawn = np.isfinite(centers).all(axis=1) & (radii > 0) & (radii <= MAX_MAGNITUDE)
        if not drawn.all():
            first = int(np.flatnonzero(~drawn)[0])
            culprit = (f"radii[{first}] is {value_text(radii[first])}"
                       if np.isfinite(centers[first]).all() else
                       f"centers[{first}] is {value_text(centers[first])}")
            _set(self, "warnings", (f"{where}: {int((~drawn).sum())} of {count} spheres draw "
                                    f"nothing, as in Cycles ({culprit})",))
            centers, radii, indices = (_frozen(a[drawn]) for a in (centers, radii, indices))
        for name, value in (("centers", centers), ("radii", radii),
                            ("material_indices", indices), ("materials", materials)):
            _set(self, name, value)

    def __len__(self) -> int:
        return len(self.radii)


def _identity_transforms() -> np.ndarray:
    return np.eye(4)[None]


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A triangle mesh in object space, drawn once per instance transform.

    vertices (V, 3); triangles (T, 3) vertex indices, counter-clockwise seen from the front
    (Blender's winding); corner_normals (T, 3, 3) per-corner normals in object space (unit
    after validation: they are normalised), or None for flat shading (the geometric normal);
    material_indices (T,) into ``materials`` (at least one); transforms (K, 4, 4)
    object-to-world matrices, one per instance (affine: last row 0 0 0 1, invertible 3 x 3).
    Normals go to world space by the inverse transpose of each instance's 3 x 3.
    shadow_terminator_offset: Blender's Shadow Terminator > Geometry Offset in [0, 1] (its
    default 0.1): how many of a smooth mesh's grazing shadow rays leave from the smooth
    surface over its facets rather than from the facets (``core.terminator``); 0 keeps the
    facets' faceted terminator.  Flat meshes (corner_normals None) have none.
    uv_maps: ((name, (T, 3, 2) corner UVs), ...): the UV maps shader programs read, the
    first the active render map (a program's 'uv' coordinate); () where none reads one.
    tangent_maps: ((UV map name, (T, 3, 4) corner tangents and bitangent signs), ...): the
    MikkTSpace tangents of the UV maps Normal Map nodes read, object space, the first the
    active render map's; () where none reads them.
    attributes: ((name, (T, 3, 4) corner values and alpha), ...): the mesh attributes
    Attribute and Vertex Color nodes read ('' the render colour attribute); () where none.
    Triangles that touch a vertex that is not finite are left out, as Cycles leaves them
    (``warnings`` counts them, in one line).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray | None
    material_indices: np.ndarray
    materials: tuple
    transforms: np.ndarray = field(default_factory=_identity_transforms)
    name: str = ""
    shadow_terminator_offset: float = DEFAULT_GEOMETRY_OFFSET
    uv_maps: tuple = ()
    tangent_maps: tuple = ()
    attributes: tuple = ()
    warnings: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        where = _set_label("mesh", self.name)
        vertices = _frozen_array(where, "vertices", self.vertices, np.float64, (None, 3))
        triangles = _frozen_array(where, "triangles", self.triangles, np.int64, (None, 3))
        count = len(triangles)
        indices = _frozen_array(where, "material_indices", self.material_indices, np.int64,
                                (count,))
        materials = _materials(where, self.materials)
        transforms = _frozen_array(where, "transforms", self.transforms, np.float64,
                                   (None, 4, 4))
        _require_indices(where, "triangles", triangles, len(vertices), "vertices")
        _require_indices(where, "material_indices", indices, len(materials), "materials")
        vertices, keep, dropped = usable_triangles(vertices, triangles)
        vertices = _frozen(vertices)
        _require_finite(where, "transforms", transforms)
        if len(transforms) == 0:
            raise SceneError(f"{where}: transforms must hold at least one 4 x 4 matrix")
        bad = _first_bad(np.any(transforms[:, 3, :] != (0.0, 0.0, 0.0, 1.0), axis=1))
        if bad is not None:
            raise SceneError(f"{where}: transforms{_index_text(bad)} must be affine (last row "
                             f"0 0 0 1), got {value_text(transforms[bad][3])}")
        linear = transforms[:, :3, :3]
        # Judged on the matrix divided by its largest entry, so that a scene modelled at any
        # scale (1e-150 or 1e155) is not singular through under- or overflow of the det.
        scale = np.abs(linear).max(axis=(1, 2))
        unit = linear / np.where(scale > 0, scale, 1.0)[:, None, None]
        bad = _first_bad((scale == 0) | (np.abs(np.linalg.det(unit)) <= 1e-12))
        if bad is not None:
            raise SceneError(f"{where}: transforms{_index_text(bad)} is singular (its 3 x 3 "
                             f"part has no inverse)")
        normals = self.corner_normals
        if normals is not None:
            # Not copied first: the normalised normals are a new array anyway.
            normals = _checked_array(where, "corner_normals", normals, np.float64,
                                     (count, 3, 3))
            if keep is not None:
                normals = normals[keep]
            _require_finite(where, "corner_normals", normals)
            normals = _unit_rows(where, "corner_normals", normals)
        if keep is not None:
            triangles, indices = _frozen(triangles[keep]), _frozen(indices[keep])
            _set(self, "warnings", (f"{where}: {dropped}",))
        for name, value in (("vertices", vertices), ("triangles", triangles),
                            ("corner_normals", normals), ("material_indices", indices),
                            ("materials", materials), ("transforms", transforms)):
            _set(self, name, value)
        _set(self, "shadow_terminator_offset",
             _fraction(f"{where}.shadow_terminator_offset", self.shadow_terminator_offset))
        maps = []
        for name, corners in self.uv_maps:
            if not isinstance(name, str):
                raise SceneError(f"{where}: uv_maps names must be strings, got {name!r}")
            corners = _frozen_array(where, f"uv_maps[{name!r}]", corners, np.float32,
                                    (count, 3, 2))
            _require_finite(where, f"uv_maps[{name!r}]", corners)
            maps.append((name, corners if keep is None else _frozen(corners[keep])))
        _set(self, "uv_maps", tuple(maps))
        tangents = []
        for name, corners in self.tangent_maps:
            corners = _frozen_array(where, f"tangent_maps[{name!r}]", corners, np.float32,
                                    (count, 3, 4))
            _require_finite(where, f"tangent_maps[{name!r}]", corners)
            tangents.append((str(name), corners if keep is None else _frozen(corners[keep])))
        _set(self, "tangent_maps", tuple(tangents))
        attributes = []
        for name, corners in self.attributes:
            if not isinstance(name, str):
                raise SceneError(f"{where}: attributes names must be strings, got {name!r}")
            corners = _frozen_array(where, f"attributes[{name!r}]", corners, np.float32,
                                    (count, 3, 4))
            # (Imported data may hold NaN: read as zero, as a missing attribute is.)
            if not np.isfinite(corners).all():
                corners = _frozen(np.nan_to_num(corners, nan=0.0, posinf=0.0, neginf=0.0))
            attributes.append((name, corners if keep is None else _frozen(corners[keep])))
        _set(self, "attributes", tuple(attributes))

    def __len__(self) -> int:
        """Triangles drawn: triangles per instance times instances."""
        return len(self.triangles) * len(self.transforms)


@dataclass(frozen=True)
class Scene:
    """A whole scene.

    spheres: hand-made spheres (may be empty).  lights: any of ``LIGHT_TYPES``; their
    contributions sum.  sphere_sets: spheres as arrays (``SphereSet``); meshes: triangle
    meshes (``TriangleMesh``).
    camera: a ScreenCamera (the article's) or a BlenderCamera.
    background: RGB seen where a ray escapes (default semantics; the article's is black).
    world: the world's shader program (``core.shader.program.ShaderProgram``: its value is
        the radiance of the directions rays escape in), which the path integrator runs;
        ``background`` is then its value straight up.  None: the world is ``background``.
    ambient: an RGB ambient intensity lighting every point in addition to the lights' own
        ambient terms (default semantics only).  For a SurfaceMaterial it is the radiance of
        a constant environment: a diffuse surface reflects albedo x ambient, a rough glossy
        one F(N.V) x ambient (Blender's world colour x strength plays this role).
    """

    camera: Camera
    spheres: tuple[Sphere, ...] = ()
    lights: tuple = ()
    background: Vec3 = (0.0, 0.0, 0.0)
    ambient: Vec3 = (0.0, 0.0, 0.0)
    sphere_sets: tuple[SphereSet, ...] = ()
    meshes: tuple[TriangleMesh, ...] = ()
    world: object = None

    def __post_init__(self):
        if not isinstance(self.camera, (ScreenCamera, BlenderCamera)):
            raise SceneError(f"scene.camera must be a ScreenCamera or BlenderCamera, "
                             f"got {value_text(self.camera)}")
        _set(self, "spheres", tuple(self.spheres))
        _set(self, "lights", tuple(self.lights))
        for i, sphere in enumerate(self.spheres):
            if not isinstance(sphere, Sphere):
                raise SceneError(f"scene.spheres[{i}] must be a Sphere, got {value_text(sphere)}")
        for i, light in enumerate(self.lights):
            if not isinstance(light, LIGHT_TYPES):
                raise SceneError(f"scene.lights[{i}] must be a PointLight, SphereLight, "
                                 f"SpotLight, SunLight or AreaLight, got {value_text(light)}")
        _set(self, "sphere_sets", tuple(self.sphere_sets))
        _set(self, "meshes", tuple(self.meshes))
        for i, sphere_set in enumerate(self.sphere_sets):
            if not isinstance(sphere_set, SphereSet):
                raise SceneError(f"scene.sphere_sets[{i}] must be a SphereSet, got "
                                 f"{value_text(sphere_set)}")
        for i, mesh in enumerate(self.meshes):
            if not isinstance(mesh, TriangleMesh):
                raise SceneError(f"scene.meshes[{i}] must be a TriangleMesh, got "
                                 f"{value_text(mesh)}")
        _set(self, "background", _colour("scene.background", self.background))
        _set(self, "ambient", _colour("scene.ambient", self.ambient))
        if self.world is not None and not _is_program(self.world):
            raise SceneError(f"scene.world must be a core.shader ShaderProgram or None, got "
                             f"{type(self.world).__name__}")

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the scene's parts render otherwise than they hold it (a light that emits
        nothing, triangles or spheres left out, ...), one line each naming the part and
        the field."""
        parts = (self.camera, *self.lights, *self.sphere_sets, *self.meshes)
        return tuple(line for part in parts for line in getattr(part, "warnings", ()))

    @property
    def sphere_count(self) -> int:
        """Spheres, listed one by one or in sets."""
        return len(self.spheres) + sum(len(s) for s in self.sphere_sets)

    @property
    def triangle_count(self) -> int:
        """Triangles drawn (each mesh's triangles times its instances)."""
        return sum(len(mesh) for mesh in self.meshes)


@dataclass(frozen=True)
class RenderSettings:
    """How to render.

    semantics: 'article' keeps every quirk of the article; 'default' fixes them (see
        ``core.shading`` and the README for the list).
    precision: 'float64', 'float32', or 'auto' (``core.precision.choose_precision`` picks
        float32 only when the scene's ratio of size to smallest feature allows it).
    max_depth: number of bounces (the primary hit counts as the first).
    anti_aliasing: 'off' (one ray through each pixel centre), 'fixed' (``samples`` stratified
        rays in every pixel), 'adaptive' (one ray per pixel, then ``samples`` rays in the pixels
        whose neighbours hit a different sphere or differ in colour).
    samples: rays per supersampled pixel.
    light_samples: shadow rays per light with radius > 0 (soft shadows).
    world_samples: shadow rays per point towards the world (a k x k grid of at least this
        many; default semantics, scenes with several spheres and a world that shines): the
        share of the sky a point sees scales the world's diffuse light (contact shadows);
        0 treats the world as unoccluded.
    contribution_cutoff: a path stops once nothing it could still add exceeds this (a fraction
        of full white); 1e-6 keeps results float64-accurate to the 8-bit output many times over.
    tile_size: tiles are tile_size x tile_size pixels; memory per tile is bounded by it.
    threads: how many tiles render at once (None: one per core), on threads or worker
        processes as ``parallelism`` says.  Results never depend on it.
    parallelism: 'auto' (the default), 'threads' (a thread pool in this process) or
        'processes' (worker processes, ``core.workers``).  Processes render only renders of
        more than one tile and at least ``core.workers.MIN_PIXELS`` pixels (smaller ones
        stay in this process, where a worker's start-up would cost more than it gains), and
        fall back to threads where processes cannot start (``RenderResult.fallback`` says
        why).  'auto' takes processes where 'processes' would and ``threads`` is more than
        one (one worker only moves the work), except in a process that renders once
        (``python -m core``, render.py for one frame), where a cold start must pay:
        workers already running, or ``core.workers.COLD_MIN_SAMPLES`` camera samples.
        Measured on 2 cores, two threads render the article's 1080p frame 0.91x as fast as
        one (the GIL), two warm processes 1.75x (README: "Worker processes and malloc
        settings").  Results never depend on it.
    cluster: '' (render on this machine, as ``parallelism`` says), or the address of a Dask
        scheduler ('tcp://HOST:PORT' or 'tls://HOST:PORT') whose workers render the tiles
        (``core.cluster``; needs ``dask[distributed]`` here and Glint's core on the workers).
        The image is the same bit for bit.
    film: the image's alpha and background (default semantics; ``core.choices.FILM_CHOICES``):
        'coverage' (the core's own image): the background where camera rays escape, alpha =
        1 - transparency, the share of the pixel's samples that escaped (directly or straight
        through Transparent BSDFs, weighted by what passed) or met a holdout; 'opaque'
        (Blender's Film > Transparent off): the same colours, alpha = 1 - the holdouts' share
        only; 'transparent' (Film > Transparent on): escaped camera rays add no background,
        alpha as for 'coverage'.  Article semantics: alpha is the coverage ('opaque': 1).
    """

    semantics: Literal["default", "article"] = "default"
    precision: Literal["auto", "float64", "float32"] = "auto"
    max_depth: int = 3
    anti_aliasing: Literal["off", "fixed", "adaptive"] = "off"
    samples: int = 16
    light_samples: int = 16
    world_samples: int = 9
    contribution_cutoff: float = 1e-6
    tile_size: int = 128
    threads: int | None = None
    parallelism: Literal["auto", "threads", "processes"] = "auto"
    film: Literal["coverage", "opaque", "transparent"] = "coverage"
    integrator: Literal["path", "whitted"] = "path"
    max_bounces: int = 12
    diffuse_bounces: int = 4
    glossy_bounces: int = 4
    transmission_bounces: int = 12
    transparent_bounces: int = 8
    clamp_direct: float = 0.0
    clamp_indirect: float = 10.0
    caustics_reflective: bool = True
    caustics_refractive: bool = True
    filter_glossy: float = 1.0
    noise_threshold: float = 0.0
    min_samples: int = 0
    time_limit: float = 0.0
    filter_type: Literal["BOX", "GAUSSIAN", "BLACKMAN_HARRIS"] = "BLACKMAN_HARRIS"
    filter_width: float = 1.5
    seed: int = 0
    guides: bool = False
    cluster: str = ""

    def __post_init__(self):
        _choice("settings.semantics", self.semantics, SEMANTICS)
        _choice("settings.precision", self.precision, PRECISIONS)
        _choice("settings.anti_aliasing", self.anti_aliasing, ANTI_ALIASING)
        _choice("settings.parallelism", self.parallelism, PARALLELISM)
        _set(self, "cluster", check_address("settings.cluster", self.cluster))
        _choice("settings.film", self.film, FILMS)
        _count("settings.max_depth", self.max_depth, maximum=MAX_DEPTH)
        _count("settings.samples", self.samples, maximum=MAX_SAMPLES)
        _count("settings.light_samples", self.light_samples, maximum=MAX_LIGHT_SAMPLES)
        _count("settings.world_samples", self.world_samples, minimum=0,
               maximum=MAX_LIGHT_SAMPLES)
        _count("settings.tile_size", self.tile_size, minimum=8, maximum=MAX_TILE_SIZE)
        if self.threads is not None:
            _count("settings.threads", self.threads, maximum=MAX_THREADS)
        _set(self, "contribution_cutoff",
             _non_negative("settings.contribution_cutoff", self.contribution_cutoff))
        _choice("settings.integrator", self.integrator, INTEGRATORS)
        _choice("settings.filter_type", self.filter_type, PIXEL_FILTERS)
        for name in ("max_bounces", "diffuse_bounces", "glossy_bounces",
                     "transmission_bounces", "transparent_bounces"):
            _count(f"settings.{name}", getattr(self, name), minimum=0, maximum=MAX_DEPTH)
        _count("settings.min_samples", self.min_samples, minimum=0, maximum=MAX_SAMPLES)
        _count("settings.seed", self.seed, minimum=0, maximum=2 ** 31 - 1)
        for name in ("clamp_direct", "clamp_indirect", "filter_glossy", "noise_threshold",
                     "time_limit"):
            _set(self, name, _non_negative(f"settings.{name}", getattr(self, name)))
        _set(self, "filter_width", _positive("settings.filter_width", self.filter_width))
        if self.filter_width > MAX_FILTER_WIDTH:
            raise SceneError(f"settings.filter_width must be at most {MAX_FILTER_WIDTH:g} "
                             f"pixels, got {value_text(self.filter_width)}")
        for name in ("caustics_reflective", "caustics_refractive", "guides"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise SceneError(f"settings.{name} must be True or False, got "
                                 f"{value_text(getattr(self, name))}")
            _set(self, name, bool(getattr(self, name)))
