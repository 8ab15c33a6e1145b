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
the lobe's directional albedo with Fresnel times W (``glossy_albedo``: what the lobe's own
response to lights integrates to, not F(N.V), which at grazing angles is 4x too much on a
rough surface); smooth ones (roughness <= ``SurfaceMaterial.MIRROR_ROUGHNESS``) trace a
mirror ray instead, weighted by F(N.V), which sees the world where it escapes.  A diffuse
lobe under a Principled BSDF's specular layer loses what that layer reflects (1 - A(N.V),
Cycles' layering: ``diffuse_seen``), for lights and the world alike.

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

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from .reflectance import MIN_ALPHA, dielectric_f0, ior_from_f0
from .materials import Material, SurfaceMaterial
from .vectors import dot, normalize, take


@dataclass(frozen=True)
class SurfaceArrays:
    """Per-sphere lobes in the render precision: (3, N) colours, (N,) scalars.

    physical: SurfaceMaterial (True) or the article's Material.  layer, layer_f0: the
    specular layer over the diffuse lobe; dielectric, specular_ior: the share of the glossy
    lobe's Fresnel that follows a dielectric's curve (``SurfaceMaterial``'s
    specular_dielectric, specular_ior).  alpha: the GGX lobe's
    roughness^2 (physical); lobe_norm, exponent: the article's highlight, 1 / pi and
    shininess / 4.  mirror: traces a
    mirror ray weighted by F(N.V).  glossy_environment: reflects F(N.V) x the world instead.
    reflection: the article's mirror weight (0 for physical).  holdout: the Holdout shader's
    weight; holdout_object: the object is a holdout (``SurfaceMaterial``).  any_*: whether any
    sphere needs that work at all.
    """

    physical: np.ndarray
    diffuse: np.ndarray
    layer: np.ndarray
    layer_f0: np.ndarray
    f0: np.ndarray
    dielectric: np.ndarray
    specular_ior: np.ndarray
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
    translucency: np.ndarray
    holdout: np.ndarray
    holdout_object: np.ndarray
    any_physical: bool
    any_layer: bool
    any_dielectric: bool
    any_emission: bool
    any_through: bool
    any_holdout: bool


def surface_arrays(materials, dtype) -> SurfaceArrays:
    """SurfaceArrays for a sequence of Material / SurfaceMaterial (one per sphere)."""
    rows = {name: [] for name in ("physical", "diffuse", "layer", "layer_f0", "f0", "f90",
                                  "dielectric", "specular_ior", "lobe_norm", "exponent",
                                  "alpha",
                                  "emission", "mirror", "glossy_environment", "reflection",
                                  "transmission", "transmission_fresnel", "ior",
                                  "transparency", "translucency", "holdout",
                                  "holdout_object")}
    black = (0.0, 0.0, 0.0)
    for material in materials:
        if isinstance(material, SurfaceMaterial):
            mirror = material.roughness <= SurfaceMaterial.MIRROR_ROUGHNESS
            values = dict(physical=True, diffuse=material.diffuse, layer=material.layer,
                          layer_f0=material.layer_f0, f0=material.specular_f0,
                          dielectric=material.specular_dielectric,
                          specular_ior=material.specular_ior,
                          f90=material.specular_f90, lobe_norm=0.0, exponent=0.0,
                          alpha=max(material.roughness ** 2, MIN_ALPHA),
                          emission=material.emission, mirror=mirror,
                          glossy_environment=not mirror, reflection=0.0,
                          transmission=material.transmission,
                          transmission_fresnel=material.transmission_fresnel,
                          ior=material.ior, transparency=material.transparency,
                          translucency=material.translucency, holdout=material.holdout,
                          holdout_object=material.holdout_object)
        else:
            assert isinstance(material, Material)
            values = dict(physical=False, diffuse=material.diffuse, layer=0.0, layer_f0=0.0,
                          f0=material.specular, dielectric=0.0, specular_ior=1.5,
                          f90=material.specular, lobe_norm=1 / np.pi,
                          exponent=material.shininess / 4, alpha=1.0, emission=black,
                          mirror=False,
                          glossy_environment=False, reflection=material.reflection,
                          transmission=black, transmission_fresnel=0.0, ior=1.0,
                          transparency=black, translucency=black, holdout=0.0,
                          holdout_object=False)
        for name, value in values.items():
            rows[name].append(value)
    arrays = {}
    for name, values in rows.items():
        if name in ("physical", "mirror", "glossy_environment", "holdout_object"):
            arrays[name] = np.asarray(values, bool).reshape(-1)
        elif name in ("diffuse", "f0", "f90", "emission", "transmission", "transparency",
                      "translucency"):
            arrays[name] = np.ascontiguousarray(np.asarray(values, np.float64).reshape(-1, 3).T,
                                                dtype)
        else:
            arrays[name] = np.asarray(values, np.float64).reshape(-1).astype(dtype)
    return SurfaceArrays(
        **arrays, any_physical=bool(arrays["physical"].any()),
        any_layer=bool((arrays["layer"] * arrays["layer_f0"]).any()),
        any_dielectric=bool(arrays["dielectric"].any()),
        any_emission=bool(arrays["emission"].any()),
        any_through=bool(arrays["transmission"].any() or arrays["transparency"].any()),
        any_holdout=bool(arrays["holdout"].any() or arrays["holdout_object"].any()))


def held_share(holdout, whole, transparency, weight):
    """(k,) how much of each camera-path sample (weights (3, k)) holdouts take, as Cycles
    does: a Holdout shader of weight h takes h x the mean of the weight's channels; an object
    holdout (``whole``) all of it but its transparency (3, k), through which the ray goes on."""
    held = holdout * weight.mean(axis=0)
    if whole.any():
        held = np.where(whole, ((1 - transparency) * weight).mean(axis=0), held)
    return held


def translucent_view(surfaces: SurfaceArrays):
    """The lobes the light arriving through a surface meets (Translucent BSDF: a Lambertian
    lobe of colour ``translucency`` on the back side, nothing else), for shading the back
    hemisphere with the front's code (``core.shading``); None when no surface is translucent."""
    if not surfaces.translucency.any():
        return None
    black = np.zeros_like(surfaces.diffuse)
    return dataclasses.replace(
        surfaces, diffuse=surfaces.translucency, layer=np.zeros_like(surfaces.layer),
        f0=black, f90=black, emission=black,
        dielectric=np.zeros_like(surfaces.dielectric),
        glossy_environment=np.zeros_like(surfaces.glossy_environment), any_layer=False,
        any_dielectric=False, any_emission=False)


def schlick(f0, f90, cosine):
    """Schlick's Fresnel (3, m) for lobes f0, f90 (3, m) and cosines (m,)."""
    return f0 + (f90 - f0) * _schlick_rise(cosine)


def _schlick_rise(cosine):
    c = np.clip(1 - cosine, 0, 1)
    c2 = c * c
    return c2 * c2 * c


def dielectric_rise(cosine, ior):
    """(F(c) - F(1)) / (1 - F(1)) (m,): how far the exact unpolarised Fresnel reflectance F of
    a dielectric of index ``ior`` >= 1 seen from outside has risen from normal incidence
    towards 1 at cosines c, the curve Cycles' Principled BSDF gives its specular layer
    (generalized Schlick with exponent -ior).  At IOR 1.5 it lies above Schlick's (1 - c)^5
    for c > 0.35 (0.051 against 0.031 at c = 0.5), below it under grazing light."""
    c = np.clip(cosine, 0, 1)
    eta = np.maximum(ior, 1.0)
    cos_t = np.sqrt(np.maximum(1 - (1 - c * c) / (eta * eta), 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (c - eta * cos_t) / (c + eta * cos_t)
        p = (eta * c - cos_t) / (eta * c + cos_t)
    reflectance = np.nan_to_num(0.5 * (s * s + p * p), nan=1.0)
    f0 = ((eta - 1) / (eta + 1)) ** 2
    return np.clip((reflectance - f0) / np.maximum(1 - f0, 1e-9), 0, 1)


def fresnel(surfaces: SurfaceArrays, spheres, f0, f90, cosine):
    """(3, m) the glossy lobes' F = f0 + (f90 - f0) w(c) at cosines (m,): w Schlick's
    (1 - c)^5 blended towards ``dielectric_rise`` by each surface's dielectric share."""
    rise = _schlick_rise(cosine)
    if surfaces.any_dielectric:
        share = surfaces.dielectric[spheres]
        curved = np.flatnonzero(share > 0)
        if len(curved):
            exact = dielectric_rise(cosine[curved], surfaces.specular_ior[spheres[curved]])
            rise = rise.copy()
            rise[curved] += share[curved] * (exact - rise[curved])
    return f0 + (f90 - f0) * rise


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


def directional_albedo_quadrature(rise=None) -> np.ndarray:
    """(alphas, cosines) table of E(mu, alpha), the lobe's reflectance with F = 1, or with a
    Fresnel rise w(V.H) from 0 to 1 (``_schlick_rise``: ``_SCHLICK_TABLE``; a dielectric's
    ``dielectric_rise``: ``dielectric_table``) of the share weighted by w.

    Half vectors are drawn from D(h) (N.H) on a stratified 96 x 32 grid (tan^2 theta_h =
    alpha^2 u / (1 - u)), which resolves sharp and wide lobes alike; each contributes
    Vis 4 (V.H) (N.L) / (N.H), the estimator of the integral of D Vis cos(theta_l).  The
    view lies in the x-z plane, so the grid's azimuths pair up as phi and 2 pi - phi with
    equal contributions: the half of them below pi give the same mean at half the cost."""
    u = (np.arange(96) + 0.5) / 96
    phi = (np.arange(16) + 0.5) / 32 * 2 * np.pi
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
        * np.maximum(cos_l, 0) / cos_h * (1 if rise is None else rise(v_dot_h)), 0)
    return np.minimum(contribution.mean(axis=(2, 3)), 1.0)


#: E(mu, alpha) (``directional_albedo_quadrature``, rounded to 5 digits; a test recomputes it),
#: rows alpha = 0, 0.05, .., 1, columns mu = 0.02, 0.0608, .., 1.
_ALBEDO_TABLE = np.array([
    [0.99772, 0.99986, 0.99995, 0.99998, 0.99999, 0.99999, 0.99999, 1.00000, 1.00000,
     1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000,
     1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000, 1.00000],
    [0.90363, 0.87731, 0.90496, 0.93343, 0.95327, 0.96623, 0.97470, 0.98076, 0.98485,
     0.98751, 0.98991, 0.99146, 0.99262, 0.99368, 0.99449, 0.99517, 0.99585, 0.99662,
     0.99681, 0.99707, 0.99729, 0.99762, 0.99814, 0.99969, 0.99993],
    [0.92849, 0.88517, 0.87335, 0.88024, 0.89460, 0.91029, 0.92457, 0.93672, 0.94680,
     0.95497, 0.96171, 0.96702, 0.97143, 0.97499, 0.97793, 0.98018, 0.98189, 0.98373,
     0.98507, 0.98603, 0.98687, 0.98715, 0.98704, 0.98602, 0.98873],
    [0.93816, 0.90003, 0.87777, 0.86922, 0.87032, 0.87695, 0.88627, 0.89640, 0.90624,
     0.91593, 0.92455, 0.93197, 0.93816, 0.94399, 0.94871, 0.95247, 0.95569, 0.95795,
     0.95951, 0.96178, 0.96462, 0.96719, 0.96944, 0.97075, 0.97315],
    [0.94272, 0.90885, 0.88469, 0.86963, 0.86185, 0.85965, 0.86191, 0.86671, 0.87266,
     0.87938, 0.88629, 0.89255, 0.89878, 0.90409, 0.90883, 0.91355, 0.91937, 0.92475,
     0.92967, 0.93364, 0.93713, 0.93982, 0.94261, 0.94547, 0.94741],
    [0.94483, 0.91301, 0.88847, 0.86975, 0.85651, 0.84874, 0.84443, 0.84306, 0.84378,
     0.84589, 0.84908, 0.85282, 0.85691, 0.86290, 0.86998, 0.87641, 0.88235, 0.88750,
     0.89214, 0.89643, 0.90133, 0.90538, 0.90896, 0.91253, 0.91560],
    [0.94551, 0.91429, 0.88848, 0.86701, 0.85060, 0.83754, 0.82819, 0.82132, 0.81741,
     0.81504, 0.81449, 0.81747, 0.82225, 0.82697, 0.83191, 0.83671, 0.84118, 0.84583,
     0.85134, 0.85615, 0.86044, 0.86523, 0.86936, 0.87347, 0.87753],
    [0.94528, 0.91324, 0.88555, 0.86184, 0.84176, 0.82497, 0.81109, 0.80048, 0.79224,
     0.78738, 0.78707, 0.78776, 0.78936, 0.79130, 0.79347, 0.79647, 0.80058, 0.80447,
     0.80847, 0.81283, 0.81700, 0.82132, 0.82557, 0.82969, 0.83350],
    [0.94440, 0.91045, 0.88019, 0.85406, 0.83058, 0.81051, 0.79356, 0.77952, 0.76968,
     0.76499, 0.76143, 0.75891, 0.75711, 0.75637, 0.75706, 0.75861, 0.76040, 0.76279,
     0.76564, 0.76876, 0.77197, 0.77558, 0.77916, 0.78285, 0.78659],
    [0.94307, 0.90643, 0.87338, 0.84409, 0.81790, 0.79492, 0.77514, 0.75976, 0.75035,
     0.74268, 0.73588, 0.73019, 0.72612, 0.72377, 0.72224, 0.72123, 0.72153, 0.72200,
     0.72328, 0.72493, 0.72689, 0.72921, 0.73179, 0.73456, 0.73751],
    [0.94140, 0.90156, 0.86551, 0.83269, 0.80356, 0.77796, 0.75681, 0.74221, 0.73047,
     0.71972, 0.71027, 0.70259, 0.69699, 0.69225, 0.68837, 0.68574, 0.68379, 0.68265,
     0.68203, 0.68199, 0.68244, 0.68332, 0.68455, 0.68608, 0.68788],
    [0.93948, 0.89596, 0.85657, 0.82064, 0.78877, 0.76087, 0.73984, 0.72413, 0.70967,
     0.69654, 0.68525, 0.67631, 0.66833, 0.66159, 0.65604, 0.65133, 0.64762, 0.64463,
     0.64225, 0.64054, 0.63938, 0.63866, 0.63839, 0.63847, 0.63891],
    [0.93736, 0.88985, 0.84681, 0.80778, 0.77305, 0.74409, 0.72327, 0.70539, 0.68853,
     0.67351, 0.66120, 0.65012, 0.64038, 0.63202, 0.62465, 0.61831, 0.61287, 0.60817,
     0.60417, 0.60082, 0.59799, 0.59575, 0.59393, 0.59253, 0.59148],
    [0.93509, 0.88332, 0.83639, 0.79418, 0.75735, 0.72827, 0.70648, 0.68596, 0.66730,
     0.65116, 0.63717, 0.62441, 0.61332, 0.60330, 0.59447, 0.58662, 0.57957, 0.57332,
     0.56779, 0.56288, 0.55862, 0.55484, 0.55160, 0.54874, 0.54626],
    [0.93269, 0.87648, 0.82579, 0.78074, 0.74168, 0.71298, 0.68898, 0.66638, 0.64622,
     0.62931, 0.61338, 0.59953, 0.58692, 0.57566, 0.56540, 0.55610, 0.54770, 0.54010,
     0.53322, 0.52696, 0.52132, 0.51623, 0.51161, 0.50747, 0.50368],
    [0.93028, 0.86975, 0.81517, 0.76696, 0.72650, 0.69766, 0.67121, 0.64700, 0.62615,
     0.60730, 0.59041, 0.57516, 0.56144, 0.54881, 0.53733, 0.52688, 0.51730, 0.50855,
     0.50045, 0.49305, 0.48622, 0.47994, 0.47416, 0.46883, 0.46388],
    [0.92783, 0.86280, 0.80440, 0.75306, 0.71258, 0.68207, 0.65343, 0.62773, 0.60600,
     0.58580, 0.56790, 0.55144, 0.53654, 0.52298, 0.51048, 0.49901, 0.48839, 0.47862,
     0.46952, 0.46111, 0.45329, 0.44600, 0.43923, 0.43290, 0.42696],
    [0.92532, 0.85570, 0.79338, 0.73952, 0.69897, 0.66615, 0.63590, 0.60959, 0.58606,
     0.56501, 0.54588, 0.52858, 0.51276, 0.49819, 0.48479, 0.47240, 0.46095, 0.45028,
     0.44037, 0.43112, 0.42247, 0.41438, 0.40679, 0.39966, 0.39295],
    [0.92275, 0.84847, 0.78215, 0.72619, 0.68552, 0.65044, 0.61852, 0.59147, 0.56662,
     0.54468, 0.52467, 0.50639, 0.48971, 0.47436, 0.46024, 0.44707, 0.43493, 0.42358,
     0.41298, 0.40306, 0.39374, 0.38500, 0.37677, 0.36900, 0.36169],
    [0.92015, 0.84113, 0.77136, 0.71343, 0.67212, 0.63481, 0.60185, 0.57349, 0.54791,
     0.52482, 0.50398, 0.48501, 0.46760, 0.45156, 0.43679, 0.42306, 0.41028, 0.39839,
     0.38726, 0.37681, 0.36700, 0.35777, 0.34905, 0.34082, 0.33300],
    [0.91751, 0.83373, 0.76061, 0.70119, 0.65858, 0.61951, 0.58591, 0.55597, 0.52962,
     0.50578, 0.48415, 0.46446, 0.44645, 0.42979, 0.41450, 0.40027, 0.38703, 0.37469,
     0.36315, 0.35232, 0.34214, 0.33255, 0.32351, 0.31495, 0.30687],
])


#: The Schlick-weighted share E5(mu, alpha) of E (``directional_albedo_quadrature`` with
#: ``_schlick_rise``, same grid and rounding): a lobe with Schlick's F from f0 to f90 reflects
#: f0 E + (f90 - f0) E5.
_SCHLICK_TABLE = np.array([
    [0.90119, 0.73041, 0.58495, 0.46358, 0.36324, 0.28108, 0.21450, 0.16118, 0.11904, 0.08621,
     0.06106, 0.04215, 0.02825, 0.01828, 0.01135, 0.00670, 0.00372, 0.00191, 0.00088, 0.00035,
     0.00012, 0.00003, 0.00000, 0.00000, 0.00000],
    [0.52738, 0.47823, 0.43025, 0.37107, 0.30809, 0.24849, 0.19571, 0.15104, 0.11413, 0.08436,
     0.06108, 0.04307, 0.02953, 0.01963, 0.01257, 0.00771, 0.00449, 0.00248, 0.00125, 0.00057,
     0.00023, 0.00008, 0.00003, 0.00002, 0.00000],
    [0.37505, 0.33566, 0.29951, 0.26370, 0.22729, 0.19124, 0.15703, 0.12594, 0.09875, 0.07568,
     0.05670, 0.04143, 0.02951, 0.02041, 0.01368, 0.00883, 0.00546, 0.00323, 0.00180, 0.00094,
     0.00046, 0.00020, 0.00008, 0.00003, 0.00001],
    [0.28332, 0.25209, 0.22318, 0.19595, 0.17000, 0.14518, 0.12178, 0.10018, 0.08073, 0.06376,
     0.04926, 0.03719, 0.02740, 0.01966, 0.01370, 0.00926, 0.00602, 0.00376, 0.00224, 0.00127,
     0.00067, 0.00033, 0.00014, 0.00005, 0.00002],
    [0.22324, 0.19708, 0.17348, 0.15174, 0.13146, 0.11261, 0.09526, 0.07938, 0.06507, 0.05239,
     0.04139, 0.03204, 0.02426, 0.01793, 0.01292, 0.00904, 0.00612, 0.00399, 0.00250, 0.00149,
     0.00083, 0.00043, 0.00020, 0.00008, 0.00002],
    [0.18151, 0.15878, 0.13904, 0.12099, 0.10452, 0.08959, 0.07600, 0.06370, 0.05267, 0.04292,
     0.03442, 0.02711, 0.02094, 0.01583, 0.01169, 0.00841, 0.00587, 0.00396, 0.00257, 0.00159,
     0.00093, 0.00051, 0.00025, 0.00010, 0.00003],
    [0.15127, 0.13120, 0.11405, 0.09874, 0.08511, 0.07280, 0.06177, 0.05189, 0.04314, 0.03540,
     0.02864, 0.02283, 0.01788, 0.01374, 0.01034, 0.00760, 0.00543, 0.00376, 0.00252, 0.00161,
     0.00097, 0.00055, 0.00028, 0.00012, 0.00003],
    [0.12863, 0.11059, 0.09543, 0.08222, 0.07059, 0.06023, 0.05106, 0.04293, 0.03575, 0.02946,
     0.02398, 0.01926, 0.01524, 0.01185, 0.00904, 0.00675, 0.00491, 0.00347, 0.00238, 0.00156,
     0.00097, 0.00056, 0.00030, 0.00013, 0.00004],
    [0.11123, 0.09474, 0.08112, 0.06959, 0.05947, 0.05062, 0.04283, 0.03599, 0.02999, 0.02477,
     0.02023, 0.01633, 0.01301, 0.01020, 0.00786, 0.00594, 0.00439, 0.00315, 0.00219, 0.00147,
     0.00093, 0.00056, 0.00030, 0.00014, 0.00004],
    [0.09757, 0.08230, 0.06996, 0.05968, 0.05080, 0.04310, 0.03638, 0.03053, 0.02544, 0.02102,
     0.01721, 0.01394, 0.01115, 0.00880, 0.00683, 0.00521, 0.00389, 0.00283, 0.00200, 0.00136,
     0.00088, 0.00054, 0.00030, 0.00014, 0.00005],
    [0.08665, 0.07240, 0.06111, 0.05179, 0.04391, 0.03712, 0.03125, 0.02617, 0.02179, 0.01800,
     0.01475, 0.01197, 0.00961, 0.00761, 0.00594, 0.00456, 0.00343, 0.00252, 0.00180, 0.00124,
     0.00082, 0.00051, 0.00029, 0.00014, 0.00005],
    [0.07778, 0.06433, 0.05392, 0.04542, 0.03833, 0.03228, 0.02710, 0.02265, 0.01882, 0.01555,
     0.01274, 0.01035, 0.00832, 0.00661, 0.00519, 0.00400, 0.00303, 0.00224, 0.00162, 0.00113,
     0.00075, 0.00047, 0.00027, 0.00014, 0.00005],
    [0.07047, 0.05769, 0.04801, 0.04022, 0.03377, 0.02833, 0.02370, 0.01976, 0.01639, 0.01352,
     0.01108, 0.00900, 0.00725, 0.00577, 0.00454, 0.00352, 0.00268, 0.00199, 0.00145, 0.00102,
     0.00069, 0.00044, 0.00026, 0.00013, 0.00005],
    [0.06437, 0.05214, 0.04306, 0.03588, 0.02998, 0.02505, 0.02089, 0.01737, 0.01438, 0.01184,
     0.00969, 0.00788, 0.00634, 0.00506, 0.00398, 0.00310, 0.00237, 0.00177, 0.00130, 0.00092,
     0.00063, 0.00040, 0.00024, 0.00012, 0.00005],
    [0.05922, 0.04745, 0.03890, 0.03223, 0.02680, 0.02230, 0.01853, 0.01536, 0.01269, 0.01044,
     0.00853, 0.00693, 0.00558, 0.00445, 0.00351, 0.00274, 0.00210, 0.00158, 0.00116, 0.00083,
     0.00057, 0.00037, 0.00022, 0.00012, 0.00005],
    [0.05488, 0.04351, 0.03538, 0.02915, 0.02411, 0.01998, 0.01655, 0.01368, 0.01127, 0.00925,
     0.00755, 0.00613, 0.00493, 0.00394, 0.00311, 0.00242, 0.00186, 0.00141, 0.00104, 0.00074,
     0.00051, 0.00034, 0.00020, 0.00011, 0.00004],
    [0.05118, 0.04012, 0.03237, 0.02650, 0.02181, 0.01800, 0.01485, 0.01223, 0.01006, 0.00824,
     0.00671, 0.00544, 0.00438, 0.00350, 0.00276, 0.00216, 0.00166, 0.00126, 0.00093, 0.00067,
     0.00046, 0.00031, 0.00019, 0.00010, 0.00004],
    [0.04797, 0.03718, 0.02977, 0.02421, 0.01983, 0.01629, 0.01339, 0.01100, 0.00902, 0.00737,
     0.00600, 0.00486, 0.00391, 0.00311, 0.00246, 0.00192, 0.00148, 0.00112, 0.00083, 0.00060,
     0.00042, 0.00028, 0.00017, 0.00009, 0.00004],
    [0.04518, 0.03461, 0.02749, 0.02222, 0.01811, 0.01481, 0.01213, 0.00994, 0.00812, 0.00662,
     0.00538, 0.00435, 0.00349, 0.00279, 0.00220, 0.00172, 0.00133, 0.00101, 0.00075, 0.00054,
     0.00038, 0.00025, 0.00016, 0.00009, 0.00004],
    [0.04272, 0.03234, 0.02549, 0.02048, 0.01661, 0.01352, 0.01104, 0.00901, 0.00735, 0.00598,
     0.00485, 0.00391, 0.00314, 0.00250, 0.00198, 0.00155, 0.00119, 0.00091, 0.00068, 0.00049,
     0.00035, 0.00023, 0.00015, 0.00008, 0.00004],
    [0.04055, 0.03034, 0.02373, 0.01894, 0.01529, 0.01240, 0.01008, 0.00820, 0.00667, 0.00541,
     0.00438, 0.00353, 0.00283, 0.00225, 0.00178, 0.00139, 0.00107, 0.00082, 0.00061, 0.00044,
     0.00031, 0.00021, 0.00013, 0.00008, 0.00003],
])

#: The same for the curve of a dielectric of IOR 1.5 (``dielectric_rise``), Blender's default
#: IOR; other indices are integrated when first used (``dielectric_table``).
_DIELECTRIC_TABLE_1_5 = np.array([
    [0.88379, 0.69572, 0.54833, 0.43316, 0.34259, 0.27098, 0.21414, 0.16889, 0.13279, 0.10397,
     0.08095, 0.06259, 0.04796, 0.03635, 0.02717, 0.01995, 0.01433, 0.01000, 0.00671, 0.00427,
     0.00250, 0.00130, 0.00053, 0.00012, 0.00000],
    [0.50522, 0.45357, 0.40564, 0.35034, 0.29403, 0.24222, 0.19706, 0.15897, 0.12720, 0.10095,
     0.07964, 0.06223, 0.04815, 0.03686, 0.02782, 0.02064, 0.01500, 0.01063, 0.00724, 0.00469,
     0.00284, 0.00155, 0.00071, 0.00025, 0.00004],
    [0.36010, 0.32097, 0.28645, 0.25372, 0.22159, 0.19048, 0.16126, 0.13469, 0.11116, 0.09074,
     0.07331, 0.05858, 0.04629, 0.03613, 0.02781, 0.02104, 0.01559, 0.01129, 0.00791, 0.00531,
     0.00338, 0.00196, 0.00101, 0.00040, 0.00011],
    [0.27493, 0.24471, 0.21761, 0.19288, 0.16995, 0.14842, 0.12827, 0.10963, 0.09263, 0.07746,
     0.06404, 0.05233, 0.04225, 0.03369, 0.02648, 0.02048, 0.01553, 0.01152, 0.00830, 0.00577,
     0.00381, 0.00236, 0.00131, 0.00062, 0.00023],
    [0.21959, 0.19464, 0.17269, 0.15293, 0.13484, 0.11825, 0.10307, 0.08914, 0.07641, 0.06489,
     0.05455, 0.04539, 0.03733, 0.03033, 0.02431, 0.01919, 0.01487, 0.01128, 0.00834, 0.00597,
     0.00409, 0.00264, 0.00157, 0.00081, 0.00032],
    [0.18115, 0.15961, 0.14127, 0.12476, 0.10990, 0.09654, 0.08441, 0.07338, 0.06337, 0.05433,
     0.04620, 0.03893, 0.03246, 0.02676, 0.02179, 0.01749, 0.01380, 0.01068, 0.00807, 0.00592,
     0.00418, 0.00280, 0.00175, 0.00097, 0.00043],
    [0.15317, 0.13417, 0.11817, 0.10405, 0.09159, 0.08038, 0.07033, 0.06128, 0.05316, 0.04582,
     0.03922, 0.03332, 0.02806, 0.02338, 0.01927, 0.01568, 0.01256, 0.00988, 0.00761, 0.00570,
     0.00412, 0.00285, 0.00185, 0.00108, 0.00053],
    [0.13208, 0.11495, 0.10072, 0.08841, 0.07762, 0.06803, 0.05951, 0.05190, 0.04508, 0.03898,
     0.03351, 0.02862, 0.02425, 0.02037, 0.01694, 0.01392, 0.01129, 0.00900, 0.00703, 0.00536,
     0.00396, 0.00281, 0.00188, 0.00115, 0.00059],
    [0.11575, 0.10001, 0.08710, 0.07623, 0.06670, 0.05838, 0.05101, 0.04447, 0.03865, 0.03347,
     0.02883, 0.02471, 0.02103, 0.01777, 0.01487, 0.01232, 0.01008, 0.00812, 0.00643, 0.00497,
     0.00374, 0.00271, 0.00186, 0.00118, 0.00064],
    [0.10280, 0.08813, 0.07633, 0.06651, 0.05804, 0.05068, 0.04421, 0.03850, 0.03345, 0.02898,
     0.02500, 0.02146, 0.01832, 0.01553, 0.01307, 0.01089, 0.00897, 0.00729, 0.00582, 0.00456,
     0.00348, 0.00256, 0.00180, 0.00117, 0.00068],
    [0.09236, 0.07856, 0.06766, 0.05865, 0.05103, 0.04443, 0.03868, 0.03364, 0.02920, 0.02528,
     0.02182, 0.01875, 0.01604, 0.01363, 0.01150, 0.00963, 0.00797, 0.00652, 0.00526, 0.00416,
     0.00321, 0.00240, 0.00172, 0.00115, 0.00069],
    [0.08379, 0.07068, 0.06052, 0.05220, 0.04525, 0.03928, 0.03413, 0.02962, 0.02568, 0.02222,
     0.01917, 0.01648, 0.01411, 0.01201, 0.01016, 0.00853, 0.00709, 0.00583, 0.00473, 0.00377,
     0.00294, 0.00223, 0.00162, 0.00111, 0.00069],
    [0.07667, 0.06411, 0.05456, 0.04685, 0.04045, 0.03501, 0.03033, 0.02627, 0.02274, 0.01965,
     0.01694, 0.01456, 0.01247, 0.01063, 0.00900, 0.00758, 0.00632, 0.00522, 0.00425, 0.00341,
     0.00268, 0.00206, 0.00152, 0.00106, 0.00068],
    [0.07067, 0.05857, 0.04952, 0.04234, 0.03640, 0.03141, 0.02713, 0.02344, 0.02025, 0.01748,
     0.01505, 0.01293, 0.01107, 0.00944, 0.00801, 0.00675, 0.00564, 0.00467, 0.00383, 0.00309,
     0.00244, 0.00189, 0.00141, 0.00100, 0.00066],
    [0.06557, 0.05383, 0.04523, 0.03849, 0.03297, 0.02833, 0.02441, 0.02104, 0.01814, 0.01563,
     0.01344, 0.01154, 0.00988, 0.00842, 0.00715, 0.00603, 0.00505, 0.00419, 0.00345, 0.00279,
     0.00222, 0.00173, 0.00131, 0.00094, 0.00063],
    [0.06123, 0.04982, 0.04155, 0.03520, 0.03001, 0.02571, 0.02208, 0.01898, 0.01633, 0.01404,
     0.01206, 0.01034, 0.00884, 0.00754, 0.00640, 0.00540, 0.00453, 0.00377, 0.00311, 0.00253,
     0.00202, 0.00158, 0.00121, 0.00088, 0.00060],
    [0.05749, 0.04632, 0.03839, 0.03234, 0.02746, 0.02344, 0.02006, 0.01720, 0.01476, 0.01267,
     0.01086, 0.00930, 0.00795, 0.00677, 0.00575, 0.00485, 0.00408, 0.00340, 0.00280, 0.00229,
     0.00184, 0.00145, 0.00111, 0.00082, 0.00057],
    [0.05423, 0.04327, 0.03561, 0.02983, 0.02522, 0.02145, 0.01830, 0.01565, 0.01340, 0.01147,
     0.00982, 0.00840, 0.00717, 0.00610, 0.00518, 0.00437, 0.00367, 0.00307, 0.00254, 0.00207,
     0.00167, 0.00132, 0.00102, 0.00076, 0.00054],
    [0.05137, 0.04057, 0.03316, 0.02764, 0.02327, 0.01971, 0.01676, 0.01429, 0.01220, 0.01043,
     0.00891, 0.00761, 0.00649, 0.00552, 0.00468, 0.00395, 0.00332, 0.00277, 0.00230, 0.00188,
     0.00152, 0.00121, 0.00094, 0.00071, 0.00051],
    [0.04884, 0.03817, 0.03099, 0.02570, 0.02155, 0.01817, 0.01541, 0.01310, 0.01116, 0.00951,
     0.00811, 0.00692, 0.00589, 0.00501, 0.00424, 0.00358, 0.00301, 0.00252, 0.00209, 0.00171,
     0.00139, 0.00111, 0.00087, 0.00066, 0.00048],
    [0.04659, 0.03604, 0.02907, 0.02398, 0.02001, 0.01682, 0.01421, 0.01204, 0.01023, 0.00871,
     0.00741, 0.00631, 0.00537, 0.00455, 0.00386, 0.00326, 0.00274, 0.00229, 0.00190, 0.00156,
     0.00127, 0.00102, 0.00080, 0.00061, 0.00045],
])


@functools.lru_cache(maxsize=16)
def _integrated_dielectric_table(ior: float) -> np.ndarray:
    return directional_albedo_quadrature(lambda c: dielectric_rise(c, ior))


def dielectric_table(ior: float) -> np.ndarray:
    """The share table of ``dielectric_rise`` at ``ior`` (rounded to 0.001): the tabulated
    one at 1.5, else integrated once per process (0.66 s measured at load 6)."""
    ior = round(max(float(ior), 1.0), 3)
    return _DIELECTRIC_TABLE_1_5 if ior == 1.5 else _integrated_dielectric_table(ior)


def directional_albedo(cos_v, alpha, table=_ALBEDO_TABLE):
    """E(N.V, alpha) (m,) of the GGX lobe (or another table on its grid), bilinear in the
    precomputed table."""
    # Both grids are uniform: the cells' indices by arithmetic, one flat gather per corner
    # (np.interp twice and four 2-D gathers cost 3x as much per point).
    columns, rows = len(_ALBEDO_COSINES), len(_ALBEDO_ALPHAS)
    low, step = _ALBEDO_COSINES[0], _ALBEDO_COSINES[1] - _ALBEDO_COSINES[0]
    x = np.clip((np.asarray(cos_v, np.float64) - low) / step, 0, columns - 1)
    y = np.clip(np.asarray(alpha, np.float64) * (rows - 1), 0, rows - 1)
    x0 = np.minimum(x.astype(np.intp), columns - 2)
    y0 = np.minimum(y.astype(np.intp), rows - 2)
    fx, fy = x - x0, y - y0
    flat = table.ravel()
    corner = y0 * columns + x0
    top = flat.take(corner) * (1 - fx) + flat.take(corner + 1) * fx
    bottom = flat.take(corner + columns) * (1 - fx) + flat.take(corner + columns + 1) * fx
    return (top * (1 - fy) + bottom * fy).astype(np.asarray(cos_v).dtype)


def _compensation(f0, albedo):
    """Turquin's multiple-scattering factor 1 + f0 (1 / E - 1) (module docstring)."""
    return 1 + f0 * (1 / albedo - 1)


def glossy_albedo(f0, f90, cos_v, alpha, dielectric=None, ior=None):
    """(3, m) the share of light from a constant environment the GGX lobe reflects towards V:
    the integral of its ``light_response`` over the hemisphere, (1 + f0 (1 / E - 1))
    (f0 E + (f90 - f0) S) for lobes f0, f90 (3, m), cosines N.V and alphas (m,), S the share
    table of its Fresnel curve: Schlick's, blended by ``dielectric`` (m,) towards that of a
    dielectric of index ``ior`` (m,).  At a grazing angle it stays well below Schlick's
    F(N.V) (0.19 against 0.75 at N.V = 0.06 for Blender's default surface): the microfacets
    that reflect V into the sky face it far more squarely than the mean surface does."""
    albedo = directional_albedo(cos_v, alpha)
    share = directional_albedo(cos_v, alpha, _SCHLICK_TABLE)
    if dielectric is not None and np.any(dielectric > 0):
        share = share.copy()
        for index in np.unique(ior[dielectric > 0]):
            chosen = np.flatnonzero((ior == index) & (dielectric > 0))
            exact = directional_albedo(cos_v[chosen], alpha[chosen], dielectric_table(index))
            share[chosen] += dielectric[chosen] * (exact - share[chosen])
    return _compensation(f0, albedo) * (f0 * albedo + (f90 - f0) * share)


def diffuse_seen(surfaces: SurfaceArrays, spheres, cos_v):
    """(3, m) the diffuse albedo seen from V: ``diffuse``, its layered share (``layer`` of
    it, under a specular layer of f0 ``layer_f0`` and f90 1) scaled from base (1 - f0) to base
    (1 - A(N.V)), A that layer's ``glossy_albedo`` with a dielectric's Fresnel
    (``SurfaceMaterial``'s docstring)."""
    diffuse = take(surfaces.diffuse, spheres)
    if not surfaces.any_layer:
        return diffuse
    layer, f0 = surfaces.layer[spheres], surfaces.layer_f0[spheres]
    layered = np.flatnonzero((layer > 0) & (f0 > 0))
    if len(layered) == 0:
        return diffuse
    f0 = f0[layered]
    # Cycles' layer is a dielectric whose index gives its f0 (``ior_from_F0``).
    albedo = glossy_albedo(f0, np.ones_like(f0), np.clip(cos_v[layered], 0, 1),
                           surfaces.alpha[spheres[layered]], np.ones_like(f0), ior_from_f0(f0))
    loss = layer[layered] * (albedo - f0) / np.maximum(1 - f0, 1e-6)
    diffuse = diffuse.copy()
    diffuse[:, layered] *= np.clip(1 - loss, 0, None)
    return diffuse


def light_response(surfaces: SurfaceArrays, spheres, normals, to_view, towards, e):
    """Radiance (3, m) per unit light scale for irradiance e (m,) (cos(theta_i) included)
    from unit directions ``towards`` (3, m), seen from ``to_view`` (3, m) (module doc)."""
    half, _ = normalize(towards + to_view)
    cos_half = np.maximum(dot(normals, half), 0)
    f0, f90 = take(surfaces.f0, spheres), take(surfaces.f90, spheres)
    physical = surfaces.physical[spheres]
    reflectance = np.where(physical, fresnel(surfaces, spheres, f0, f90, dot(towards, half)), f0)
    alpha = surfaces.alpha[spheres]
    cos_l = np.maximum(dot(normals, towards), 1e-6)
    cos_v = np.maximum(dot(normals, to_view), 1e-6)
    # Multiple scattering between microfacets, which single-scattering GGX loses (Turquin
    # 2019): scale by 1 + f0 (1 / E(N.V) - 1), E the lobe's directional albedo.
    compensation = _compensation(f0, directional_albedo(cos_v, alpha))
    lobe = np.where(physical, ggx(cos_half, cos_l, cos_v, alpha),
                    surfaces.lobe_norm[spheres] * _power(cos_half, surfaces.exponent[spheres]))
    reflectance = np.where(physical, reflectance * compensation, reflectance)
    return e * (diffuse_seen(surfaces, spheres, cos_v) * (1 / np.pi) + reflectance * lobe)


def environment(surfaces: SurfaceArrays, spheres, normals, to_view, world):
    """Radiance (3, m) the physical surfaces reflect from a constant world (3, 1): emission,
    the rough glossy lobe's ``glossy_albedo`` x W, and what the specular layer takes from the
    diffuse lobe ((``diffuse_seen`` - diffuse) x W: the ambient term adds diffuse x W)."""
    colour = take(surfaces.emission, spheres) if surfaces.any_emission else 0
    if not world.any():
        return colour
    glossy = surfaces.glossy_environment[spheres]
    cos_v = None
    if glossy.any():
        cos_v = np.clip(dot(normals, to_view), 0, 1)
        reflected = glossy_albedo(take(surfaces.f0, spheres), take(surfaces.f90, spheres),
                                  cos_v, surfaces.alpha[spheres], surfaces.dielectric[spheres],
                                  surfaces.specular_ior[spheres])
        colour = colour + reflected * glossy * world
    if surfaces.any_layer:
        cos_v = np.clip(dot(normals, to_view), 0, 1) if cos_v is None else cos_v
        colour = colour + (diffuse_seen(surfaces, spheres, cos_v)
                           - take(surfaces.diffuse, spheres)) * world
    return colour


@dataclass
class Branch:
    """Secondary rays leaving some of m hit points: index (k,) into the points, unit
    directions (3, k), weights (3, k), whether each leaves through the surface, and whether
    it goes straight on (a Transparent BSDF: what a camera ray sees through it is still the
    camera's view, for holdouts and Film > Transparent)."""

    index: np.ndarray
    directions: np.ndarray
    weights: np.ndarray
    through: bool
    straight: bool = False


def scatter(surfaces: SurfaceArrays, normals, directions, cos_in, spheres, front) -> list:
    """Branches of secondary rays at m hits (default semantics; module docstring).

    normals face the incoming unit ``directions`` (3, m); cos_in = D.N (m,) <= 0; front:
    whether the outside was hit."""
    dtype = directions.dtype
    cos_v = -cos_in
    reflect_weight = np.broadcast_to(surfaces.reflection[spheres], directions.shape).copy()
    mirror = surfaces.mirror[spheres]
    if mirror.any():
        reflectance = fresnel(surfaces, spheres, take(surfaces.f0, spheres),
                              take(surfaces.f90, spheres), cos_v)
        reflect_weight += np.where(mirror, reflectance, 0)
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
                                   take(transparency, passing), True, straight=True))
    reflecting = np.flatnonzero(reflect_weight.max(axis=0) > 0)
    if len(reflecting):
        d, n = take(directions, reflecting), take(normals, reflecting)
        reflected = d - (2 * cos_in[reflecting]) * n
        branches.insert(0, Branch(reflecting, reflected.astype(dtype),
                                  take(reflect_weight, reflecting), False))
    return branches
