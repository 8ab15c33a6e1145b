"""How surfaces answer light in the default semantics: the lobes of ``SurfaceMaterial`` (and
the article's ``Material`` under Blender's lights), and the secondary rays they spawn.

Radiance leaving a point towards V, for light of irradiance E (``core.lights``, cos(theta_i)
included) arriving from direction L, H = normalize(L + V):

    diffuse / pi * E                                             (Lambert)
  + F(L.H) * D(N.H) * Vis(N.L, N.V) * E                          (GGX microfacet lobe)

with Schlick's F(c) = f0 + (f90 - f0) (1 - c)^5, Trowbridge-Reitz's
D = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2) and the height-correlated Smith visibility
Vis = G / (4 N.L N.V) = 0.5 / (N.L sqrt((N.V)^2 (1 - alpha^2) + alpha^2)
+ N.V sqrt((N.L)^2 (1 - alpha^2) + alpha^2)) (Heitz 2014), alpha = roughness^2 (Blender's
convention): the lobe Cycles' Glossy and Principled BSDFs use, at the cost of a few
arithmetic operations per point, so highlights have Cycles' size, shape and strength (a
normalised Blinn-Phong lobe, tried first, matched the energy within 10 % but missed GGX's
long tails by 50-90 % per pixel).  Single-scattering GGX loses the light that bounces
between microfacets (31 % at roughness 1); Turquin's compensation 1 + f0 (1 / E(N.V) - 1),
with E the lobe's directional albedo tabulated once (``directional_albedo``), puts it back,
as Cycles' multiscatter GGX does.  The article's Material
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

from .scene import MIN_ALPHA, Material, SurfaceMaterial, dielectric_f0
from .vectors import dot, normalize, take


@dataclass(frozen=True)
class SurfaceArrays:
    """Per-sphere lobes in the render precision: (3, N) colours, (N,) scalars.

    physical: SurfaceMaterial (True) or the article's Material.  alpha: the GGX lobe's
    roughness^2 (physical); lobe_norm, exponent: the article's highlight, 1 / pi and
    shininess / 4.  mirror: traces a
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
    alpha: np.ndarray
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
                                  "alpha",
                                  "emission", "mirror", "glossy_environment", "reflection",
                                  "transmission", "transmission_fresnel", "ior",
                                  "transparency")}
    black = (0.0, 0.0, 0.0)
    for material in materials:
        if isinstance(material, SurfaceMaterial):
            mirror = material.roughness <= SurfaceMaterial.MIRROR_ROUGHNESS
            values = dict(physical=True, diffuse=material.diffuse, f0=material.specular_f0,
                          f90=material.specular_f90, lobe_norm=0.0, exponent=0.0,
                          alpha=max(material.roughness ** 2, MIN_ALPHA),
                          emission=material.emission, mirror=mirror,
                          glossy_environment=not mirror, reflection=0.0,
                          transmission=material.transmission,
                          transmission_fresnel=material.transmission_fresnel,
                          ior=material.ior, transparency=material.transparency)
        else:
            assert isinstance(material, Material)
            values = dict(physical=False, diffuse=material.diffuse, f0=material.specular,
                          f90=material.specular, lobe_norm=1 / np.pi,
                          exponent=material.shininess / 4, alpha=1.0, emission=black,
                          mirror=False,
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


def _visibility(cos_l, cos_v, a2):
    """Height-correlated Smith G / (4 N.L N.V) (Heitz 2014)."""
    return 0.5 / (cos_l * np.sqrt(cos_v * cos_v * (1 - a2) + a2)
                  + cos_v * np.sqrt(cos_l * cos_l * (1 - a2) + a2))


def ggx(cos_half, cos_l, cos_v, alpha):
    """D(N.H) Vis(N.L, N.V) of the GGX lobe (module docstring), any matching shapes."""
    a2 = alpha * alpha
    d = a2 / (np.pi * (cos_half * cos_half * (a2 - 1) + 1) ** 2)
    return d * _visibility(cos_l, cos_v, a2)


_ALBEDO_COSINES = np.linspace(0.02, 1.0, 25)
_ALBEDO_ALPHAS = np.linspace(0.0, 1.0, 21)
_albedo_table = None


def _directional_albedo_table() -> np.ndarray:
    """(alphas, cosines) table of E(mu, alpha), the lobe's reflectance with F = 1, once.

    Half vectors are drawn from D(h) (N.H) on a stratified 96 x 32 grid (tan^2 theta_h =
    alpha^2 u / (1 - u)), which resolves sharp and wide lobes alike; each contributes
    Vis 4 (V.H) (N.L) / (N.H), the estimator of the integral of D Vis cos(theta_l)."""
    global _albedo_table
    if _albedo_table is None:
        u = (np.arange(96) + 0.5) / 96
        phi = (np.arange(32) + 0.5) / 32 * 2 * np.pi
        alpha = np.maximum(_ALBEDO_ALPHAS, 1e-3)[:, None, None, None]
        mu = _ALBEDO_COSINES[None, :, None, None]
        cos_h = 1 / np.sqrt(1 + alpha ** 2 * (u / (1 - u))[None, None, :, None])
        sin_h = np.sqrt(1 - cos_h ** 2)
        h = (sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h)
        view = (np.sqrt(1 - mu ** 2), 0.0, mu)
        v_dot_h = view[0] * h[0] + view[2] * h[2]
        cos_l = 2 * v_dot_h * cos_h - mu
        contribution = np.where(
            (cos_l > 0) & (v_dot_h > 0),
            _visibility(np.maximum(cos_l, 1e-9), mu, alpha ** 2) * 4 * v_dot_h
            * np.maximum(cos_l, 0) / cos_h, 0)
        _albedo_table = np.minimum(contribution.mean(axis=(2, 3)), 1.0)
    return _albedo_table


def directional_albedo(cos_v, alpha):
    """E(N.V, alpha) (m,) of the GGX lobe, bilinear in the precomputed table."""
    table = _directional_albedo_table()
    x = np.interp(cos_v, _ALBEDO_COSINES, np.arange(len(_ALBEDO_COSINES)))
    y = np.interp(alpha, _ALBEDO_ALPHAS, np.arange(len(_ALBEDO_ALPHAS)))
    x0 = np.minimum(x.astype(int), len(_ALBEDO_COSINES) - 2)
    y0 = np.minimum(y.astype(int), len(_ALBEDO_ALPHAS) - 2)
    fx, fy = x - x0, y - y0
    top = table[y0, x0] * (1 - fx) + table[y0, x0 + 1] * fx
    bottom = table[y0 + 1, x0] * (1 - fx) + table[y0 + 1, x0 + 1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.asarray(cos_v).dtype)


def light_response(surfaces: SurfaceArrays, spheres, normals, to_view, towards, e):
    """Radiance (3, m) per unit light scale for irradiance e (m,) (cos(theta_i) included)
    from unit directions ``towards`` (3, m), seen from ``to_view`` (3, m) (module doc)."""
    half, _ = normalize(towards + to_view)
    cos_half = np.maximum(dot(normals, half), 0)
    f0, f90 = take(surfaces.f0, spheres), take(surfaces.f90, spheres)
    physical = surfaces.physical[spheres]
    fresnel = np.where(physical, schlick(f0, f90, dot(towards, half)), f0)
    alpha = surfaces.alpha[spheres]
    cos_l = np.maximum(dot(normals, towards), 1e-6)
    cos_v = np.maximum(dot(normals, to_view), 1e-6)
    # Multiple scattering between microfacets, which single-scattering GGX loses (Turquin
    # 2019): scale by 1 + f0 (1 / E(N.V) - 1), E the lobe's directional albedo.
    compensation = 1 + f0 * (1 / directional_albedo(cos_v, alpha) - 1)
    lobe = np.where(physical, ggx(cos_half, cos_l, cos_v, alpha),
                    surfaces.lobe_norm[spheres] * _power(cos_half, surfaces.exponent[spheres]))
    fresnel = np.where(physical, fresnel * compensation, fresnel)
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
