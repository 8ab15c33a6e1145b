"""How surfaces answer light in the default semantics: the lobes of ``SurfaceMaterial`` (and
the article's ``Material`` under Blender's lights), and the secondary rays they spawn.

Radiance leaving a point towards V, for light of irradiance E (``core.lights``, cos(theta_i)
included) arriving from direction L, H = normalize(L + V):

    diffuse / pi * E                                   (Lambert)
  + F(L.H) * (n + 8) / (8 pi) * (N.H)^n * E            (normalised Blinn-Phong)

with Schlick's F(c) = f0 + (f90 - f0) (1 - c)^5 and n = 2 / alpha^2 - 2, alpha = roughness^2
(the Beckmann lobe it matches; ``scene.blinn_exponent``).  (n + 8) / (8 pi) is the
normalisation that makes the lobe's directional albedo about 1 for every n (Akenine-Moller et
al., Real-Time Rendering, 3rd ed., 7.6), so a rougher surface has a wider, dimmer highlight of
the same energy, as Cycles' GGX lobe does to a first approximation.  The article's Material
keeps its own lobe: kd / pi * E + ks / pi * (N.H)^(shininess / 4) * E (its light intensities
read as E / pi).

A constant environment of radiance W (``Scene.ambient``, the world) adds diffuse * W (the
cosine-weighted integral of a / pi over the hemisphere is a) and, on rough glossy surfaces,
F(N.V) * W; smooth ones (roughness <= ``SurfaceMaterial.MIRROR_ROUGHNESS``) trace a mirror
ray instead, weighted by F(N.V), which sees the world where it escapes.

Secondary rays (``scatter``): a mirror ray (F(N.V) for smooth physical surfaces, the
article's ``reflection`` for its Material, plus what total internal reflection returns), a
refracted ray (Snell's law with eta = 1 / ior entering and ior leaving, weight
transmission * (1 - transmission_fresnel * F), F Schlick's with f0 = ((ior - 1) / (ior + 1))^2
evaluated at the cosine on the less dense side; none under total internal reflection, where
the mirror ray gets transmission * (1 - transmission_fresnel * F(N.V)) more, so a clear glass
reflects everything), and a straight-through ray weighted by ``transparency``.  Rough
transmission is traced as sharp refraction (the blur is not modelled).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Material, SurfaceMaterial, blinn_exponent, dielectric_f0
from .vectors import dot, normalize, take


@dataclass(frozen=True)
class SurfaceArrays:
    """Per-sphere lobes in the render precision: (3, N) colours, (N,) scalars.

    physical: SurfaceMaterial (True) or the article's Material.  lobe_norm, exponent: the
    highlight's (n + 8) / (8 pi) and n (article: 1 / pi and shininess / 4).  mirror: traces a
    mirror ray weighted by F(N.V).  glossy_environment: reflects F(N.V) x the world instead.
    reflection: the article's mirror weight (0 for physical).  any_*: whether any sphere
    needs that work at all.
    """

    physical: np.ndarray
    diffuse: np.ndarray
    f0: np.ndarray
    f90: np.ndarray
    lobe_norm: np.ndarray
    exponent: np.ndarray
    emission: np.ndarray
    mirror: np.ndarray
    glossy_environment: np.ndarray
    reflection: np.ndarray
    transmission: np.ndarray
    transmission_fresnel: np.ndarray
    ior: np.ndarray
    transparency: np.ndarray
    any_physical: bool
    any_emission: bool
    any_through: bool


def surface_arrays(materials, dtype) -> SurfaceArrays:
    """SurfaceArrays for a sequence of Material / SurfaceMaterial (one per sphere)."""
    rows = {name: [] for name in ("physical", "diffuse", "f0", "f90", "lobe_norm", "exponent",
                                  "emission", "mirror", "glossy_environment", "reflection",
                                  "transmission", "transmission_fresnel", "ior",
                                  "transparency")}
    black = (0.0, 0.0, 0.0)
    for material in materials:
        if isinstance(material, SurfaceMaterial):
            n = blinn_exponent(material.roughness)
            mirror = material.roughness <= SurfaceMaterial.MIRROR_ROUGHNESS
            values = dict(physical=True, diffuse=material.diffuse, f0=material.specular_f0,
                          f90=material.specular_f90, lobe_norm=(n + 8) / (8 * np.pi),
                          exponent=n, emission=material.emission, mirror=mirror,
                          glossy_environment=not mirror, reflection=0.0,
                          transmission=material.transmission,
                          transmission_fresnel=material.transmission_fresnel,
                          ior=material.ior, transparency=material.transparency)
        else:
            assert isinstance(material, Material)
            values = dict(physical=False, diffuse=material.diffuse, f0=material.specular,
                          f90=material.specular, lobe_norm=1 / np.pi,
                          exponent=material.shininess / 4, emission=black, mirror=False,
                          glossy_environment=False, reflection=material.reflection,
                          transmission=black, transmission_fresnel=0.0, ior=1.0,
                          transparency=black)
        for name, value in values.items():
            rows[name].append(value)
    arrays = {}
    for name, values in rows.items():
        if name in ("physical", "mirror", "glossy_environment"):
            arrays[name] = np.asarray(values, bool).reshape(-1)
        elif name in ("diffuse", "f0", "f90", "emission", "transmission", "transparency"):
            arrays[name] = np.ascontiguousarray(np.asarray(values, np.float64).reshape(-1, 3).T,
                                                dtype)
        else:
            arrays[name] = np.asarray(values, np.float64).reshape(-1).astype(dtype)
    return SurfaceArrays(
        **arrays, any_physical=bool(arrays["physical"].any()),
        any_emission=bool(arrays["emission"].any()),
        any_through=bool(arrays["transmission"].any() or arrays["transparency"].any()))


def schlick(f0, f90, cosine):
    """Schlick's Fresnel (3, m) for lobes f0, f90 (3, m) and cosines (m,)."""
    c = np.clip(1 - cosine, 0, 1)
    c2 = c * c
    return f0 + (f90 - f0) * (c2 * c2 * c)


def _power(base, exponent):
    with np.errstate(invalid="ignore", divide="ignore", over="ignore", under="ignore"):
        result = np.power(np.maximum(base, 0), exponent)
    return np.nan_to_num(result, nan=0.0, posinf=0.0)


def light_response(surfaces: SurfaceArrays, spheres, normals, to_view, towards, e):
    """Radiance (3, m) per unit light scale for irradiance e (m,) (cos(theta_i) included)
    from unit directions ``towards`` (3, m), seen from ``to_view`` (3, m) (module doc)."""
    half, _ = normalize(towards + to_view)
    cos_half = np.maximum(dot(normals, half), 0)
    f0, f90 = take(surfaces.f0, spheres), take(surfaces.f90, spheres)
    physical = surfaces.physical[spheres]
    fresnel = np.where(physical, schlick(f0, f90, dot(towards, half)), f0)
    lobe = surfaces.lobe_norm[spheres] * _power(cos_half, surfaces.exponent[spheres])
    return e * (take(surfaces.diffuse, spheres) * (1 / np.pi) + fresnel * lobe)


def environment(surfaces: SurfaceArrays, spheres, normals, to_view, world):
    """Radiance (3, m) the physical surfaces reflect from a constant world (3, 1): emission
    plus the rough glossy lobe's F(N.V) W (diffuse x world is the ambient term)."""
    colour = take(surfaces.emission, spheres) if surfaces.any_emission else 0
    glossy = surfaces.glossy_environment[spheres]
    if glossy.any() and world.any():
        cos_v = dot(normals, to_view)
        fresnel = schlick(take(surfaces.f0, spheres), take(surfaces.f90, spheres), cos_v)
        colour = colour + fresnel * glossy * world
    return colour


@dataclass
class Branch:
    """Secondary rays leaving some of m hit points: index (k,) into the points, unit
    directions (3, k), weights (3, k), and whether each leaves through the surface."""

    index: np.ndarray
    directions: np.ndarray
    weights: np.ndarray
    through: bool


def scatter(surfaces: SurfaceArrays, normals, directions, cos_in, spheres, front) -> list:
    """Branches of secondary rays at m hits (default semantics; module docstring).

    normals face the incoming unit ``directions`` (3, m); cos_in = D.N (m,) <= 0; front:
    whether the outside was hit."""
    dtype = directions.dtype
    cos_v = -cos_in
    reflect_weight = np.broadcast_to(surfaces.reflection[spheres], directions.shape).copy()
    mirror = surfaces.mirror[spheres]
    if mirror.any():
        fresnel = schlick(take(surfaces.f0, spheres), take(surfaces.f90, spheres), cos_v)
        reflect_weight += np.where(mirror, fresnel, 0)
    branches = []
    if surfaces.any_through:
        transmission = take(surfaces.transmission, spheres)
        transparency = take(surfaces.transparency, spheres)
        refracting = transmission.max(axis=0) > 0
        if refracting.any():
            index = np.flatnonzero(refracting)
            ior = surfaces.ior[spheres[index]]
            eta = np.where(front[index], 1 / ior, ior)
            c = cos_v[index]
            sin2_t = eta * eta * (1 - c * c)
            total = sin2_t >= 1
            cos_t = np.sqrt(np.maximum(1 - sin2_t, 0))
            f0 = dielectric_f0(ior)
            # Schlick on the less dense side: the incident cosine entering, the transmitted
            # one leaving (so that F reaches 1 at the critical angle).
            f = f0 + (1 - f0) * (1 - np.where(eta <= 1, c, cos_t)) ** 5
            k = surfaces.transmission_fresnel[spheres[index]]
            weights = transmission[:, index] * np.where(total, 0, 1 - k * f)
            # Under total internal reflection the refracted share is reflected: for glass
            # (f0 = c f0(ior), f90 = c on the mirror lobe) the two then sum to c.
            f_incident = f0 + (1 - f0) * (1 - c) ** 5
            reflect_weight[:, index] += transmission[:, index] * (total * (1 - k * f_incident))
            d, n = directions[:, index], normals[:, index]
            refracted = eta * d + (eta * c - cos_t) * n
            go = np.flatnonzero(~total & (weights.max(axis=0) > 0))
            if len(go):
                refracted, _ = normalize(take(refracted, go))
                branches.append(Branch(index[go], refracted, take(weights, go), True))
        passing = np.flatnonzero(transparency.max(axis=0) > 0)
        if len(passing):
            branches.append(Branch(passing, take(directions, passing),
                                   take(transparency, passing), True))
    reflecting = np.flatnonzero(reflect_weight.max(axis=0) > 0)
    if len(reflecting):
        d, n = take(directions, reflecting), take(normals, reflecting)
        reflected = d - (2 * cos_in[reflecting]) * n
        branches.insert(0, Branch(reflecting, reflected.astype(dtype),
                                  take(reflect_weight, reflecting), False))
    return branches
