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

import dataclasses
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
    reflection: the article's mirror weight (0 for physical).  holdout: the Holdout shader's
    weight; holdout_object: the object is a holdout (``SurfaceMaterial``).  any_*: whether any
    sphere needs that work at all.
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
    translucency: np.ndarray
    holdout: np.ndarray
    holdout_object: np.ndarray
    any_physical: bool
    any_emission: bool
    any_through: bool
    any_holdout: bool


def surface_arrays(materials, dtype) -> SurfaceArrays:
    """SurfaceArrays for a sequence of Material / SurfaceMaterial (one per sphere)."""
    rows = {name: [] for name in ("physical", "diffuse", "f0", "f90", "lobe_norm", "exponent",
                                  "alpha",
                                  "emission", "mirror", "glossy_environment", "reflection",
                                  "transmission", "transmission_fresnel", "ior",
                                  "transparency", "translucency", "holdout",
                                  "holdout_object")}
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
                          ior=material.ior, transparency=material.transparency,
                          translucency=material.translucency, holdout=material.holdout,
                          holdout_object=material.holdout_object)
        else:
            assert isinstance(material, Material)
            values = dict(physical=False, diffuse=material.diffuse, f0=material.specular,
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
        any_emission=bool(arrays["emission"].any()),
        any_through=bool(arrays["transmission"].any() or arrays["transparency"].any()),
        any_holdout=bool(arrays["holdout"].any() or arrays["holdout_object"].any()))


def translucent_view(surfaces: SurfaceArrays):
    """The lobes the light arriving through a surface meets (Translucent BSDF: a Lambertian
    lobe of colour ``translucency`` on the back side, nothing else), for shading the back
    hemisphere with the front's code (``core.shading``); None when no surface is translucent."""
    if not surfaces.translucency.any():
        return None
    black = np.zeros_like(surfaces.diffuse)
    return dataclasses.replace(
        surfaces, diffuse=surfaces.translucency, f0=black, f90=black, emission=black,
        glossy_environment=np.zeros_like(surfaces.glossy_environment), any_emission=False)


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


def directional_albedo_quadrature() -> np.ndarray:
    """(alphas, cosines) table of E(mu, alpha), the lobe's reflectance with F = 1.

    Half vectors are drawn from D(h) (N.H) on a stratified 96 x 32 grid (tan^2 theta_h =
    alpha^2 u / (1 - u)), which resolves sharp and wide lobes alike; each contributes
    Vis 4 (V.H) (N.L) / (N.H), the estimator of the integral of D Vis cos(theta_l)."""
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


def directional_albedo(cos_v, alpha):
    """E(N.V, alpha) (m,) of the GGX lobe, bilinear in the precomputed table."""
    table = _ALBEDO_TABLE
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
                                   take(transparency, passing), True, straight=True))
    reflecting = np.flatnonzero(reflect_weight.max(axis=0) > 0)
    if len(reflecting):
        d, n = take(directions, reflecting), take(normals, reflecting)
        reflected = d - (2 * cos_in[reflecting]) * n
        branches.insert(0, Branch(reflecting, reflected.astype(dtype),
                                  take(reflect_weight, reflecting), False))
    return branches
