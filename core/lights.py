"""Blender's lights in Cycles' units: where each light is sampled and how much it delivers.

Every light is reduced to S deterministic samples.  For each shaded point P (normal N) and
sample j, ``sample_irradiance`` gives the unit direction w_j towards the light, the distance
and the irradiance e_j (W/m^2 per unit of ``PreparedLight.scale``) *including* the receiver's
cos(theta_i) = N.w_j, so that a Lambertian albedo a reflects radiance ``scale a sum_j e_j / pi``
(``core.bsdf``), as Cycles' direct light does.  The factors, light by light:

* Sphere (point) light of power P W and colour c.  Cycles spreads P evenly over the sphere of
  directions: radiant intensity I = P c / (4 pi) W/sr.  At distance d the irradiance on a
  surface turned theta from the light is E = I cos(theta) / d^2 (inverse square law, Lambert's
  cosine), and a Lambertian BRDF is a / pi, so L = a P cos(theta) / (4 pi^2 d^2): the
  factor 1/(4 pi) is the sphere's solid angle, the second 1/pi the diffuse BRDF's
  normalisation.  (Checked headless against Cycles with max_bounces = 0: 0.783 vs 0.792 for
  a = 0.5, P = 1000 W, d = 4, the pixels' cos(theta) accounting for the 1 %.)  A radius r
  makes the light a disc of radius r facing the point (Cycles' sampling of a sphere light):
  its solid angle pi r^2 / (d^2 + r^2) replaces pi r^2 / d^2, so E = I cos(theta) /
  (d^2 + r^2) (measured: r = 0.6 at d = 3.5 is 3 % dimmer in Cycles than the point formula,
  and (r / d)^2 = 2.9 %), and shadows are soft: visibility is the share of that disc the
  point sees, estimated from 2 S fixed points spread over the sphere (S Fibonacci points and
  their antipodes, so that their shadow
  rays share origins): each point j of the hemisphere facing P counts with weight
  n_j . w, w the unit direction from the light's centre to P, which turns the hemisphere's
  uniform spread into a uniform spread over the disc it projects to.
* Spot light: the sphere light times Cycles' ``spot_attenuation``,
  smoothstep(0, 1, (cos(phi) - cos(size / 2)) / ((1 - cos(size / 2)) blend)), phi the angle
  from the spot's axis (a hard edge for blend = 0).  The power is *not* concentrated into
  the cone: a spot is a masked point light, so inside the cone it equals a point light of
  the same power (checked headless: ratio 1.000 on the axis).
* Sun of strength S W/m^2: the irradiance of a surface facing it is S, so E = S c cos(theta)
  and L = a S cos(theta) / pi (checked headless: 0.475 vs 0.477).  An angle alpha spreads
  the samples over a disc of directions of half-angle alpha / 2 (soft shadows); E keeps the
  centre's cos(theta).
* Area light of power P and area A (square, rectangle, disk, ellipse; one-sided towards the
  light's -Z): a Lambertian emitter of radiance L_e = P c / (pi A) (Cycles'
  ``eval_fac = 0.25 invarea`` on a strength that Blender's light sync scales by 4 / pi;
  checked headless: a small square light gives 4.00x the point light of the same power at
  the same distance, and 4 = (1 / (pi A)) A / (1 / (4 pi))).  The irradiance
  E = integral L_e cos(theta_l) cos(theta_i) / d^2 dA is a sum over S stratified points of
  the light (equal areas A / S; disks by Shirley & Chiu's concentric map), each with its own
  direction, distance and visibility: e_j = cos(theta_l) cos(theta_i) / (S d_j^2), scale =
  P c / pi.

Shadow rays from a light's samples share an origin (a ``SharedOrigin`` per sample, as for the
article's lights); a sun's rays leave the points instead.

The patterns the samples follow (pixel shares, grids, Fibonacci spheres, cosine
directions) are ``core.sampler``'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .light_sources import AreaLight, SphereLight, SpotLight, SunLight
from .sampler import concentric_disk, diagonal_grid, fibonacci_sphere
from .vectors import dot, normalize


@dataclass(frozen=True)
class PreparedLight:
    """A light ready for shading (float64).

    kind: 'sphere' (point and spot: irradiance from the centre, visibility from the samples),
        'area' (every sample its own direction and irradiance) or 'sun' (samples are
        directions towards the light).
    scale: (3,) colour x the light's constant factor (module docstring).
    centre: (3,) position, or the unit direction towards the sun.
    samples: (S, 3) sample positions on the light, or unit directions towards the sun.
    terms: the geometry's ``SharedOrigin`` per sample position (empty for a sun).
    radius: a sphere light's radius; sample_normals (S, 3): its samples' outward normals.
    normal: (3,) an area light's emitting direction.  axis, cos_half, blend: a spot's cone.
    """

    kind: str
    scale: np.ndarray
    centre: np.ndarray
    samples: np.ndarray
    terms: tuple
    radius: float = 0.0
    sample_normals: np.ndarray | None = None
    normal: np.ndarray | None = None
    axis: np.ndarray | None = None
    cos_half: float = -1.0
    blend: float = 0.0


def _tangents(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    first = np.cross(direction, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(direction, first)


def prepare_light(light, light_samples: int, geometry) -> PreparedLight:
    """A SphereLight, SpotLight, SunLight or AreaLight as a PreparedLight; ``light_samples``
    samples for lights with an extent (radius, angle, area), one otherwise.  geometry: the
    scene's ``Aggregate``, which makes the shadow rays' shared-origin terms."""
    colour = np.asarray(light.colour, np.float64)
    terms_at = lambda points: tuple(geometry.shared_origin(p) for p in points)  # noqa: E731
    if isinstance(light, SunLight):
        towards = -np.asarray(light.direction, np.float64)
        if light.angle > 0:
            first, second = _tangents(towards)
            disk = concentric_disk(diagonal_grid(light_samples)) * math.tan(light.angle / 2)
            samples = towards + disk[:, :1] * first + disk[:, 1:] * second
            samples /= np.linalg.norm(samples, axis=1, keepdims=True)
        else:
            samples = towards[None, :]
        return PreparedLight("sun", colour * light.strength, towards, samples, ())
    if isinstance(light, AreaLight):
        centre = np.asarray(light.position, np.float64)
        grid = diagonal_grid(light_samples)
        if light.shape in ("DISK", "ELLIPSE"):
            grid = concentric_disk(grid)
        samples = (centre + 0.5 * light.size_x * grid[:, :1] * np.asarray(light.axis_x)
                   + 0.5 * light.size_y * grid[:, 1:] * np.asarray(light.axis_y))
        return PreparedLight("area", colour * light.power / math.pi, centre, samples,
                             terms_at(samples), normal=np.asarray(light.direction, np.float64))
    if isinstance(light, (SphereLight, SpotLight)):
        centre = np.asarray(light.position, np.float64)
        normals = None
        if light.radius > 0:
            # Samples j and j + S are antipodes, so a sample share (module docstring) of
            # j = s (mod S) always holds as many samples facing a point as not.
            normals = fibonacci_sphere(light_samples)
            normals = np.concatenate([normals, -normals])
        samples = centre[None, :] if normals is None else centre + light.radius * normals
        prepared = dict(kind="sphere", scale=colour * light.power / (4 * math.pi),
                        centre=centre, samples=samples, terms=terms_at(samples),
                        radius=light.radius, sample_normals=normals)
        if isinstance(light, SpotLight):
            prepared.update(axis=np.asarray(light.direction, np.float64),
                            cos_half=math.cos(light.spot_size / 2), blend=light.spot_blend)
        return PreparedLight(**prepared)
    raise TypeError(f"not a Blender light type: {type(light).__name__}")


def spot_attenuation(light: PreparedLight, from_light) -> np.ndarray:
    """(m,) Cycles' spot mask for unit directions (3, m) from the light towards the points."""
    cos_angle = dot(from_light, light.axis[:, None].astype(from_light.dtype))
    if light.blend <= 0:
        return (cos_angle > light.cos_half).astype(from_light.dtype)
    x = np.clip((cos_angle - light.cos_half) / ((1.0 - light.cos_half) * light.blend), 0, 1)
    return x * x * (3 - 2 * x)


def centre_irradiance(light: PreparedLight, points, normals):
    """For 'sphere' and 'sun' lights: (towards (3, m) unit, distance (m,), e (m,) irradiance
    per unit scale including cos(theta_i), 0 where the light is behind the surface)."""
    dtype = points.dtype
    if light.kind == "sun":
        towards = np.broadcast_to(light.centre.astype(dtype)[:, None], points.shape)
        cos_i = dot(normals, towards)
        return towards, np.full(points.shape[1], np.inf, dtype), np.maximum(cos_i, 0)
    towards, distance = normalize(light.centre.astype(dtype)[:, None] - points)
    cos_i = dot(normals, towards)
    e = np.maximum(cos_i, 0) / (distance * distance + light.radius ** 2)
    if light.axis is not None:
        e = e * spot_attenuation(light, -towards)
    return towards, distance, e


def area_sample_irradiance(light: PreparedLight, sample: int, points, normals):
    """For 'area' lights, sample j: (towards (3, m), distance (m,), e_j (m,)) (module doc)."""
    dtype = points.dtype
    towards, distance = normalize(light.samples[sample].astype(dtype)[:, None] - points)
    cos_i = np.maximum(dot(normals, towards), 0)
    cos_l = np.maximum(-dot(towards, light.normal.astype(dtype)[:, None]), 0)
    e = cos_i * cos_l / (len(light.samples) * distance * distance)
    return towards, distance, e


