"""Materials: the article's Blinn-Phong ``Material`` and the physically based
``SurfaceMaterial`` (lobes in Cycles' units), validated on construction as every part of a
scene is (``core.scene``; the reflectance formulas they use: ``core.reflectance``; how the
tracer shades them: ``core.bsdf``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .reflectance import blinn_exponent, dielectric_f0, principled_fresnel
from .validation import (MAX_SHININESS, SceneError, Vec3, value_text, _colour, _finite,
                         _fraction, _non_negative, _positive, _set)


def _is_program(value) -> bool:
    from .shader.program import ShaderProgram
    return isinstance(value, ShaderProgram)


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
