"""Where light comes from, for a path tracer: Blender's lights, emitting triangles and the
world, each sampled from a shading point (next-event estimation) and found by rays that
BSDF sampling sends their way, with both densities in solid angle for multiple importance
sampling.  Units are Cycles' (``core.lights``'s module docstring derives them):

* point light, power P, colour c, radius r: Cycles' default soft-falloff point light is a
  disc of radius r facing the shading point, of radiance P c / (4 pi) / (pi r^2); r = 0 is
  a point of intensity P c / (4 pi) (a delta light: no density);
* spot light: the point light times the spot's smoothstep mask;
* sun of strength S: a cone of directions of half-angle angle / 2, radiance
  S c / (pi sin^2(angle / 2)) (so that a surface facing it receives S); angle 0 is a delta;
* area light: a one-sided Lambertian rectangle or ellipse of radiance P c / (pi A); a
  rectangle is sampled uniformly in the solid angle it covers, an ellipse over its area;
* emitting triangles: their material's emission, on both sides (Cycles' Emission closure);
* the world: a constant radiance (found by escaping rays only: for a constant world,
  cosine-weighted BSDF samples are the better estimator, and no shadow ray is spent on it).

Next-event estimation samples every light source at every vertex where there are few
(``SAMPLED_EACH``), else one chosen in proportion to an estimate of its power.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .light_sources import AreaLight, PointLight, SphereLight, SpotLight, SunLight
from .shader.points import ShadingPoints
from .shader.program import run
from .vectors import dot, normalize

#: Up to this many light sources, every vertex samples each of them.
SAMPLED_EACH = 8
#: A point light's power that the article's PointLight of unit intensity stands for.
ARTICLE_LIGHT_POWER = PointLight.REFERENCE_POWER_W


@dataclass(frozen=True, eq=False)
class Light:
    """One of Blender's lights, float64 (module docstring).

    kind: 'point', 'sun' or 'area' (a spot is a point with a cone: ``axis`` not None).
    radiance: (3,) the emitted radiance (point with radius, sun with angle, area), or the
        intensity (point of radius 0, W/sr) or irradiance (sun of angle 0, W/m^2).
    position: (3,) centre; direction: (3,) the sun's travel, the area light's emitting
        normal, or the spot's axis.  radius: point light radius.  cos_half, one_minus_cos:
        the sun's cone.  axis_x, axis_y, size_x, size_y, disk: the area light's extent.
    power: an estimate of the power it brings a scene, for choosing among many.
    program, matrix: the light's node tree and its object's world matrix (``core.scene``),
        ``light_texture`` evaluates.
    """

    kind: str
    radiance: np.ndarray
    position: np.ndarray
    direction: np.ndarray
    power: float
    radius: float = 0.0
    axis: np.ndarray | None = None
    spot_cos_half: float = -1.0
    spot_blend: float = 0.0
    one_minus_cos: float = 0.0
    axis_x: np.ndarray | None = None
    axis_y: np.ndarray | None = None
    size_x: float = 0.0
    size_y: float = 0.0
    disk: bool = False
    program: object = None
    matrix: np.ndarray | None = None

    @property
    def delta(self) -> bool:
        """A point light of radius 0 or a sun of angle 0: no BSDF sample finds it."""
        if self.kind == "point":
            return self.radius <= 0
        return self.kind == "sun" and self.one_minus_cos <= 0

    @property
    def area(self) -> float:
        full = self.size_x * self.size_y
        return full * math.pi / 4 if self.disk else full


def prepare_lights(lights, scene_radius: float) -> tuple[Light, ...]:
    """The scene's lights as ``Light``s; scene_radius: how far the scene reaches from its
    centre (a sun's power estimate)."""
    prepared = []
    for light in lights:
        texture = {}
        if getattr(light, "program", None) is not None:
            texture = dict(program=light.program,
                           matrix=np.asarray(light.matrix, np.float64).reshape(3, 4))
        if isinstance(light, PointLight):
            light = SphereLight(light.position, light.diffuse,
                                ARTICLE_LIGHT_POWER, light.radius, light.name)
        colour = np.asarray(light.colour, np.float64)
        if isinstance(light, SunLight):
            half = light.angle / 2
            direction = np.asarray(light.direction, np.float64)
            one_minus = 2 * math.sin(half / 2) ** 2
            radiance = colour * light.strength
            if half > 0:
                radiance = radiance / (math.pi * math.sin(half) ** 2)
            prepared.append(Light("sun", radiance, np.zeros(3), direction,
                                  light.strength * float(colour.mean()) * math.pi
                                  * scene_radius ** 2, one_minus_cos=one_minus))
        elif isinstance(light, AreaLight):
            disk = light.shape in ("DISK", "ELLIPSE")
            area = light.area
            prepared.append(Light(
                "area", colour * light.power / (math.pi * area),
                np.asarray(light.position, np.float64),
                np.asarray(light.direction, np.float64), light.power * float(colour.mean()),
                axis_x=np.asarray(light.axis_x, np.float64),
                axis_y=np.asarray(light.axis_y, np.float64), size_x=light.size_x,
                size_y=light.size_y, disk=disk, **texture))
        elif isinstance(light, (SphereLight, SpotLight)):
            intensity = colour * light.power / (4 * math.pi)
            radiance = (intensity / (math.pi * light.radius ** 2) if light.radius > 0
                        else intensity)
            spot = {}
            if isinstance(light, SpotLight):
                spot = dict(axis=np.asarray(light.direction, np.float64),
                            spot_cos_half=math.cos(light.spot_size / 2),
                            spot_blend=light.spot_blend)
            prepared.append(Light("point", radiance, np.asarray(light.position, np.float64),
                                  np.zeros(3), light.power * float(colour.mean()),
                                  radius=light.radius, **spot, **texture))
        else:
            raise TypeError(f"not a light: {type(light).__name__}")
    return tuple(prepared)


def light_texture(light: Light, points, normal, incoming, distance) -> np.ndarray:
    """(3, k) what ``light``'s node tree multiplies its colour by at k points (3, k) on it
    (world space), of unit normal (3, k), sending light along unit ``incoming`` (3, k) (the
    shader's wi: from the light towards what it lights), as Cycles evaluates a light's
    shader at its light sample's point: the emission of its program there, with the Object
    texture coordinate the point in the light's object space, Normal the normal in it, and
    the ray length the ``distance`` (k,) to what it lights."""
    matrix = light.matrix.astype(points.dtype)
    k = points.shape[1]
    inverse = np.linalg.inv(np.vstack([light.matrix, [0.0, 0.0, 0.0, 1.0]]))[:3]
    inverse = inverse.astype(points.dtype)

    def column(c):
        return lambda: np.repeat(matrix[:, c:c + 1], k, axis=1)
    sources = {"object": lambda: inverse[:, :3] @ points + inverse[:, 3:],
               "object_axis_x": column(0), "object_axis_y": column(1),
               "object_axis_z": column(2), "object_location": column(3),
               "ray_length": lambda: distance[None, :]}
    value = run(light.program, ShadingPoints(points, normal, normal, incoming,
                                             sources=sources))
    return np.broadcast_to(np.maximum(value.emission, 0), points.shape).astype(points.dtype)


def _spot_mask(light: Light, from_light):
    """(k,) Cycles' spot smoothstep for unit directions (3, k) from the light."""
    cos_angle = dot(from_light, light.axis[:, None].astype(from_light.dtype))
    if light.spot_blend <= 0:
        return (cos_angle > light.spot_cos_half).astype(from_light.dtype)
    x = np.clip((cos_angle - light.spot_cos_half)
                / ((1.0 - light.spot_cos_half) * light.spot_blend), 0, 1)
    return x * x * (3 - 2 * x)


def _tangents(normal):
    """Two unit vectors (3, k) each completing unit normals (3, k) to a frame."""
    helper = np.where(np.abs(normal[0]) < 0.9, 1.0, 0.0)
    other = np.stack([helper, 1 - helper, np.zeros_like(helper)]).astype(normal.dtype)
    first, _ = normalize(np.stack([normal[1] * other[2] - normal[2] * other[1],
                                   normal[2] * other[0] - normal[0] * other[2],
                                   normal[0] * other[1] - normal[1] * other[0]]))
    second = np.stack([normal[1] * first[2] - normal[2] * first[1],
                       normal[2] * first[0] - normal[0] * first[2],
                       normal[0] * first[1] - normal[1] * first[0]])
    return first, second


def _disk(u1, u2):
    """Shirley & Chiu's concentric map of (k,) pairs in [0, 1)^2 onto the unit disk."""
    a, b = 2 * u1 - 1, 2 * u2 - 1
    first = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, a, b)
        phi = np.where(first, (math.pi / 4) * b / a, math.pi / 2 - (math.pi / 4) * a / b)
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


@dataclass
class LightSample:
    """Samples of one light from k points: unit ``towards`` (3, k), ``distance`` (k,)
    (inf for a sun), ``radiance`` (3, k) the light's radiance arriving (0 where it sends
    none), ``pdf`` (k,) the sample's density in solid angle (inf for a delta light), and
    ``over_pdf`` (3, k) radiance / pdf (what a delta light brings as is)."""

    towards: np.ndarray
    distance: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray
    over_pdf: np.ndarray


def sample_light(light: Light, points, u1, u2) -> LightSample:
    """A sample of ``light`` from each of k points (3, k) (module docstring)."""
    dtype = points.dtype
    k = points.shape[1]
    col = light.radiance.astype(dtype)[:, None]
    if light.kind == "sun":
        towards_centre = -light.direction.astype(dtype)[:, None]
        if light.delta:
            towards = np.repeat(towards_centre, k, axis=1)
            over = np.repeat(col, k, axis=1)
            return LightSample(towards, np.full(k, np.inf, dtype), over,
                               np.full(k, np.inf, dtype), over)
        cos_theta = 1 - u1 * light.one_minus_cos
        sin_theta = np.sqrt(np.maximum(1 - cos_theta * cos_theta, 0))
        phi = 2 * np.pi * u2
        first, second = _tangents(np.repeat(towards_centre, k, axis=1))
        towards = (sin_theta * np.cos(phi) * first + sin_theta * np.sin(phi) * second
                   + cos_theta * towards_centre)
        pdf = np.full(k, 1 / (2 * np.pi * light.one_minus_cos), dtype)
        radiance = np.repeat(col, k, axis=1)
        return LightSample(towards, np.full(k, np.inf, dtype), radiance, pdf, radiance / pdf)
    if light.kind == "point":
        centre = light.position.astype(dtype)[:, None]
        if light.radius > 0:
            facing, _ = normalize(points - centre)
            first, second = _tangents(facing)
            x, y = _disk(u1, u2)
            target = centre + light.radius * (x * first + y * second)
        else:
            facing = None
            target = centre
        towards, distance = normalize(target - points)
        if light.radius > 0:
            cos_l = np.maximum(-dot(towards, facing), 1e-9)
            pdf = distance * distance / (cos_l * (np.pi * light.radius ** 2))
            radiance = col * np.ones(k, dtype)
            over = radiance / pdf
        else:
            pdf = np.full(k, np.inf, dtype)
            over = col / (distance * distance)
            radiance = over
        if light.axis is not None:
            mask = _spot_mask(light, -towards)
            radiance, over = radiance * mask, over * mask
        return LightSample(towards, distance, radiance, pdf, over)
    if not light.disk:
        # A rectangle: a direction uniform in the solid angle it covers, as Cycles samples it.
        target, solid_angle = _spherical_rectangle(light, points, u1, u2)
        towards, distance = normalize(target - points)
        front = (dot(points - light.position.astype(dtype)[:, None],
                     light.direction.astype(dtype)[:, None]) > 0) & (solid_angle > 0)
        pdf = np.where(front, 1 / np.where(front, solid_angle, 1), 0)
        return LightSample(towards, distance, col * front, pdf, col * (solid_angle * front))
    # An ellipse: a point uniform over its surface.
    x, y = _disk(u1, u2)
    target = (light.position.astype(dtype)[:, None]
              + (0.5 * x * light.size_x) * light.axis_x.astype(dtype)[:, None]
              + (0.5 * y * light.size_y) * light.axis_y.astype(dtype)[:, None])
    towards, distance = normalize(target - points)
    cos_l = -dot(towards, light.direction.astype(dtype)[:, None])
    front = cos_l > 0
    pdf = np.where(front, distance * distance / (np.maximum(cos_l, 1e-9) * light.area), 0)
    radiance = col * front
    over = np.where(front, col * (np.maximum(cos_l, 0) * light.area)
                    / (distance * distance), 0)
    return LightSample(towards, distance, radiance, pdf, over)


def _spherical_rectangle(light: Light, points, u1=None, u2=None):
    """(points on the light (3, k) or None, solid angle (k,)): the solid angle a rectangle
    ``light`` covers seen from each of ``points`` (3, k), and with numbers u1, u2 (k,) a
    point on it whose direction is uniform in that solid angle (Urena et al., "An
    Area-Preserving Parametrization for Spherical Rectangles", 2013, as Cycles'
    ``area_light_rect_sample``)."""
    dtype = points.dtype
    x_axis = light.axis_x.astype(dtype)[:, None]
    y_axis = light.axis_y.astype(dtype)[:, None]
    z_axis = np.cross(light.axis_x, light.axis_y).astype(dtype)[:, None]
    corner = (light.position.astype(dtype)[:, None] - (0.5 * light.size_x) * x_axis
              - (0.5 * light.size_y) * y_axis)
    to_corner = corner - points
    z0 = dot(to_corner, z_axis)
    side = np.where(z0 > 0, -1.0, 1.0).astype(dtype)   # z points away from the rectangle
    z0 = z0 * side
    x0, y0 = dot(to_corner, x_axis), dot(to_corner, y_axis)
    x1, y1 = x0 + light.size_x, y0 + light.size_y
    # The normals of the pyramid's four faces (their z components), then its angles.
    diff = np.stack([x0 - x1, y1 - y0, x1 - x0, y0 - y1])
    nz = np.stack([y0, x1, y1, x0]) * diff
    with np.errstate(invalid="ignore", divide="ignore"):
        nz = np.nan_to_num(nz / np.sqrt(z0 * z0 * diff * diff + nz * nz))
    angle = [np.arccos(np.clip(-nz[i] * nz[(i + 1) % 4], -1, 1)) for i in range(4)]
    b0, b1 = nz[0], nz[2]
    k = 2 * np.pi - angle[2] - angle[3]
    solid_angle = np.maximum(angle[0] + angle[1] - k, 0)
    if u1 is None:
        return None, solid_angle
    with np.errstate(invalid="ignore", divide="ignore"):
        au = u1 * solid_angle + k
        fu = (np.cos(au) * b0 - b1) / np.sin(au)
        cu = np.clip(np.where(fu > 0, 1.0, -1.0) / np.sqrt(fu * fu + b0 * b0), -1, 1)
        xu = np.clip(np.nan_to_num(-(cu * z0) / np.maximum(np.sqrt(1 - cu * cu), 1e-7)),
                     x0, x1)
        d2 = xu * xu + z0 * z0
        h0 = y0 / np.sqrt(d2 + y0 * y0)
        h1 = y1 / np.sqrt(d2 + y1 * y1)
        hv = h0 + u2 * (h1 - h0)
        hv2 = hv * hv
        yv = np.where(hv2 < 1 - 1e-6, hv * np.sqrt(d2) / np.sqrt(np.maximum(1 - hv2, 1e-12)),
                      y1)
    target = points + xu * x_axis + np.nan_to_num(yv) * y_axis + (z0 * side) * z_axis
    return target.astype(dtype), solid_angle.astype(dtype)


def light_hit(light: Light, origins, directions, t_max):
    """Where BSDF-sampled rays from ``origins`` (3, k) along unit ``directions`` find a
    non-delta ``light`` before ``t_max`` (k,) (inf: the ray escaped): (hit (k,) bool,
    t (k,), radiance (3, k), pdf (k,) the density ``sample_light`` gives that direction)."""
    dtype = directions.dtype
    k = directions.shape[1]
    none = (np.zeros(k, bool), np.full(k, np.inf, dtype), np.zeros((3, k), dtype),
            np.zeros(k, dtype))
    if light.delta:
        return none
    col = light.radiance.astype(dtype)[:, None]
    if light.kind == "sun":
        cos_angle = -dot(directions, light.direction.astype(dtype)[:, None])
        hit = np.isinf(t_max) & (cos_angle >= 1 - light.one_minus_cos)
        pdf = np.full(k, 1 / (2 * np.pi * light.one_minus_cos), dtype)
        return hit, np.full(k, np.inf, dtype), col * hit, np.where(hit, pdf, 0)
    if light.kind == "point":
        centre = light.position.astype(dtype)[:, None]
        facing, _ = normalize(origins - centre)
        denominator = dot(directions, facing)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = dot(centre - origins, facing) / denominator
        at = origins + directions * t
        inside = dot(at - centre, at - centre) <= light.radius ** 2
        hit = (denominator < 0) & (t > 0) & (t < t_max) & inside
        cos_l = np.maximum(-denominator, 1e-9)
        pdf = t * t / (cos_l * np.pi * light.radius ** 2)
        radiance = col * hit
        if light.axis is not None:
            radiance = radiance * _spot_mask(light, -directions)
        return hit, np.where(hit, t, np.inf), radiance, np.where(hit, pdf, 0)
    normal = light.direction.astype(dtype)[:, None]
    centre = light.position.astype(dtype)[:, None]
    denominator = dot(directions, normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = dot(centre - origins, normal) / denominator
    at = origins + directions * t - centre
    x = dot(at, light.axis_x.astype(dtype)[:, None]) / light.size_x
    y = dot(at, light.axis_y.astype(dtype)[:, None]) / light.size_y
    inside = (x * x + y * y <= 0.25) if light.disk else (np.abs(x) <= 0.5) & (np.abs(y) <= 0.5)
    hit = (denominator < 0) & (t > 0) & (t < t_max) & inside
    if light.disk:
        cos_l = np.maximum(-denominator, 1e-9)
        pdf = t * t / (cos_l * light.area)
    else:
        rows = np.flatnonzero(hit)
        pdf = np.zeros(k, dtype)
        if len(rows):
            _, solid_angle = _spherical_rectangle(
                light, np.broadcast_to(origins, directions.shape)[:, rows])
            pdf[rows] = 1 / np.maximum(solid_angle, 1e-30)
    return hit, np.where(hit, t, np.inf), col * hit, np.where(hit, pdf, 0)


@dataclass(frozen=True, eq=False)
class MeshLights:
    """Emitting triangles, float64: their global primitive ids (E,), corners (3, E) each,
    unit normals (3, E), areas (E,), emitted radiance (3, E) (their material's constant
    emission; for a textured one, an estimate that only weighs the choice), material table
    rows (E,), whether each one's emission is textured (E,) (a program that the light
    samples evaluate where they land), the probability (E,) of choosing each (in proportion
    to area x mean radiance) and its cumulative sum, and per primitive id of the scene the
    probability of choosing it (0 for the rest), for the density of a BSDF ray that hits
    one."""

    primitives: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    v2: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    emission: np.ndarray
    material: np.ndarray
    textured: np.ndarray
    probability: np.ndarray
    cumulative: np.ndarray
    by_primitive: np.ndarray
    power: float


#: Barycentrics (b1, b2) at which a textured emitter's radiance is estimated for choosing
#: among triangles: the centroid and a point towards each corner, so that a two-triangle
#: plane under a checker is not judged dark by its centroids alone.
ESTIMATE_POINTS = ((1 / 3, 1 / 3), (1 / 6, 1 / 6), (2 / 3, 1 / 6), (1 / 6, 2 / 3))
#: A textured emitter's share of choice never falls below this fraction of its material's
#: mean radiance per area: where the estimate misses its light, the light samples still find
#: it (unbiased either way; this bounds the variance).
TEXTURED_FLOOR = 0.1


def _on_triangles(v0, v1, v2, b1, b2):
    """(3, k) the points of triangles (corners (3, k) each) at barycentrics (b1, b2) (k,)."""
    return v0 + b1 * (v1 - v0) + b2 * (v2 - v0)


def _unit_normals(v0, v1, v2):
    """((3, k) unit normals, (k,) twice the areas) of triangles (corners (3, k) each)."""
    cross = np.cross((v1 - v0).T, (v2 - v0).T).T
    double_area = np.sqrt((cross ** 2).sum(axis=0))
    return cross / np.where(double_area > 0, double_area, 1), double_area


def mesh_lights(triangles, sphere_count: int, emission_table: np.ndarray,
                textured_estimate=None):
    """The emitting triangles of ``triangles`` (``core.arrays.TriangleArrays``, global ids
    after ``sphere_count`` spheres) whose material's emission (``emission_table`` (3, M))
    is not black, or None.  textured_estimate: {material row: a function of (primitive
    (k,), barycentrics (b0, b1, b2) (k,) each, points (3, k), unit normals (3, k)) giving the
    emission (3, k) there, seen head-on} for the materials whose emission a program
    textures: every triangle of theirs may emit."""
    if triangles is None or len(triangles) == 0:
        return None
    textured_estimate = textured_estimate or {}
    emission = emission_table[:, triangles.material].astype(np.float64)
    textured = np.isin(triangles.material, list(textured_estimate))
    for material, estimate in textured_estimate.items():
        rows = np.flatnonzero(triangles.material == material)
        if len(rows) == 0:
            continue
        corners = tuple(v[:, rows] for v in (triangles.v0, triangles.v1, triangles.v2))
        normals, _ = _unit_normals(*corners)
        total = np.zeros((3, len(rows)))
        for b1, b2 in ESTIMATE_POINTS:
            b1, b2 = np.full(len(rows), b1), np.full(len(rows), b2)
            total += np.maximum(estimate(rows + sphere_count, (1 - b1 - b2, b1, b2),
                                         _on_triangles(*corners, b1, b2), normals), 0)
        total /= len(ESTIMATE_POINTS)
        mean = total.mean(axis=0)
        floor = TEXTURED_FLOOR * mean.mean() if mean.any() else 1.0
        emission[:, rows] = total + (np.maximum(mean, floor) - mean)
    emitting = np.flatnonzero((emission.max(axis=0) > 0) | textured)
    if len(emitting) == 0:
        return None
    v0, v1, v2 = (v[:, emitting] for v in (triangles.v0, triangles.v1, triangles.v2))
    normals, double_area = _unit_normals(v0, v1, v2)
    areas = 0.5 * double_area
    weight = areas * emission[:, emitting].mean(axis=0)
    if not weight.sum() > 0:
        return None
    probability = weight / weight.sum()
    by_primitive = np.zeros(sphere_count + len(triangles))
    primitives = emitting + sphere_count
    by_primitive[primitives] = probability
    return MeshLights(primitives, v0, v1, v2, normals, areas, emission[:, emitting],
                      triangles.material[emitting], textured[emitting],
                      probability, np.cumsum(probability), by_primitive,
                      float(np.pi * weight.sum()))


def sample_mesh_light(lights: MeshLights, points, u_pick, u1, u2,
                      textured=None) -> LightSample:
    """A point on an emitting triangle for each of k points.  textured: for ``lights``
    whose emission a program textures, a function of (primitive (m,), barycentrics (b0, b1,
    b2) (m,) each, points on the lights (3, m), their unit normals (3, m), unit incoming
    directions (3, m) (from the light towards the points), distances (m,)) giving the
    emission there (3, m), which the samples that land on textured triangles take."""
    dtype = points.dtype
    index = np.minimum(np.searchsorted(lights.cumulative, u_pick * lights.cumulative[-1],
                                       side="right"), len(lights.areas) - 1)
    root = np.sqrt(u1)
    b1, b2 = 1 - root, u2 * root
    v0, v1, v2 = (v[:, index].astype(dtype) for v in (lights.v0, lights.v1, lights.v2))
    target = _on_triangles(v0, v1, v2, b1, b2)
    towards, distance = normalize(target - points)
    normals = lights.normals[:, index].astype(dtype)
    cos_l = np.abs(dot(towards, normals))
    pdf = (lights.probability[index] / lights.areas[index]
           * distance * distance / np.maximum(cos_l, 1e-9)).astype(dtype)
    radiance = lights.emission[:, index].astype(dtype)
    rows = (np.flatnonzero(lights.textured[index]) if textured is not None
            else np.zeros(0, np.intp))
    if len(rows):
        radiance[:, rows] = textured(
            lights.primitives[index[rows]], (1 - b1[rows] - b2[rows], b1[rows], b2[rows]),
            target[:, rows], normals[:, rows], -towards[:, rows], lights.material[index[rows]],
            distance[rows])
    over = np.where(cos_l > 1e-9, radiance / pdf, 0)
    return LightSample(towards, distance, radiance, pdf, over)


def mesh_light_pdf(lights: MeshLights, primitive, t, cos_l):
    """(k,) the density in solid angle with which ``sample_mesh_light`` draws the points that
    BSDF rays hit on primitives (k,) at distances t (k,), cosines cos_l (k,) to their
    normals (0 for primitives that do not emit)."""
    chosen = lights.by_primitive[primitive]
    area = np.ones_like(chosen)
    emitting = chosen > 0
    if emitting.any():
        lookup = np.zeros(len(lights.by_primitive))
        lookup[lights.primitives] = lights.areas
        area = np.where(emitting, lookup[primitive], 1)
    return np.where(emitting, chosen / area * t * t / np.maximum(np.abs(cos_l), 1e-9), 0)


#: The largest map a world program is baked into for its sampling distribution.
WORLD_MAP_MAX = (1024, 512)
#: A world without an image of its own is baked at this size.
WORLD_MAP_DEFAULT = (256, 128)


@dataclass(frozen=True, eq=False)
class WorldLight:
    """A world whose radiance varies with direction (a program: an HDRI, a sky), as a light:
    directions drawn from ``environment`` (``core.environment.EnvironmentMap``, Cycles'
    background map, of the world baked at its resolution; a ``SunGuidedMap`` where a Sky
    Texture's sun is sampled on its own), its radiance the program's own value in each (so
    the map only steers the samples, exactly or not)."""

    environment: object
    power: float


def world_light(program, run_world, size=None) -> WorldLight:
    """The WorldLight of a world program: ``run_world(directions (3, n), program) -> (3, n)``
    the radiance of ``program`` (the world's, or a variant of it); size: (width, height) of
    the bake (None: ``WORLD_MAP_DEFAULT``).  A Sky Texture's sun disc (``shader.sky.
    world_sun``) is sampled on its own and left out of the bake, as in Cycles: a disc of
    half a degree would otherwise be a few cells of the map, or none."""
    from .environment import EnvironmentMap, SunGuidedMap, equirectangular_directions
    from .shader.sky import world_sun, without_sun_discs
    sun = world_sun(program)
    baked = program if sun is None else without_sun_discs(program)
    width, height = size or WORLD_MAP_DEFAULT
    width = max(8, min(int(width), WORLD_MAP_MAX[0]))
    height = max(4, min(int(height), WORLD_MAP_MAX[1]))
    rgb = np.empty((height, width, 3), np.float32)
    u = (np.arange(width) + 0.5) / width
    for row in range(0, height, 64):
        rows = np.arange(row, min(row + 64, height))
        v = 1 - (rows + 0.5) / height            # image row 0 looks up (+Z)
        directions = equirectangular_directions(np.tile(u, len(rows)), np.repeat(v, width))
        rgb[rows] = np.asarray(run_world(directions, baked), np.float32).T.reshape(
            len(rows), width, 3)
    rgb = np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0)
    environment = EnvironmentMap.from_array("world", rgb)
    sin_theta = np.sin(np.pi * (np.arange(height) + 0.5) / height)[:, None, None]
    power = float(np.abs(rgb * sin_theta).mean() * 2 * np.pi ** 2)
    if sun is not None:
        direction, half_angle = sun
        centre = direction[:, None]
        disc = np.abs(np.asarray(run_world(centre, program), np.float64)
                      - np.asarray(run_world(centre, baked), np.float64)).mean()
        # The disc's radiance at its centre over its solid angle, limb darkening's mean 0.8.
        power += float(np.nan_to_num(disc)) * 0.8 * 2 * np.pi * (1 - np.cos(half_angle))
        environment = SunGuidedMap(environment, direction, half_angle)
    return WorldLight(environment, power)
