"""Blinn-Phong shading and light visibility, for m shaded points at a time.

Both semantics use the article's model: for each light,
``ka Ia + kd Id (L.N) + ks Is (N.H) ** (shininess / 4)``.

Article semantics, every quirk kept:
  * dot products are not clamped (a point facing away from the light gets negative diffuse);
  * H = normalize(L + V) with V towards the CAMERA position, on every bounce;
  * the shadow ray starts at P + 1e-5 N and the point is in shadow if a sphere is hit (both
    roots positive) nearer than |light - P|; a shadowed point adds nothing, not even ambient,
    and ends the path (with several lights: a light that is blocked adds nothing, and the path
    ends where every light is blocked);
  * the lights' radii are ignored (the article's light is a point).

Default semantics, each quirk fixed:
  * L.N and N.H are clamped at 0, and a light behind the surface adds no diffuse or
    specular (and so needs no shadow ray);
  * V points back along the incoming ray (where the light is seen from), not at the camera;
  * ambient ``ka (sum Ia + scene ambient)`` is kept in shadow, and shadow never ends a path;
  * shadow rays are exact segments P -> light that ignore the sphere P lies on when P faces
    outward (a convex sphere cannot block its own lit side), and stop short of P by an
    offset that scales with |P| (Mitsuba's (1 + max|P_i|) eps), never a fixed 1e-5;
  * a light with radius > 0 casts soft shadows: visibility is the fraction of
    ``light_samples`` points on its sphere that P sees.

Shadow rays are traced from the light towards the points: every shadow ray of a light then
shares one origin, so the sphere terms are computed once per light, not once per ray.

Default semantics also shades Blender's lights in Cycles' units (``_shade_blender_lights``:
samples and irradiance from ``core.lights``, the surface's answer from ``core.bsdf``), for
SurfaceMaterials and the article's Materials alike; a sun's shadow rays leave the points.
"""

from __future__ import annotations

import numpy as np

from .bsdf import environment, light_response
from .context import ARTICLE_OFFSET, RayStats, TraceContext, ray_offsets
from .lights import area_sample_irradiance, centre_irradiance, cosine_directions
from .cull import (DENSE_CANDIDATES, REFLECTION_CELLS, SHADOW_CELLS, candidate_roots,
                   direction_cells)
from .vectors import dot, length, normalize, take

#: One digit of a shadow code per light: unlit (0) or visibility 0, 1/4, .., 1 (1 .. 5).
_CODE_BASE = 6


def _power(base, exponent):
    """base ** exponent per element (m,); a negative base with a non-integer exponent gives 0,
    not NaN.  A whole exponent shared by every element (the article's 25) is computed by
    repeated squaring, several times faster than pow and exact in sign for negative bases."""
    first = exponent[0] if len(exponent) else 0
    if len(exponent) and float(first).is_integer() and 0 <= first < 1024 \
            and (exponent == first).all():
        return _whole_power(base, int(first))
    with np.errstate(invalid="ignore"):
        result = np.power(base, exponent)
    return np.where(np.isnan(result), 0, result)


def _whole_power(base, n: int):
    result = np.ones_like(base)
    square = base
    while n:
        if n & 1:
            result = result * square
        n >>= 1
        if n:
            square = square * square
    return result


def light_blocked(ctx: TraceContext, terms, origin, directions, distance, exclude,
                  stats: RayStats, *, start=None, end=None):
    """Whether the segments from a light sample towards m points are blocked, (m,) bool.

    terms: OriginTerms at ``origin`` (3,), the light sample.  directions: (3, m) unit vectors
    from the light towards the points; distance: (m,) how far the points are.  Default
    semantics: blocked if a sphere other than ``exclude`` (m,) (-1: none) is crossed in
    (0, distance - end), end (m,) the offset.  Article semantics (the points are the shifted
    points S, start (m,) = |light - P|): blocked if the reversed ray S -> light has both roots
    positive and its nearer one below ``start``.
    """
    m = directions.shape[1]
    blocked = np.zeros(m, bool)
    if m == 0:
        return blocked
    stats.shadow_rays += m
    # All rays leave the light: packing them by direction makes each packet a narrow cone.
    key = direction_cells(directions, SHADOW_CELLS) if len(ctx.radii) > DENSE_CANDIDATES else None
    for block in candidate_roots(ctx.centers, ctx.radii, ctx.clusters, origin[:, None],
                                 directions, distance, terms, article=ctx.article,
                                 stats=stats, key=key):
        t_near, t_far, valid = block.t_near, block.t_far, block.valid
        reach = block.per_pair(distance)
        if ctx.article:
            hit = valid & (t_far < reach) & (t_far > reach - block.per_pair(start))
        else:
            limit = reach - block.per_pair(end)
            hit = valid & (((t_near > 0) & (t_near < limit)) | ((t_far > 0) & (t_far < limit)))
            if exclude is not None:
                hit &= block.spheres != block.per_pair(exclude)
        blocked[block.rays] |= block.any(hit)
    return blocked


def shade(ctx: TraceContext, points, normals, directions, spheres, front, stats: RayStats):
    """(colour (3, m), goes_on (m,), shadow_code (m,) uint64) at m hit points.

    goes_on: whether the path continues (article shadows end it).  shadow_code: which lights
    each point sees (a digit per light, soft visibility in quarters), so that adaptive
    anti-aliasing can find shadow edges.

    points, normals (facing the incoming ray in default semantics), directions (incoming,
    unit): (3, m); spheres: (m,) scene indices; front: (m,) True where the ray hit the outside.
    """
    mat = ctx.materials
    ka, kd, ks = take(mat.ambient, spheres), take(mat.diffuse, spheres), take(mat.specular, spheres)
    exponent = mat.exponent.take(spheres)
    if ctx.article:
        return _shade_article(ctx, points, normals, ka, kd, ks, exponent, stats)
    colour, goes_on, shadow_code = _shade_default(ctx, points, normals, directions, spheres,
                                                  front, ka, kd, ks, exponent, stats)
    if ctx.look is not None and ctx.look.active:
        blender_colour, shadow_code = _shade_blender_lights(ctx, points, normals, directions,
                                                            spheres, front, shadow_code, stats)
        colour += blender_colour
    return colour, goes_on, shadow_code


def _column(values, dtype):
    return np.asarray(values, dtype)[:, None]


def _shade_default(ctx, points, normals, directions, spheres, front, ka, kd, ks, exponent,
                   stats):
    lights = ctx.arrays.lights
    dtype = points.dtype
    m = points.shape[1]
    colour = ka * _column(lights.ambient.sum(axis=0) + ctx.arrays.ambient, dtype)
    exclude = np.where(front, spheres, -1)
    shadow_code = np.zeros(m, np.uint64)
    offset = ray_offsets(points)
    for light in range(len(lights)):
        strength_d = _column(lights.diffuse[light], dtype)
        strength_s = _column(lights.specular[light], dtype)
        from_light, distance = normalize(points - _column(lights.positions[light], dtype))
        cos_light = -dot(normals, from_light)
        # No shadow ray where the light cannot add anything.
        reflective = (dot(kd, strength_d) > 0) | (dot(ks, strength_s) > 0)
        lit = np.flatnonzero((cos_light > 0) & reflective)
        shadow_code *= np.uint64(_CODE_BASE)
        if len(lit) == 0:
            continue
        everywhere = len(lit) == m
        pick = (lambda a: a) if everywhere else (lambda a: take(a, lit))
        pick_row = (lambda a: a) if everywhere else (lambda a: a.take(lit))
        lit_points, lit_from_light = pick(points), pick(from_light)
        visibility = np.ones(len(lit), dtype)
        samples = ctx.light_samples[light]
        for sample, terms in zip(samples, ctx.light_terms[light]):
            if len(samples) == 1:
                towards, reach = lit_from_light, pick_row(distance)
            else:
                towards, reach = normalize(lit_points - _column(sample, dtype))
            blocked = light_blocked(ctx, terms, sample, towards, reach, pick_row(exclude),
                                    stats, end=pick_row(offset))
            visibility -= blocked.astype(dtype) / len(samples)
        lit_normals = pick(normals)
        half, _ = normalize(-pick(directions) - lit_from_light)
        cos_half = np.maximum(dot(lit_normals, half), 0)
        light_colour = visibility * (
            pick(kd) * strength_d * pick_row(cos_light)
            + pick(ks) * strength_s * _power(cos_half, pick_row(exponent)))
        if everywhere:
            colour += light_colour
            shadow_code += (1 + np.round(visibility * 4)).astype(np.uint64)
        else:
            colour[:, lit] += light_colour
            shadow_code[lit] += (1 + np.round(visibility * 4)).astype(np.uint64)
    return colour, np.ones(m, bool), shadow_code


def _shade_article(ctx, points, normals, ka, kd, ks, exponent, stats):
    lights = ctx.arrays.lights
    dtype = points.dtype
    m = points.shape[1]
    shifted = points + ARTICLE_OFFSET * normals
    to_camera, _ = normalize(_column(ctx.eye, dtype) - points)
    colour = np.zeros_like(points)
    goes_on = np.zeros(m, bool)
    shadow_code = np.zeros(m, np.uint64)
    for light in range(len(lights)):
        position = _column(lights.positions[light], dtype)
        from_light, shifted_distance = normalize(shifted - position)
        blocked = light_blocked(ctx, ctx.light_terms[light][0], lights.positions[light],
                                from_light, shifted_distance, None, stats,
                                start=length(position - points))
        # H = normalize(to_light + to_camera), with to_light = -from_light.
        half, _ = normalize(to_camera - from_light)
        term = (ka * _column(lights.ambient[light], dtype)
                - kd * _column(lights.diffuse[light], dtype) * dot(from_light, normals)
                + ks * _column(lights.specular[light], dtype) * _power(dot(normals, half),
                                                                       exponent))
        unblocked = ~blocked
        colour += term * unblocked
        goes_on |= unblocked
        shadow_code = shadow_code * np.uint64(_CODE_BASE) + unblocked.astype(np.uint64)
    return colour, goes_on, shadow_code


def _rays_blocked(ctx, points, towards, offset, reach, exclude, stats, leaving=None):
    """(m,) whether rays from the points along unit ``towards`` (3, m) hit a sphere between
    ``offset`` and ``reach`` (m,) (np.inf: a sun).  leaving: (m,) the sphere each ray leaves;
    with many spheres, rays leaving one sphere in one direction cell are culled together
    (as the bounce loop's reflection rays are)."""
    from .trace import nearest_sphere  # the bounce loop's query; trace imports this module

    stats.shadow_rays += points.shape[1]
    key = None
    if leaving is not None and len(ctx.radii) > DENSE_CANDIDATES:
        key = (leaving * (6 * REFLECTION_CELLS ** 2)
               + direction_cells(towards, REFLECTION_CELLS))
    _, sphere = nearest_sphere(ctx, points, towards, offset, reach, exclude, stats, key=key)
    return sphere >= 0


def _sphere_sample_weights(light, towards):
    """(S, m) weights of a sphere light's samples for points seeing its centre along unit
    ``towards`` (3, m): n_j . w on the hemisphere facing each point, normalised to sum 1
    (``core.lights``); None for lights without a radius."""
    if light.sample_normals is None:
        return None
    weights = np.maximum(-(light.sample_normals.astype(towards.dtype) @ towards), 0)
    return weights / weights.sum(axis=0)


def _world_occlusion(ctx, points, normals, spheres, offset, exclude, stats):
    """(m,) the cosine-weighted share of the world hidden from each point by spheres (0 for
    the article's Materials), from ``world_samples`` fixed directions turned into each
    point's normal frame.  The ambient term (``_shade_default``) adds diffuse x world
    unoccluded; this share of it is taken back."""
    physical = ctx.look.surfaces.physical[spheres]
    hidden = np.zeros(points.shape[1], points.dtype)
    chosen = np.flatnonzero(physical)
    if len(chosen) == 0:
        return hidden
    n = take(normals, chosen)
    zero = np.zeros_like(n[0])
    first = np.where(np.abs(n[0]) < 0.9, np.stack([zero, n[2], -n[1]]),
                     np.stack([-n[2], zero, n[0]]))
    first, _ = normalize(first)
    second = np.stack([n[1] * first[2] - n[2] * first[1], n[2] * first[0] - n[0] * first[2],
                       n[0] * first[1] - n[1] * first[0]])
    directions = cosine_directions(ctx.settings.world_samples).astype(points.dtype)
    origins = take(points, chosen)
    for x, y, z in directions:
        along = x * first + y * second + z * n
        blocked = _rays_blocked(ctx, origins, along, offset[chosen], np.inf, exclude[chosen],
                                stats, leaving=spheres[chosen])
        hidden[chosen] += blocked / len(directions)
    return hidden


def _shade_blender_lights(ctx, points, normals, directions, spheres, front, shadow_code, stats):
    """(radiance (3, m), shadow_code) from Blender's lights (``core.lights``) and the world's
    glossy and emitted terms (``core.bsdf``) at m points, default semantics.

    Each light appends a digit to ``shadow_code`` (its visibility in quarters, as the
    article's lights do) for adaptive anti-aliasing."""
    look = ctx.look
    surfaces = look.surfaces
    dtype = points.dtype
    m = points.shape[1]
    to_view = -directions
    world = _column(ctx.arrays.ambient, dtype)
    colour = np.zeros((3, m), dtype)
    colour += environment(surfaces, spheres, normals, to_view, world)
    exclude = np.where(front, spheres, -1)
    offset = ray_offsets(points)
    if ctx.settings.world_samples and world.any() and len(ctx.radii) > 1:
        colour -= _world_occlusion(ctx, points, normals, spheres, offset, exclude, stats) * (
            take(surfaces.diffuse, spheres) * world)
    for light in look.lights:
        scale = _column(light.scale, dtype)
        shadow_code = shadow_code * np.uint64(_CODE_BASE)
        visibility = np.zeros(m, dtype)
        if light.kind == "area":
            for sample, terms in enumerate(light.terms):
                towards, distance, e = area_sample_irradiance(light, sample, points, normals)
                lit = np.flatnonzero(e > 0)
                if len(lit) == 0:
                    continue
                blocked = light_blocked(ctx, terms, light.samples[sample], -take(towards, lit),
                                        distance[lit], exclude[lit], stats, end=offset[lit])
                seen = lit[~blocked]
                visibility[seen] += 1 / len(light.terms)
                colour[:, seen] += scale * light_response(
                    surfaces, spheres[seen], take(normals, seen), take(to_view, seen),
                    take(towards, seen), e[seen])
        else:
            towards, distance, e = centre_irradiance(light, points, normals)
            lit = np.flatnonzero(e > 0)
            if len(lit) == 0:
                continue
            lit_points, lit_towards = take(points, lit), take(towards, lit)
            weights = _sphere_sample_weights(light, lit_towards)
            for sample, position in enumerate(light.samples):
                if weights is not None:
                    facing = np.flatnonzero(weights[sample] > 0)
                    from_sample, reach = normalize(take(lit_points, facing)
                                                   - _column(position, dtype))
                    blocked = light_blocked(ctx, light.terms[sample], position, from_sample,
                                            reach, exclude[lit[facing]], stats,
                                            end=offset[lit[facing]])
                    visibility[lit[facing]] += weights[sample, facing] * ~blocked
                    continue
                if light.kind == "sun":
                    along = (lit_towards if len(light.samples) == 1 else
                             np.repeat(position.astype(dtype)[:, None], len(lit), axis=1))
                    blocked = _rays_blocked(ctx, lit_points, along, offset[lit], np.inf,
                                            exclude[lit], stats, leaving=spheres[lit])
                else:
                    if len(light.samples) == 1:
                        from_sample, reach = -lit_towards, distance[lit]
                    else:
                        from_sample, reach = normalize(lit_points - _column(position, dtype))
                    blocked = light_blocked(ctx, light.terms[sample], position, from_sample,
                                            reach, exclude[lit], stats, end=offset[lit])
                visibility[lit] += (~blocked) / len(light.samples)
            seen = lit[visibility[lit] > 0]
            colour[:, seen] += scale * visibility[seen] * light_response(
                surfaces, spheres[seen], take(normals, seen), take(to_view, seen),
                take(towards, seen), e[seen])
        shadow_code += (1 + np.round(visibility * 4)).astype(np.uint64)
    return colour, shadow_code
