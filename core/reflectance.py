"""How surfaces reflect, as the material descriptions and the shading both need it: a
dielectric's Fresnel reflectance at normal incidence and its inverse, the share of a
Principled BSDF's glossy lobe that follows a dielectric's Fresnel curve, and the Blinn-Phong
exponent matching a roughness."""

from __future__ import annotations

import numpy as np


def dielectric_f0(ior: float) -> float:
    """Fresnel reflectance at normal incidence of a dielectric of index ``ior`` in air."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def ior_from_f0(f0):
    """The index >= 1 whose ``dielectric_f0`` is f0 (f0 capped at 0.999; a float or an
    array)."""
    root = np.sqrt(np.clip(f0, 0.0, 0.999))
    index = (1.0 + root) / (1.0 - root)
    return float(index) if np.ndim(index) == 0 else index


def principled_fresnel(base, tint, metallic, alpha, level, f0_dielectric):
    """(specular_dielectric, specular_ior) of a Principled BSDF's glossy lobe: the share of
    its rise from f0 to f90 (grey means) that is the dielectric layer's rather than the
    metal's, and the index whose f0 that layer has (Cycles' ``ior_from_F0``)."""
    dielectric = (1.0 - metallic) * alpha * (min(1.0, 2.0 * level) - f0_dielectric)
    rise_dielectric = dielectric * float(np.mean(tint))
    rise = rise_dielectric + metallic * alpha * (1.0 - float(np.mean(base)))
    share = min(1.0, max(0.0, rise_dielectric / rise)) if rise > 0 else 0.0
    return share, ior_from_f0(f0_dielectric)


#: alpha = roughness^2 is clamped here so that roughness 0 gives a finite exponent.
MIN_ALPHA = 1e-3


def blinn_exponent(roughness: float) -> float:
    """The Blinn-Phong exponent n = 2 / alpha^2 - 2 matching a Beckmann lobe of roughness
    alpha = roughness^2 (Walter et al. 2007, eq. 30)."""
    alpha = max(float(roughness) ** 2, MIN_ALPHA)
    return 2.0 / alpha ** 2 - 2.0
