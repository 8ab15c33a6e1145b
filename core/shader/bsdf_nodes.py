"""Blender's shader nodes as closures over arrays of shading points: the BSDF, emission and
mixing nodes a material's Surface (or a world's) is built from.

A shader socket carries a ``LobeSum``: per hit, every lobe kind's weight as a colour, and
the lobes' parameters (roughness, indices, the specular layer) as sums weighted by their
lobe's strength, so that Mix and Add Shader are plain weighted sums, per hit.  At the end
(``LobeSum.closures``) the sums are divided by their weights: two glossy lobes of different
roughness become one of their weighted mean roughness, as two diffuse colours become their
sum (the model's one approximation of a mix; the supported-nodes page says so).
The lobes and their parameters are ``core.closures``' (see its docstring for what each
means); the Principled BSDF's are ``core.materials.SurfaceMaterial.principled``'s, per hit.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..closures import Closures
from ..reflectance import MIN_ALPHA, dielectric_f0, ior_from_f0
from .registry import CLOSURE, COLOR, FLOAT, VECTOR, node

_COLOURS = ("diffuse", "f0", "f90", "transmission", "emission", "transparency",
            "translucency", "normal_sum")


@dataclass
class LobeSum:
    """Per-hit lobes (module docstring): colours (3, n) or (3, 1), weights (n,) or 0-d."""

    diffuse: np.ndarray
    f0: np.ndarray
    f90: np.ndarray
    gloss_weight: np.ndarray
    roughness_sum: np.ndarray
    transmission: np.ndarray
    refraction_weight: np.ndarray
    ior_sum: np.ndarray
    fresnel_sum: np.ndarray
    emission: np.ndarray
    transparency: np.ndarray
    translucency: np.ndarray
    holdout: np.ndarray
    layered_sum: np.ndarray
    layer_f0_sum: np.ndarray
    dielectric_sum: np.ndarray
    specular_ior_sum: np.ndarray
    normal_sum: np.ndarray
    normal_weight: np.ndarray

    @classmethod
    def none(cls, dtype=np.float64) -> "LobeSum":
        values = {}
        for item in fields(cls):
            shape = (3, 1) if item.name in _COLOURS else ()
            values[item.name] = np.zeros(shape, dtype)
        return cls(**values)

    def scaled(self, k) -> "LobeSum":
        """Every weight times k (0-d or (n,))."""
        k = np.asarray(k)
        return LobeSum(**{item.name: getattr(self, item.name) * k for item in fields(self)})

    def __add__(self, other: "LobeSum") -> "LobeSum":
        return LobeSum(**{item.name: getattr(self, item.name) + getattr(other, item.name)
                          for item in fields(self)})

    def with_normal(self, normal, weight) -> "LobeSum":
        """The lobes with their own shading normal (3, n) (a linked Normal input), counted
        with ``weight`` (n,) in the closures' weighted mean normal."""
        self.normal_sum = normal * weight
        self.normal_weight = np.asarray(weight)
        return self

    def closures(self, n: int, dtype, normal=None) -> Closures:
        """The per-hit ``Closures`` of these lobes at n hits (``Lobes.material``'s rules);
        normal: (3, n) the hits' own shading normal, which lobes without a linked Normal
        keep."""
        def colour(value):
            return np.ascontiguousarray(np.broadcast_to(np.maximum(value, 0), (3, n)), dtype)

        def scalar(value):
            return np.ascontiguousarray(np.broadcast_to(value, (n,)), dtype)

        def ratio(total, weight, default):
            total, weight = scalar(total), scalar(weight)
            return np.where(weight > 0, total / np.where(weight > 0, weight, 1), default)

        roughness = np.clip(ratio(self.roughness_sum, self.gloss_weight, 0.5), 0, 1)
        ior = np.maximum(ratio(self.ior_sum, self.refraction_weight, 1.5), 1e-3)
        fresnel = np.clip(ratio(self.fresnel_sum, self.refraction_weight, 1.0), 0, 1)
        diffuse = colour(self.diffuse)
        diffuse_weight = diffuse.mean(axis=0)
        layer = np.clip(ratio(self.layered_sum, diffuse_weight, 0.0), 0, 1)
        layer_f0 = np.clip(ratio(self.layer_f0_sum, self.layered_sum, 0.0), 0, 1)
        f0, f90 = colour(self.f0), colour(self.f90)
        rise = np.maximum(f90 - f0, 0).mean(axis=0)
        dielectric = np.clip(ratio(self.dielectric_sum, rise, 0.0), 0, 1)
        specular_ior = np.maximum(ratio(self.specular_ior_sum, self.dielectric_sum, 1.5), 1.0)
        bumped = None
        if normal is not None and np.any(self.normal_weight > 0):
            # The lobes' normals, weighted by the lobes, with the hits' own for the rest.
            own = np.maximum(total_weight(self) - scalar(self.normal_weight), 0)
            summed = np.broadcast_to(self.normal_sum, (3, n)) + normal * own
            length = np.sqrt((summed * summed).sum(axis=0))
            bumped = np.where(length > 0, summed / np.where(length > 0, length, 1),
                              normal).astype(dtype)
        holdout = np.clip(scalar(self.holdout), 0, 1)
        return Closures(
            diffuse=diffuse, layer=layer, layer_f0=layer_f0, f0=f0, f90=f90,
            dielectric=dielectric, specular_ior=specular_ior,
            alpha=np.maximum(roughness ** 2, MIN_ALPHA).astype(dtype),
            transmission=colour(self.transmission), transmission_fresnel=fresnel, ior=ior,
            translucency=colour(self.translucency), transparency=colour(self.transparency),
            emission=np.ascontiguousarray(np.broadcast_to(self.emission, (3, n)), dtype),
            holdout=holdout,
            holdout_object=np.zeros(n, bool), normal=bumped)


def total_weight(lobes: LobeSum):
    """(n,) how much the lobes weigh in a mean of their normals: their colours' means."""
    return (np.asarray(lobes.diffuse).mean(axis=0) + np.asarray(lobes.f90).mean(axis=0)
            + np.asarray(lobes.transmission).mean(axis=0)
            + np.asarray(lobes.translucency).mean(axis=0))


def _glossy(f0, f90, roughness) -> LobeSum:
    lobes = LobeSum.none()
    lobes.f0, lobes.f90 = f0, f90
    lobes.gloss_weight = np.asarray(f90).mean(axis=0)
    lobes.roughness_sum = lobes.gloss_weight * roughness
    return lobes


def _refraction(colour, ior, fresnel) -> LobeSum:
    lobes = LobeSum.none()
    lobes.transmission = colour
    lobes.refraction_weight = np.asarray(colour).mean(axis=0)
    lobes.ior_sum = lobes.refraction_weight * ior
    lobes.fresnel_sum = lobes.refraction_weight * fresnel
    return lobes


def _normal(points, lobes: LobeSum, normal) -> LobeSum:
    """The lobes with a linked Normal input: its normal (None, or the points' own: the
    hit's normal, nothing to record)."""
    if normal is None or normal is points.normal:
        return lobes
    return lobes.with_normal(np.asarray(normal), total_weight(lobes))


_NORMAL = {"Normal": "normal"}


@node("ShaderNodeBsdfPrincipled",
      inputs=(("Base Color", COLOR), ("Metallic", FLOAT), ("Roughness", FLOAT), ("IOR", FLOAT),
              ("Alpha", FLOAT), ("Normal", VECTOR), ("Specular IOR Level", FLOAT),
              ("Specular Tint", COLOR), ("Transmission Weight", FLOAT),
              ("Emission Color", COLOR), ("Emission Strength", FLOAT)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="Coat, sheen, subsurface, anisotropy and thin film are not modelled (the base "
           "layers are)")
def principled(points, base, metallic, roughness, ior, alpha, normal, level, tint,
               transmission, emission_colour, emission_strength):
    """Cycles' Principled BSDF's base layers (``SurfaceMaterial.principled``): a metal of
    weight metallic, a dielectric specular layer of f0 from the IOR and Specular IOR Level
    over glass (transmission) and diffuse; alpha scales everything and lets the rest through."""
    m = np.clip(metallic, 0, 1)
    t = np.clip(transmission, 0, 1)
    a = np.clip(alpha, 0, 1)
    ior = np.maximum(ior, 1e-3)
    level = np.maximum(level, 0)
    base = np.maximum(base, 0)
    tint = np.maximum(tint, 0)
    f0_dielectric = np.minimum(1.0, dielectric_f0(ior) * 2.0 * level)
    dielectric = (1 - m) * a
    lobes = _glossy(dielectric * f0_dielectric * tint + m * a * base,
                    dielectric * np.minimum(1.0, 2.0 * level) * tint + m * a, roughness)
    lobes.diffuse = dielectric * (1 - t) * (1 - f0_dielectric) * base
    layered = np.where(f0_dielectric > 0, lobes.diffuse.mean(axis=0), 0)
    lobes.layered_sum = layered
    lobes.layer_f0_sum = layered * np.minimum(1.0, f0_dielectric * tint.max(axis=0))
    # The share of the glossy lobe's rise from f0 to f90 that is the dielectric layer's
    # (``core.reflectance.principled_fresnel``, per hit).
    rise_dielectric = dielectric * (np.minimum(1.0, 2.0 * level) - f0_dielectric) * tint.mean(
        axis=0)
    rise = rise_dielectric + m * a * (1 - base.mean(axis=0))
    share = np.clip(np.where(rise > 0, rise_dielectric / np.where(rise > 0, rise, 1), 0), 0, 1)
    lobes.dielectric_sum = share * np.maximum(lobes.f90 - lobes.f0, 0).mean(axis=0)
    lobes.specular_ior_sum = lobes.dielectric_sum * ior_from_f0(f0_dielectric)
    lobes = lobes + _refraction(dielectric * t * base, ior, 1.0)
    lobes.emission = emission_colour * emission_strength
    lobes.transparency = (1 - a) * np.ones((3, 1))
    return (_normal(points, lobes, normal),)


@node("ShaderNodeBsdfDiffuse", inputs=(("Color", COLOR), ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="Oren-Nayar roughness is not modelled (Lambert)")
def diffuse_bsdf(points, colour, normal):
    lobes = LobeSum.none()
    lobes.diffuse = colour
    return (_normal(points, lobes, normal),)


def _approximated_diffuse(points, colour, normal):
    lobes = LobeSum.none()
    lobes.diffuse = colour
    return (_normal(points, lobes, normal),)


for _kind, _output in (("ShaderNodeSubsurfaceScattering", "BSSRDF"),
                       ("ShaderNodeBsdfSheen", "BSDF"), ("ShaderNodeBsdfToon", "BSDF")):
    node(_kind, inputs=(("Color", COLOR), ("Normal", VECTOR)), outputs=((_output, CLOSURE),),
         implicit=_NORMAL, note="approximated by a Diffuse BSDF of its colour",
         stand_in=True)(
        _approximated_diffuse)


@node("ShaderNodeBsdfGlossy", inputs=(("Color", COLOR), ("Roughness", FLOAT),
                                      ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="isotropic GGX (Anisotropy is not modelled)")
def glossy_bsdf(points, colour, roughness, normal):
    return (_normal(points, _glossy(colour, colour, roughness), normal),)


@node("ShaderNodeBsdfAnisotropic", inputs=(("Color", COLOR), ("Roughness", FLOAT),
                                           ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="isotropic GGX (Anisotropy is not modelled)")
def anisotropic_bsdf(points, colour, roughness, normal):
    return glossy_bsdf(points, colour, roughness, normal)


@node("ShaderNodeBsdfMetallic", inputs=(("Base Color", COLOR), ("Edge Tint", COLOR),
                                        ("Roughness", FLOAT), ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="Schlick's Fresnel from Base Color to white (Edge Tint and the physical "
           "conductor model are not modelled)")
def metallic_bsdf(points, base, edge, roughness, normal):
    return (_normal(points, _glossy(base, np.ones_like(base), roughness), normal),)


@node("ShaderNodeBsdfGlass", inputs=(("Color", COLOR), ("Roughness", FLOAT), ("IOR", FLOAT),
                                     ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="rough refraction goes through GGX microfacets by BSDF samples only (light "
           "samples do not reach through it)")
def glass_bsdf(points, colour, roughness, ior, normal):
    ior = np.maximum(ior, 1e-3)
    lobes = _glossy(colour * dielectric_f0(ior), colour, roughness) + _refraction(colour, ior,
                                                                                   1.0)
    return (_normal(points, lobes, normal),)


@node("ShaderNodeBsdfRefraction", inputs=(("Color", COLOR), ("Roughness", FLOAT),
                                          ("IOR", FLOAT), ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL,
      note="rough refraction goes through GGX microfacets by BSDF samples only")
def refraction_bsdf(points, colour, roughness, ior, normal):
    lobes = _refraction(colour, np.maximum(ior, 1e-3), 0.0)
    # Its microfacets' roughness, weighed as a glossy lobe's is (the two share one alpha).
    lobes.gloss_weight = lobes.refraction_weight
    lobes.roughness_sum = lobes.refraction_weight * np.asarray(roughness)
    return (_normal(points, lobes, normal),)


@node("ShaderNodeBsdfTranslucent", inputs=(("Color", COLOR), ("Normal", VECTOR)),
      outputs=(("BSDF", CLOSURE),), implicit=_NORMAL)
def translucent_bsdf(points, colour, normal):
    lobes = LobeSum.none()
    lobes.translucency = colour
    return (_normal(points, lobes, normal),)


@node("ShaderNodeBsdfTransparent", inputs=(("Color", COLOR),), outputs=(("BSDF", CLOSURE),))
def transparent_bsdf(points, colour):
    lobes = LobeSum.none()
    lobes.transparency = colour
    return (lobes,)


@node("ShaderNodeEmission", inputs=(("Color", COLOR), ("Strength", FLOAT)),
      outputs=(("Emission", CLOSURE),))
def emission(points, colour, strength):
    lobes = LobeSum.none()
    lobes.emission = colour * strength
    return (lobes,)


@node("ShaderNodeBackground", inputs=(("Color", COLOR), ("Strength", FLOAT)),
      outputs=(("Background", CLOSURE),))
def background(points, colour, strength):
    return emission(points, colour, strength)


@node("ShaderNodeHoldout", outputs=(("Holdout", CLOSURE),))
def holdout(points):
    lobes = LobeSum.none()
    lobes.holdout = np.asarray(1.0)
    return (lobes,)


@node("ShaderNodeMixShader", inputs=(("Fac", FLOAT), ("Shader", CLOSURE),
                                     ("Shader_001", CLOSURE)),
      outputs=(("Shader", CLOSURE),))
def mix_shader(points, factor, first, second):
    factor = np.clip(factor, 0, 1)
    return (first.scaled(1 - factor) + second.scaled(factor),)


@node("ShaderNodeAddShader", inputs=(("Shader", CLOSURE), ("Shader_001", CLOSURE)),
      outputs=(("Shader", CLOSURE),))
def add_shader(points, first, second):
    return (first + second,)

