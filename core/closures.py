"""What a surface does with light at each of k hits: the closures a material's program (or
its constant table row) gives, and the BSDF they make: evaluated for a pair of directions,
and sampled.

The lobes, per hit (each weight a colour, as a sum of Cycles' closures of one kind):

* diffuse: Lambert, albedo ``diffuse``; its ``layer`` share lies under a dielectric specular
  layer of normal reflectance ``layer_f0``, which takes 1 - A(N.V) of it as Cycles'
  Principled BSDF does (``core.bsdf.diffuse_seen``'s model, per hit here);
* glossy: GGX of alpha = roughness^2 with Fresnel from ``f0`` to ``f90`` (Schlick's curve,
  blended by ``dielectric`` towards a dielectric's of index ``specular_ior``) and Turquin's
  multiple-scattering compensation (``core.bsdf``); alpha at most ``DELTA_ALPHA`` is a mirror;
* transmission: refraction by Snell's law (``ior`` inside over outside) through the normal,
  or for rough glass through a microfacet drawn from GGX's visible normals (weighed by its
  shadowing G1 of the refracted direction), weight ``transmission`` x (1 -
  ``transmission_fresnel`` F), F Schlick's for the index on the less dense side; under total
  internal reflection that share is reflected.  Refraction is sampled only (no density):
  light reaches through glass by BSDF rays, as through Cycles' glass without caustics
  tricks;
* translucent: Lambert on the back side, albedo ``translucency``;
* transparent: straight through, weight ``transparency``.

Mirrors, refraction and transparency are delta lobes (no density to evaluate); the others
are evaluated and sampled (cosine-weighted, GGX's visible normals (Heitz 2018)), one lobe
chosen per sample in proportion to its estimated albedo, the sampled direction weighted by
the BSDF's density over every non-delta lobe (so light samples and BSDF samples share one
density for multiple importance sampling).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .bsdf import (SurfaceArrays, _compensation, _visibility, dielectric_rise,
                   directional_albedo, glossy_albedo)
from .reflectance import MIN_ALPHA, dielectric_f0, ior_from_f0
from .vectors import dot, normalize, take

#: Lobes, in the order ``lobe_albedos`` stacks them.
DIFFUSE, GLOSSY, TRANSMISSION, TRANSLUCENT, TRANSPARENT = range(5)
LOBES = ("diffuse", "glossy", "transmission", "translucent", "transparent")
#: GGX alpha up to which the glossy lobe is a perfect mirror (Blender's roughness 0.0316:
#: the exported alpha's floor, ``core.reflectance.MIN_ALPHA``).
DELTA_ALPHA = MIN_ALPHA


@dataclass
class Closures:
    """Per-hit lobes (module docstring): colours (3, k), scalars (k,); ``normal`` the
    shading normal the lobes use (3, k) (a program's bump), or None for the hit's own;
    ``specular_normal`` the one the glossy and transmission lobes use instead, or None
    for the same (``with_specular_normal``)."""

    diffuse: np.ndarray
    layer: np.ndarray
    layer_f0: np.ndarray
    f0: np.ndarray
    f90: np.ndarray
    dielectric: np.ndarray
    specular_ior: np.ndarray
    alpha: np.ndarray
    transmission: np.ndarray
    transmission_fresnel: np.ndarray
    ior: np.ndarray
    translucency: np.ndarray
    transparency: np.ndarray
    emission: np.ndarray
    holdout: np.ndarray
    holdout_object: np.ndarray
    normal: np.ndarray | None = None
    smooth: np.ndarray | None = None   # (3, k) the normal before bump: ``bump_shadowing``
    specular_normal: np.ndarray | None = None

    def __len__(self) -> int:
        return self.alpha.shape[0]

    @classmethod
    def from_table(cls, surfaces: SurfaceArrays, material: np.ndarray) -> "Closures":
        """The closures of hits on constant materials, rows ``material`` (k,) of the table.
        The article's Blinn-Phong materials become a diffuse lobe and a glossy one of the
        matching roughness (their mirror weight a mirror lobe where they have one)."""
        values = {}
        for name in ("diffuse", "f0", "f90", "transmission", "translucency",
                     "transparency", "emission"):
            values[name] = take(getattr(surfaces, name), material)
        for name in ("layer", "layer_f0", "dielectric", "specular_ior", "alpha",
                     "transmission_fresnel", "ior", "holdout", "holdout_object"):
            values[name] = getattr(surfaces, name)[material]
        closures = cls(**values)
        if not surfaces.physical.all():
            _article_lobes(closures, surfaces, material)
        return closures

    def take(self, index) -> "Closures":
        values = {}
        for item in fields(self):
            value = getattr(self, item.name)
            if value is None:
                values[item.name] = None
            elif value.ndim == 2:
                values[item.name] = take(value, index)
            else:
                values[item.name] = value[index]
        return Closures(**values)

    def put(self, index, other: "Closures") -> None:
        """Write ``other``'s k' hits into hits ``index`` (k',)."""
        for item in fields(self):
            mine, theirs = getattr(self, item.name), getattr(other, item.name)
            if theirs is None:
                continue
            if mine is None:
                raise ValueError(f"closures: cannot put a {item.name} into closures "
                                 f"without one")
            if mine.ndim == 2:
                mine[:, index] = theirs
            else:
                mine[index] = theirs


def with_specular_normal(closures: Closures, true_normal, to_view, normal) -> None:
    """Give the glossy and transmission lobes of hits whose shading ``normal`` (3, k)
    would mirror the view below the surface (a bump, a normal map, a smooth mesh near its
    terminator) a normal raised until it does not, as Cycles' Principled, Glossy and Glass
    closures take ``maybe_ensure_valid_specular_reflection`` of theirs; the diffuse and
    translucent lobes keep ``normal``, as Cycles' do.  None where no hit needs it."""
    specular = valid_reflection(true_normal, to_view, normal)
    closures.specular_normal = None if specular is normal else specular


def _article_lobes(closures: Closures, surfaces: SurfaceArrays, material) -> None:
    """The article's Materials among ``material`` as physical lobes (``Closures.from_table``):
    specular ks as a glossy lobe of the GGX alpha whose Blinn-Phong exponent n matches
    (alpha = sqrt(2 / (n + 2)), Walter et al. 2007), a mirror of weight ``reflection``
    where there is one."""
    article = np.flatnonzero(~surfaces.physical[material])
    rows = material[article]
    exponent = surfaces.exponent[rows]
    alpha = np.sqrt(2.0 / (exponent + 2.0))
    reflection = surfaces.reflection[rows]
    mirror = reflection > 0
    specular = np.minimum(take(surfaces.f0, rows), 1.0)
    glossy = np.where(mirror, reflection, specular)
    closures.f0[:, article] = glossy
    closures.f90[:, article] = glossy
    closures.alpha[article] = np.where(mirror, DELTA_ALPHA, np.maximum(alpha, DELTA_ALPHA))


# --------------------------------------------------------------------------------------------
# Fresnel, albedos and frames, per hit.

def fresnel(closures: Closures, cosine) -> np.ndarray:
    """(3, k) the glossy lobe's F at cosines (k,) between the light (or view) and the half
    vector: Schlick's rise from f0 to f90, blended towards a dielectric's curve."""
    c = np.clip(1 - cosine, 0, 1)
    c2 = c * c
    rise = c2 * c2 * c
    curved = np.flatnonzero(closures.dielectric > 0)
    if len(curved):
        exact = dielectric_rise(cosine[curved], closures.specular_ior[curved])
        rise = rise.copy()
        rise[curved] += closures.dielectric[curved] * (exact - rise[curved])
    return closures.f0 + (closures.f90 - closures.f0) * rise


def diffuse_seen(closures: Closures, cos_o) -> np.ndarray:
    """(3, k) the diffuse albedo seen from a view at cosines cos_o: the layered share scaled
    from base (1 - f0) to base (1 - A(N.V)), A the layer's directional albedo (Cycles'
    ``closure_layering_weight``)."""
    diffuse = closures.diffuse
    layered = np.flatnonzero((closures.layer > 0) & (closures.layer_f0 > 0))
    if len(layered) == 0:
        return diffuse
    f0 = closures.layer_f0[layered]
    albedo = glossy_albedo(f0, np.ones_like(f0), np.clip(cos_o[layered], 0, 1),
                           closures.alpha[layered], np.ones_like(f0), ior_from_f0(f0))
    loss = closures.layer[layered] * (albedo - f0) / np.maximum(1 - f0, 1e-6)
    diffuse = diffuse.copy()
    diffuse[:, layered] *= np.clip(1 - loss, 0, None)
    return diffuse


def _transmission_share(closures: Closures, cos_o, entering):
    """((3, k) the refracted weight, (3, k) what total internal reflection returns, (k,)
    whether it does, (k,) eta, (k,) cos_t) for views at cosines cos_o > 0 (module doc)."""
    ior = np.maximum(closures.ior, 1e-6)
    eta = np.where(entering, 1 / ior, ior)
    sin2_t = eta * eta * (1 - cos_o * cos_o)
    total = sin2_t >= 1
    cos_t = np.sqrt(np.maximum(1 - sin2_t, 0))
    f0 = dielectric_f0(ior)
    # Schlick on the less dense side: the incident cosine entering, the transmitted one
    # leaving (so that F reaches 1 at the critical angle).
    f = f0 + (1 - f0) * (1 - np.where(eta <= 1, cos_o, cos_t)) ** 5
    f_incident = f0 + (1 - f0) * (1 - cos_o) ** 5
    k = closures.transmission_fresnel
    refracted = closures.transmission * np.where(total, 0, 1 - k * f)
    reflected = closures.transmission * (total * (1 - k * f_incident))
    return refracted, reflected, total, eta, cos_t


def valid_reflection(true_normal, to_view, normal):
    """(3, k) Cycles' ``ensure_valid_specular_reflection``: a bumped or mapped shading
    normal whose mirror reflection of the view would go below the surface, raised towards
    the true normal (all facing the view, unit, (3, k)) just enough that it does not."""
    i_z = dot(to_view, true_normal)
    reflected_z = 2 * dot(normal, to_view) * dot(normal, true_normal) - i_z
    threshold = np.minimum(0.9 * i_z, 0.01)
    wrong = reflected_z < threshold
    if not wrong.any():
        return normal
    x = normal - dot(normal, true_normal) * true_normal
    length = np.sqrt(dot(x, x))
    x = np.where(length > 0, x / np.where(length > 0, length, 1), normal)
    i_x = dot(to_view, x)
    a = i_x * i_x + i_z * i_z
    b = 2 * (a + i_z * threshold)
    c = (threshold + i_z) ** 2
    root = np.sqrt(np.maximum(b * b - 4 * a * c, 0))
    safe_a = np.where(a > 0, a, 1)
    nz2 = np.where(i_x < 0, 0.25 * (b + root) / safe_a, 0.25 * (b - root) / safe_a)
    raised = np.sqrt(np.maximum(1 - nz2, 0)) * x + np.sqrt(np.maximum(nz2, 0)) * true_normal
    return np.where(wrong, raised, normal)


def bump_shadowing(smooth, normal, towards):
    """(k,) Cycles' ``bump_shadowing_term`` for diffuse lobes of bumped normals (unit,
    (3, k)) towards unit ``towards`` (3, k): 0 where the direction and the bumped normal are
    on opposite sides of the smooth surface (no light through opaque geometry), else Conty
    et al.'s GGX shadowing of the angle to the smooth normal, with a roughness from how far
    the bump tilts it (alpha^2 = tan^2(tilt) / 8)."""
    cos_si = dot(smooth, towards)
    cos_sn = dot(smooth, normal)
    cos_ni = dot(normal, towards)
    leak = cos_si * cos_sn * cos_ni < 0
    cos_i = np.abs(cos_si)
    cos_d = np.abs(cos_sn)
    alpha2 = np.clip(0.125 * (1 / np.maximum(cos_d * cos_d, 1e-12) - 1), 0, 1)
    safe_i = np.maximum(cos_i, 1e-6)
    tan2_i = (1 - safe_i * safe_i) / (safe_i * safe_i)
    shadowing = 2 / (1 + np.sqrt(1 + alpha2 * tan2_i))
    shadowing = np.where((cos_d >= 1) | (cos_i >= 1), 1.0, shadowing)
    shadowing = np.where(cos_i < 1e-6, 0.0, shadowing)
    return np.where(leak, 0.0, shadowing)


def frame(normal):
    """(tangent, bitangent) (3, k) completing unit normals (3, k) to orthonormal frames
    (Duff et al. 2017)."""
    sign = np.where(normal[2] >= 0, 1.0, -1.0).astype(normal.dtype)
    a = -1 / (sign + normal[2])
    b = normal[0] * normal[1] * a
    tangent = np.stack([1 + sign * normal[0] * normal[0] * a, sign * b, -sign * normal[0]])
    bitangent = np.stack([b, sign + normal[1] * normal[1] * a, -normal[1]])
    return tangent, bitangent


def cosine_hemisphere(normal, u1, u2):
    """(3, k) directions with density cos(theta) / pi about unit normals (3, k) (Malley)."""
    tangent, bitangent = frame(normal)
    r = np.sqrt(u1)
    phi = 2 * np.pi * u2
    x, y = r * np.cos(phi), r * np.sin(phi)
    z = np.sqrt(np.maximum(1 - u1, 0))
    return x * tangent + y * bitangent + z * normal


def _ggx_d(cos_h, alpha):
    a2 = alpha * alpha
    return a2 / (np.pi * (cos_h * cos_h * (a2 - 1) + 1) ** 2)


def _smith_g1(cosine, alpha):
    a2 = alpha * alpha
    return 2 * cosine / (cosine + np.sqrt(a2 + (1 - a2) * cosine * cosine))


def ggx_visible_normal(normal, to_view, alpha, u1, u2):
    """(3, k) half vectors drawn from GGX's distribution of normals visible from unit
    ``to_view`` (3, k) about unit normals, roughness alpha (k,) (Heitz 2018)."""
    tangent, bitangent = frame(normal)
    view = np.stack([dot(to_view, tangent), dot(to_view, bitangent), dot(to_view, normal)])
    stretched, _ = normalize(np.stack([alpha * view[0], alpha * view[1], view[2]]))
    length2 = stretched[0] ** 2 + stretched[1] ** 2
    safe = np.maximum(length2, 1e-20)
    t1 = np.where(length2 > 0, np.stack([-stretched[1], stretched[0],
                                         np.zeros_like(stretched[0])]) / np.sqrt(safe),
                  np.stack([np.ones_like(u1), np.zeros_like(u1), np.zeros_like(u1)]))
    t2 = np.stack([stretched[1] * t1[2] - stretched[2] * t1[1],
                   stretched[2] * t1[0] - stretched[0] * t1[2],
                   stretched[0] * t1[1] - stretched[1] * t1[0]])
    r = np.sqrt(u1)
    phi = 2 * np.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1 + stretched[2])
    p2 = (1 - s) * np.sqrt(np.maximum(1 - p1 * p1, 0)) + s * p2
    p3 = np.sqrt(np.maximum(1 - p1 * p1 - p2 * p2, 0))
    h = p1 * t1 + p2 * t2 + p3 * stretched
    local, _ = normalize(np.stack([alpha * h[0], alpha * h[1], np.maximum(h[2], 1e-7)]))
    return local[0] * tangent + local[1] * bitangent + local[2] * normal


# --------------------------------------------------------------------------------------------
# The BSDF.

@dataclass
class LobeChoice:
    """How a hit's lobes are chosen: probability (5, k) of each lobe (``LOBES`` order),
    and the lobes' albedo estimates (5, 3, k) the probabilities come from; with them what
    depends on the view alone, for ``evaluate`` at every light: compensation (3, k) the
    glossy lobe's multiple-scattering factor."""

    probability: np.ndarray
    albedo: np.ndarray
    compensation: np.ndarray

    def take(self, rows) -> "LobeChoice":
        return LobeChoice(self.probability[:, rows], self.albedo[:, :, rows],
                          self.compensation[:, rows])


def lobe_albedos(closures: Closures, normal, to_view, entering) -> LobeChoice:
    """Each lobe's albedo seen from ``to_view`` (3, k) and the probability of sampling it
    (in proportion to the albedo's mean over the channels); normals face the view."""
    cos_o = np.clip(dot(normal, to_view), 1e-6, 1)
    cos_s = cos_o if closures.specular_normal is None else np.clip(
        dot(closures.specular_normal, to_view), 1e-6, 1)
    albedo = np.zeros((5,) + closures.diffuse.shape, closures.diffuse.dtype)
    albedo[DIFFUSE] = diffuse_seen(closures, cos_s)   # (the layer above attenuates it)
    glossy = closures.alpha > DELTA_ALPHA
    albedo[GLOSSY] = np.where(
        glossy, glossy_albedo(closures.f0, closures.f90, cos_s, closures.alpha,
                              closures.dielectric, closures.specular_ior),
        fresnel(closures, cos_s))
    if closures.transmission.any():
        refracted, reflected, _, _, _ = _transmission_share(closures, cos_s, entering)
        albedo[TRANSMISSION] = refracted + reflected
    albedo[TRANSLUCENT] = closures.translucency
    albedo[TRANSPARENT] = closures.transparency
    weight = np.maximum(albedo, 0).mean(axis=1)
    total = weight.sum(axis=0)
    probability = weight / np.where(total > 0, total, 1)
    compensation = _compensation(closures.f0, directional_albedo(
        cos_s, np.maximum(closures.alpha, DELTA_ALPHA)))
    return LobeChoice(probability, albedo, compensation)


def evaluate(closures: Closures, choice: LobeChoice, normal, to_view, towards):
    """(f cos (3, k), pdf (k,)) of the non-delta lobes for light arriving from unit
    ``towards`` (3, k), seen from ``to_view``; pdf the density of ``sample`` drawing that
    direction (per solid angle, the lobes' choice included).  choice: ``lobe_albedos`` of
    the same hits, normals and view."""
    cos_o = np.clip(dot(normal, to_view), 1e-6, 1)
    cos_i = dot(normal, towards)
    above = cos_i > 0
    f = np.zeros_like(closures.diffuse)
    pdf = np.zeros_like(cos_o)
    p = choice.probability
    lit = np.maximum(cos_i, 0)
    softened = 1.0
    if closures.smooth is not None:
        softened = bump_shadowing(closures.smooth, normal, towards)
    if p[DIFFUSE].any():
        f += choice.albedo[DIFFUSE] * (lit / np.pi * softened)
        pdf += p[DIFFUSE] * (lit / np.pi)
    if p[TRANSLUCENT].any():
        behind = np.maximum(-cos_i, 0)
        f += closures.translucency * (behind / np.pi * softened)
        pdf += p[TRANSLUCENT] * (behind / np.pi)
    rough = closures.alpha > DELTA_ALPHA
    if (p[GLOSSY] * rough).any():
        if closures.specular_normal is not None:
            normal = closures.specular_normal
            cos_o = np.clip(dot(normal, to_view), 1e-6, 1)
            cos_i = dot(normal, towards)
            above = cos_i > 0
            lit = np.maximum(cos_i, 0)
        alpha = np.maximum(closures.alpha, DELTA_ALPHA)
        half = towards + to_view      # (0 for light straight through: no reflection there)
        size = np.sqrt(dot(half, half))
        half = np.where(size > 0, half / np.where(size > 0, size, 1), normal)
        cos_h = np.clip(dot(normal, half), 0, 1)
        d = _ggx_d(cos_h, alpha)
        reflectance = fresnel(closures, np.clip(dot(towards, half), 0, 1))
        compensation = choice.compensation
        lobe = d * _visibility(np.maximum(cos_i, 1e-6), cos_o, alpha * alpha) * lit
        f += np.where(rough & above, reflectance * compensation * lobe, 0)
        density = _smith_g1(cos_o, alpha) * d / (4 * cos_o)
        pdf += np.where(rough & above, p[GLOSSY] * density, 0)
    return f, pdf


@dataclass
class BsdfSample:
    """A sampled direction per hit: ``directions`` (3, k); ``weight`` (3, k) f cos / pdf
    (what the path's throughput is multiplied by); ``pdf`` (k,) the density over the
    non-delta lobes (0 for delta lobes); ``lobe`` (k,) which lobe (``LOBES``; -1: none,
    the path ends); ``through`` (k,) whether the ray leaves through the surface."""

    directions: np.ndarray
    weight: np.ndarray
    pdf: np.ndarray
    lobe: np.ndarray
    through: np.ndarray

    @property
    def delta(self) -> np.ndarray:
        return (self.lobe == TRANSMISSION) | (self.lobe == TRANSPARENT) | (
            (self.lobe == GLOSSY) & (self.pdf == 0))


def sample(closures: Closures, choice: LobeChoice, normal, to_view, entering, u_lobe, u1,
           u2) -> BsdfSample:
    """Draw one direction per hit: a lobe by ``choice``, then a direction from it (module
    docstring).  u_lobe, u1, u2: (k,) numbers in [0, 1)."""
    k = len(u1)
    dtype = normal.dtype
    cumulative = np.cumsum(choice.probability, axis=0)
    lobe = (u_lobe[None, :] >= cumulative).sum(axis=0)
    lobe = np.where(cumulative[-1] > 0, np.minimum(lobe, 4), -1)
    directions = np.zeros((3, k), dtype)   # (paths whose surface has no lobe keep 0)
    weight = np.zeros((3, k), dtype)
    through = np.zeros(k, bool)
    specular = normal if closures.specular_normal is None else closures.specular_normal
    reflected = to_view * -1 + specular * (2 * dot(specular, to_view))

    diffuse = lobe == DIFFUSE
    directions[:, diffuse] = cosine_hemisphere(normal[:, diffuse], u1[diffuse], u2[diffuse])
    translucent = lobe == TRANSLUCENT
    directions[:, translucent] = -cosine_hemisphere(normal[:, translucent], u1[translucent],
                                                    u2[translucent])
    through |= translucent
    glossy = lobe == GLOSSY
    rough = glossy & (closures.alpha > DELTA_ALPHA)
    mirror = glossy & ~rough
    if rough.any():
        index = np.flatnonzero(rough)
        view = take(to_view, index)
        half = ggx_visible_normal(take(specular, index), view, closures.alpha[index],
                                  u1[index], u2[index])
        directions[:, index] = 2 * dot(view, half) * half - view
    directions[:, mirror] = reflected[:, mirror]
    albedo = choice.albedo
    probability = choice.probability
    safe = lambda p: np.where(p > 0, p, 1)  # noqa: E731
    weight[:, mirror] = albedo[GLOSSY][:, mirror] / safe(probability[GLOSSY][mirror])
    transparent = lobe == TRANSPARENT
    directions[:, transparent] = -to_view[:, transparent]
    weight[:, transparent] = (albedo[TRANSPARENT][:, transparent]
                              / safe(probability[TRANSPARENT][transparent]))
    through |= transparent
    refracting = lobe == TRANSMISSION
    if refracting.any():
        index = np.flatnonzero(refracting)
        part = closures.take(index)
        view = take(to_view, index)
        n = take(specular, index)
        # Rough glass refracts through a microfacet drawn from GGX's visible normals (its
        # shadowing weighs the ray by G1 of where it goes); smooth glass through the normal.
        rough_glass = part.alpha > DELTA_ALPHA
        facet = n
        if rough_glass.any():
            facet = n.copy()
            rows = np.flatnonzero(rough_glass)
            facet[:, rows] = ggx_visible_normal(take(n, rows), take(view, rows),
                                                part.alpha[rows], u1[index[rows]],
                                                u2[index[rows]])
        c = np.clip(dot(view, facet), 1e-6, 1)
        refracted, returned, total, eta, cos_t = _transmission_share(part, c, entering[index])
        bent, _ = normalize(-eta * view + (eta * c - cos_t) * facet)
        mirrored = 2 * c * facet - view
        directions[:, index] = np.where(total, mirrored, bent)
        shares = np.where(total, returned, refracted)
        if rough_glass.any():
            going = np.abs(dot(n, directions[:, index]))
            shadowing = _smith_g1(np.maximum(going, 1e-6), np.maximum(part.alpha, DELTA_ALPHA))
            shares = shares * np.where(rough_glass, shadowing, 1.0)
        weight[:, index] = shares / safe(probability[TRANSMISSION][index])
        through[index] = ~total

    scattered = diffuse | translucent | rough
    f, pdf = evaluate(closures, choice, normal, to_view, directions)
    valid = scattered & (pdf > 0)
    weight[:, scattered] = np.where(valid[scattered], f[:, scattered]
                                    / safe(pdf[scattered]), 0)
    pdf = np.where(scattered, pdf, 0)
    # A direction that leaves on the wrong side of the shading normal ends the path.
    lobe = np.where(scattered & ~valid, -1, lobe)
    return BsdfSample(directions, weight, pdf, lobe, through)
