"""The Whitted integrator's shading of m hit points at a time, and light visibility: the
shading model of the default semantics (``WhittedShading``; the article's, every quirk kept,
is ``core.article.ArticleShading``, which shares its interface).

Every function takes the frame's ``core.context.TraceContext`` as ``ctx`` (which picks the
shading model, so this module does not import it).

Both semantics use the article's model: for each light,
``ka Ia + kd Id (L.N) + ks Is (N.H) ** (shininess / 4)``.

Default semantics, each of the article's quirks (``core.article``) fixed:
  * L.N and N.H are clamped at 0, and a light behind the surface adds no diffuse or
    specular (and so needs no shadow ray);
  * V points back along the incoming ray (where the light is seen from), not at the camera;
  * ambient ``ka (sum Ia + scene ambient)`` is kept in shadow, and shadow never ends a path;
  * shadow rays are exact segments P -> light that ignore the primitive P lies on where it
    cannot block them (a sphere's lit outside, any triangle: ``Aggregate.exclusions``), and
    stop short of P by an offset that scales with |P| (Mitsuba's (1 + max|P_i|) eps), never
    a fixed 1e-5;
  * a light with radius > 0 casts soft shadows: visibility is the fraction of
    ``light_samples`` points on its sphere that P sees.

Soft lights and the world are sampled in full at pixel centres; an anti-aliasing sample
traces only its share of their samples (``shares``: ``core.lights.SampleShares``), so that a
pixel of S samples traces about max(F, S) shadow rays per light of F samples, not S F.

Shadow rays are traced from the light towards the points: every shadow ray of a light then
shares one origin, so the geometry's terms are computed once per light, not once per ray.
Visibility is asked of the scene's aggregate (``ctx.geometry.occluded``), segment by segment,
a shading call's batches joined where the answers allow (``_blocked_each``: each trace has a
fixed cost, and an anti-aliasing round's share of one light sample is a few hundred rays).

Default semantics also shades Blender's lights in Cycles' units (``_shade_blender_lights``:
samples and irradiance from ``core.lights``, the surface's answer from ``core.bsdf``), for
SurfaceMaterials and the article's Materials alike; a sun's shadow rays, and the rays that
find how much of the world a point sees, leave the points instead.  Those are a stratified
grid of cosine-weighted directions in the point's normal frame, the grid shifted per pixel
(``core.lights.shifted_cosine_direction``, ``pixel_shifts``): one grid for every point made
an occluder cast k^2 sharp copies of its shadow on a flat surface and made a smooth mesh's
facets step, an error that stays where it is however large the area; shifted, the same rays
give noise, which averages out over neighbouring pixels and samples.  Adaptive
anti-aliasing allows for that noise where it looks for edges (``world_noise``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .bsdf import diffuse_seen, environment, light_response
from .lights import area_sample_irradiance, centre_irradiance
from .sampler import (SampleShares, cosine_directions, share_weights,
                      shifted_cosine_direction)
from .rays import RayBatch, RayStats, ray_offsets, timed
from .terminator import TerminatorLift
from .vectors import dot, normalize, normalize_in_place, take

#: One digit of a shadow code per light: unlit (0) or visibility 0, 1/4, .., 1 (1 .. 5).
SHADOW_CODE_BASE = 6


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
    """base ** n (m,) by repeated squaring, n >= 0 whole: the products of ``1 * base ** 2^i``
    in the order of the bits of n, each formed once (a leading 1 * x is x exactly)."""
    result = None
    square = base
    while n:
        if n & 1:
            if result is None:   # (never the caller's array: it is written into below)
                result = square.copy() if square is base else square
            else:
                np.multiply(result, square, out=result)
        n >>= 1
        if n:
            square = square * square
    return np.ones_like(base) if result is None else result


def specular_power(materials, exponents, base):
    """base ** the materials' exponents (m,) (``_power``), with one whole exponent shared by
    the material table (the article's) recognised once per call, not per point."""
    if len(exponents) and exponents.min() == exponents.max():
        first = float(exponents[0])
        if first.is_integer() and 0 <= first < 1024:
            return _whole_power(base, int(first))
    return _power(base, exponents.take(materials))


def light_blocked(ctx, origin, directions, distance, exclude, stats: RayStats,
                  *, end):
    """Whether the segments from a light sample towards m points are blocked, (m,) bool.

    origin: the sample's ``SharedOrigin`` (``ctx.lights.origins``).  directions: (3, m) unit
    vectors from the light towards the points; distance: (m,) how far the points are.
    Blocked if a primitive other than ``exclude`` (m,) (-1: none) is crossed in
    (0, distance - end), end (m,) the offset.  (The article's test:
    ``core.article.article_light_blocked``.)
    """
    light = origin.position[:, None]      # float64: the geometry's culling works in it
    segments = RayBatch(light, directions, 0.0, distance - end, origin, exclude)
    return ctx.geometry.occluded(segments, stats)


def traces_from_points(ctx) -> bool:
    """Whether the shading may trace occlusion rays that leave its hit points
    (``_rays_blocked``, which the aggregate answers by occlusion trails): a sun's and the
    world's (the physically based model's), and any light's from the lifted points of
    smooth triangles (``core.terminator``).  Every other shadow segment (the article's,
    a point, spot, sphere or area light sample's) leaves the light.  (None in article
    semantics: its hit rules lift nothing, ``HitRules.lifts_terminator``.)"""
    physical = ctx.physical
    world = traces_world_occlusion(ctx)
    if physical is not None and (world or any(light.kind == "sun"
                                              for light in physical.lights)):
        return True
    lit = len(ctx.lights) > 0 or (physical is not None and bool(physical.lights))
    return ctx.geometry.lifts_terminator and lit


def traces_world_occlusion(ctx) -> bool:
    """Whether the shading may trace the world's occlusion rays (``_world_occlusion``): the
    physically based model, a world that is not black, and ``_traces_world`` (so whether
    camera rays need their pixels' ``world_shift``)."""
    return (ctx.physical is not None and _traces_world(ctx)
            and bool(np.any(ctx.ambient)))


def _traces_world(ctx) -> bool:
    """Whether the physically based model traces the world's occlusion rays
    (``_world_occlusion``) where the world is not black: world samples asked for, and more
    than the one primitive a point lies on to block them."""
    return bool(ctx.settings.world_samples) and len(ctx.geometry) > 1


def shares_matter(ctx) -> bool:
    """Whether an anti-aliasing sample's share of the soft lights' samples (``shares`` of
    ``shade``) can change what it traces: not for Blinn-Phong when every light is a point
    (one sample each; in article semantics always: the article's lights are points); always
    assumed with the physically based model (its lights and the world's occlusion sample by
    shares).  Where it cannot, a pixel's centre is its AA sample 0 (``core.render``), and
    anti-aliasing samples trace every light sample (``core.tiles``)."""
    if ctx.physical is not None:
        return True
    return any(len(samples) > 1 for samples in ctx.lights.samples)


@timed("seconds_shading")
def shade(ctx, points, normals, directions, materials, exclude,
          stats: RayStats, *, shares: SampleShares | None = None,
          terminator: TerminatorLift | None = None, world_shift: np.ndarray | None = None,
          world_noise: np.ndarray | None = None):
    """(colour (3, m), goes_on (m,), shadow_code (m,) uint64) at m hit points: the default
    semantics' shading (``WhittedShading.shade``).

    goes_on: whether the path continues (article shadows end it).  shadow_code: which lights
    each point sees (a digit per light, soft visibility in quarters), so that adaptive
    anti-aliasing can find shadow edges.

    points, normals (shading normals, facing the incoming ray in default semantics),
    directions (incoming, unit): (3, m); materials: (m,) material ids (``ctx.materials``);
    exclude: (m,) the primitive each point's shadow segments ignore (-1: none;
    ``Aggregate.exclusions``), None in article semantics.  shares: which share of each soft
    light's samples (and of the world's directions) each point traces, for points reached by
    anti-aliasing samples (``core.lights.SampleShares``, m slots); None: all of them.
    terminator: where the points' shadow rays leave (``Hits.terminator``: points on smooth
    triangles leave from the smooth surface), None: from the points.  world_shift: (m, 2)
    how each point's pixel shifts the grid of the world's occlusion directions
    (``core.camera.CameraRays``), None: unshifted.  world_noise: (3, m) to add into, at
    points tracing every direction (``shares`` None), the standard deviation of their
    colour's estimate of the world's occlusion (binomial: the unoccluded term times
    sqrt(h' (1 - h') / k), h' about the share hidden, k the directions), which adaptive
    anti-aliasing's edge test allows for (``core.render``); or None.
    (Light through translucent surfaces: ``shade_translucent``.)
    """
    colour, goes_on, shadow_code = _shade_default(ctx, points, normals, directions, exclude,
                                                  materials, shares, stats, terminator)
    if ctx.physical is not None:
        blender_colour, shadow_code = _shade_blender_lights(ctx, points, normals, directions,
                                                            materials, exclude, shadow_code,
                                                            shares, stats,
                                                            terminator=terminator,
                                                            world_shift=world_shift,
                                                            world_noise=world_noise)
        colour += blender_colour
    return colour, goes_on, shadow_code


class WhittedShading:
    """The Whitted integrator's shading model in default semantics (module docstring):
    Blinn-Phong with the article's quirks fixed, plus the physically based model where
    ``ctx.physical`` is set.  Chosen once per frame (``TraceContext.shading``), as the
    geometry's hit rules are; ``core.article.ArticleShading`` overrides what differs."""

    #: Rays that escape see the scene's background (``trace_bundle``).
    sees_background = True
    #: Hits are shaded on the side the ray sees (a sphere's inside, a triangle's back), not
    #: on their outward normal's.
    shades_seen_side = True
    #: What a sample carries is a display value, clipped to [0, 1] sample by sample
    #: (``core.tiles``), rather than radiance.
    display_values = False
    #: (colour, goes_on, shadow_code) at m hit points: ``shade``'s arguments and answer.
    shade = staticmethod(shade)


WHITTED_SHADING = WhittedShading()


@timed("seconds_shading")
def shade_translucent(ctx, points, normals, directions, materials,
                      exclude_back, stats: RayStats, *, shares: SampleShares | None = None,
                      world_shift: np.ndarray | None = None,
                      world_noise: np.ndarray | None = None):
    """(radiance (3, m), shadow_code (m,) uint64) the translucent points pass through from
    their back hemisphere (``ctx.physical.translucent`` set; arguments as for ``shade``,
    with exclude_back the primitive each segment reaching a point through its surface
    ignores, ``Aggregate.exclusions`` of the other side; shadow_code: which lights each point
    sees through its surface, 0 for points that are not translucent): the Blender lights
    on the other side (shadow segments crossing the surface: a closed sphere's own far side
    blocks them, as in Cycles' direct light) and the world seen there, each times
    translucency / pi (``bsdf.translucent_view``)."""
    view = ctx.physical.translucent
    colour = np.zeros_like(points)
    shadow_code = np.zeros(points.shape[1], np.uint64)
    chosen = np.flatnonzero(view.diffuse[:, materials].max(axis=0) > 0)
    if len(chosen) == 0:
        return colour, shadow_code
    where, back = take(points, chosen), -take(normals, chosen)
    material, exclude = materials[chosen], exclude_back[chosen]
    shares = None if shares is None else shares.take(chosen)
    world_shift = None if world_shift is None else world_shift[chosen]
    light, shadow_code[chosen] = _shade_blender_lights(
        ctx, where, back, take(directions, chosen), material, exclude,
        np.zeros(len(chosen), np.uint64), shares, stats, surfaces=view, world_terms=False)
    world = column(ctx.ambient, points.dtype)
    if world.any():
        seen = 1.0
        if ctx.settings.world_samples:
            spread = None if world_noise is None else np.zeros(len(chosen), points.dtype)
            seen = 1 - _world_occlusion(ctx, where, back, material, ray_offsets(where), exclude,
                                        shares, stats, world_shift=world_shift, spread=spread)
            if spread is not None:
                world_noise[:, chosen] += take(view.diffuse, material) * world * spread
        light += take(view.diffuse, material) * world * seen
    colour[:, chosen] = light
    return colour, shadow_code


def column(values, dtype):
    """values (3,) as a (3, 1) column in ``dtype``, to broadcast over a (3, m) bundle."""
    return np.asarray(values, dtype)[:, None]


def _subset(weights, sample):
    """Indices (k,) of the points that trace sample ``sample`` (weights: (F, m) from
    ``share_weights``), or None when every point traces every sample (weights None)."""
    return None if weights is None else np.flatnonzero(weights[sample])


def _shade_default(ctx, points, normals, directions, exclude, materials, shares, stats,
                   terminator=None):
    """The default semantics' Blinn-Phong at m points (module docstring); each material's
    coefficient times a light's intensity comes from the table (``LightTerms``)."""
    lights = ctx.lights
    dtype = points.dtype
    m = points.shape[1]
    # ka (sum Ia + world), per material, then per point: the same products.
    colour = take(ctx.materials.ambient
                  * column(lights.ambient.sum(axis=0) + ctx.ambient, dtype), materials)
    shadow_code = np.zeros(m, np.uint64)
    offset = ray_offsets(points)
    exponents = ctx.materials.exponent
    for light in range(len(lights)):
        table = ctx.light_terms[light]
        from_light = points - column(lights.positions[light], dtype)
        distance = normalize_in_place(from_light)
        cos_light = -dot(normals, from_light)
        # No shadow ray where the light cannot add anything.
        lit = cos_light > 0
        lit &= table.reflective.take(materials)
        lit = np.flatnonzero(lit)
        shadow_code *= np.uint64(SHADOW_CODE_BASE)
        if len(lit) == 0:
            continue
        everywhere = len(lit) == m
        pick = (lambda a: a) if everywhere else (lambda a: take(a, lit))
        pick_row = (lambda a: a) if everywhere else (lambda a: a.take(lit))
        lit_points, lit_from_light = pick(points), pick(from_light)
        lit_lift = None if terminator is None else terminator.take(lit)
        visibility = np.ones(len(lit), dtype)
        samples = lights.samples[light]
        shared = None
        if shares is not None and len(samples) > 1:
            shared = share_weights(shares if everywhere else shares.take(lit), len(samples))
        traced = []     # per sample: (its index, rows of lit_points or None, rays)
        for index, (sample, origin) in enumerate(zip(samples, lights.origins[light])):
            part = _subset(shared, index)
            if len(samples) == 1:
                towards, reach = lit_from_light, pick_row(distance)
            elif part is None:
                towards, reach = normalize(lit_points - column(sample, dtype))
            else:
                towards, reach = normalize(take(lit_points, part) - column(sample, dtype))
            ahead = (lambda a: a) if part is None else (lambda a: a[part])
            ignored, ends = ahead(pick_row(exclude)), ahead(pick_row(offset))
            traced.append((index, part, _ShadowRays(towards, ignored, ends, origin=origin,
                                                    reach=reach)))
        flags = _blocked_each(ctx, lit_lift, lit_points,
                              [(part, rays) for _, part, rays in traced], stats)
        for (index, part, _), blocked in zip(traced, flags):
            if part is None:
                visibility -= blocked.astype(dtype) / len(samples)
            else:
                visibility[part] -= blocked * (shared[index, part] / len(samples))
        lit_normals = pick(normals)
        half = -pick(directions)
        half -= lit_from_light
        normalize_in_place(half)
        cos_half = np.maximum(dot(lit_normals, half), 0)
        lit_materials = pick_row(materials)
        spread = specular_power(lit_materials, exponents, cos_half)
        lit_cos = pick_row(cos_light)
        for row in range(3):
            # visibility (kd Id (L.N) + ks Is (N.H)^e)
            part = table.diffuse[row].take(lit_materials)
            part *= lit_cos
            specular = table.specular[row].take(lit_materials)
            specular *= spread
            part += specular
            part *= visibility
            if everywhere:
                colour[row] += part
            else:
                colour[row, lit] += part
        code = visibility * 4
        code = (np.round(code, out=code) + 1).astype(np.uint64)
        if everywhere:
            shadow_code += code
        else:
            shadow_code[lit] += code
    return colour, np.ones(m, bool), shadow_code


def _rays_blocked(ctx, points, towards, offset, reach, exclude, stats):
    """(m,) whether rays from the points along unit ``towards`` (3, m) hit anything between
    ``offset`` and ``reach`` (m,) (np.inf: a sun, the world).  Rays leaving one primitive
    (``exclude``, the primitive each ray ignores) in one direction cell are culled together,
    as the bounce loop's reflection rays are; the aggregate stops each at its first blocker."""
    return ctx.geometry.occluded(
        RayBatch(points, towards, offset, reach, None, exclude, source=exclude), stats)


def _cols(a, index):
    """Columns ``index`` of a (3, k) bundle (all of it for None)."""
    return a if index is None else take(a, index)


def _rows(a, index):
    """Entries ``index`` of a (k,) array (all of it for None)."""
    return a if index is None else a[index]


@dataclass(frozen=True)
class _ShadowRays:
    """k shadow rays of the default semantics, as a light's visibility traces them: either
    from one light sample's shared origin towards k points (``origin`` its SharedOrigin,
    ``directions`` (3, k) unit vectors from the light, ``reach`` (k,) the points' distances,
    segments ending ``offsets`` short of them), the same from several light samples
    (``lights`` (3, k) float64 each ray's sample, no shared origin: ``_blocked_each``), or
    from k points (``starts`` (3, k)) along unit ``directions`` towards a direction's light
    (a sun, the world: unbounded), leaving ``offsets`` (k,) off them.  ``exclude`` (k,):
    the primitive each ray ignores."""
    directions: np.ndarray
    exclude: np.ndarray
    offsets: np.ndarray
    starts: np.ndarray = None
    origin: object = None
    reach: np.ndarray = None
    lights: np.ndarray = None

    @property
    def from_light(self) -> bool:
        """Whether the rays leave light samples (else the points)."""
        return self.reach is not None

    @property
    def to_light(self) -> np.ndarray:
        """(3, k) unit directions from the points towards the light."""
        return -self.directions if self.from_light else self.directions

    def targets(self, index, dtype) -> np.ndarray:
        """The light samples' positions (3, 1) or (3, k') in ``dtype`` of rays ``index``
        (k',), for rays leaving light samples."""
        if self.origin is not None:
            return np.asarray(self.origin.position, dtype)[:, None]
        return take(self.lights, index).astype(dtype, copy=False)

    def blocked(self, ctx, stats, index=None) -> np.ndarray:
        """Whether rays ``index`` (k',) (None: all k) are blocked, traced as they are laid
        out: from the light sample's shared origin, from the light samples, or from the
        points."""
        if self.origin is not None:
            return light_blocked(ctx, self.origin, _cols(self.directions, index),
                                 _rows(self.reach, index), _rows(self.exclude, index), stats,
                                 end=_rows(self.offsets, index))
        if self.lights is not None:
            # (As ``light_blocked`` traces a sample's segments, each from its own sample.)
            return ctx.geometry.occluded(
                RayBatch(_cols(self.lights, index), _cols(self.directions, index), 0.0,
                         _rows(self.reach, index) - _rows(self.offsets, index), None,
                         _rows(self.exclude, index)), stats)
        return _rays_blocked(ctx, _cols(self.starts, index), _cols(self.directions, index),
                             _rows(self.offsets, index), np.inf, _rows(self.exclude, index),
                             stats)

    def leaving_samples(self) -> "_ShadowRays":
        """These rays from a shared origin, as rays that each leave their own sample."""
        count = len(self.exclude)
        return dataclasses.replace(self, origin=None, lights=np.repeat(
            np.asarray(self.origin.position, np.float64)[:, None], count, axis=1))


def _segments_blocked(ctx, terminator, points, rows, rays: _ShadowRays, stats):
    """(k,) whether the shadow rays ``rays`` of points ``rows`` (k,) of ``points`` (3, m)
    (None: all m) are blocked, those of points on smooth triangles lifted off their facets
    (``core.terminator``: ``terminator`` is the m points' TerminatorLift, or None) and traced
    from the lifted points; the others as ``rays`` lays them out."""
    if terminator is None:
        return rays.blocked(ctx, stats)
    to_light = rays.to_light
    lift = terminator if rows is None else terminator.take(rows)
    starts = points if rows is None else take(points, rows)
    moved, origins, ignored = lift.origins(starts, to_light, rays.exclude)
    if len(moved) == 0:
        return rays.blocked(ctx, stats)
    blocked = np.zeros(len(rays.exclude), bool)
    stay = np.ones(len(rays.exclude), bool)
    stay[moved] = False
    stay = np.flatnonzero(stay)
    if len(stay):
        blocked[stay] = rays.blocked(ctx, stats, stay)
    if rays.from_light:
        along, reach = normalize(rays.targets(moved, origins.dtype) - origins)
    else:
        along, reach = take(to_light, moved), np.inf
    blocked[moved] = _rays_blocked(ctx, origins, along, ray_offsets(origins), reach, ignored,
                                   stats)
    return blocked


#: ``_blocked_each`` joins a shading call's small batches of shadow rays into batches of up
#: to this many rays: the join's gain is in the traces it saves (a particle scene's world
#: rays replayed: 447 batches of 386 rays 2.10 s, joined 64 at a time 0.48 s, all in one
#: 0.46 s), while the 9 world batches of a 16,384-pixel tile with anti-aliasing off, joined,
#: made the point-cloud and instancing scenes 4-6 % slower through F12 (larger temporaries).
JOINED_SHADOW_RAYS = 16384


def _blocked_each(ctx, terminator, points, batches: list, stats) -> list:
    """Whether each ray of several batches of one shading call is blocked: batches
    [(rows (k_i,) of ``points`` (3, m) or None, _ShadowRays)] -> [(k_i,) bool]
    (``_segments_blocked``).  Each of the aggregate's traces has a fixed cost, which an
    anti-aliasing round's share of one light sample or direction (a few hundred rays) does
    not repay: consecutive batches of rays leaving the points are joined, up to
    JOINED_SHADOW_RAYS rays, and so are those of rays leaving light samples whose shared
    origin the aggregate would not use for them (``Aggregate.segments_need_origin``: the
    answers are the same); the rest go batch by batch, from their shared origins."""
    flags = [None] * len(batches)
    runs = {False: [[]], True: [[]]}    # from the points, from light samples: runs to join
    filled = {False: 0, True: 0}        # rays in each kind's last run
    for i, (rows, rays) in enumerate(batches):
        count, kind = len(rays.exclude), rays.from_light
        if rays.origin is not None and ctx.geometry.segments_need_origin(count):
            flags[i] = _segments_blocked(ctx, terminator, points, rows, rays, stats)
            continue
        if runs[kind][-1] and filled[kind] + count > JOINED_SHADOW_RAYS:
            runs[kind].append([])
            filled[kind] = 0
        runs[kind][-1].append(i)
        filled[kind] += count
    for from_light, members in ((kind, run) for kind, kinds in runs.items() for run in kinds):
        if len(members) == 1:
            rows, rays = batches[members[0]]
            flags[members[0]] = _segments_blocked(ctx, terminator, points, rows, rays, stats)
        elif members:
            for i, part in zip(members, _joined_blocked(ctx, terminator, points,
                                                        [batches[i] for i in members],
                                                        from_light, stats)):
                flags[i] = part
    return flags


def _joined_blocked(ctx, terminator, points, batches: list, from_light: bool, stats) -> list:
    """``_blocked_each``'s flags of batches [(rows, _ShadowRays)] traced as one: all from the
    points, or (from_light) all from light samples, each ray from its own."""
    parts = [rays for _, rays in batches]
    if from_light:
        parts = [rays if rays.origin is None else rays.leaving_samples() for rays in parts]
    every = np.arange(points.shape[1])
    rows = _batched([every if rows is None else rows for rows, _ in batches])
    joined = _ShadowRays(
        _batched([rays.directions for rays in parts]),
        _batched([rays.exclude for rays in parts]),
        _batched([rays.offsets for rays in parts]),
        starts=None if from_light else _batched([rays.starts for rays in parts]),
        reach=_batched([rays.reach for rays in parts]) if from_light else None,
        lights=_batched([rays.lights for rays in parts]) if from_light else None)
    blocked = _segments_blocked(ctx, terminator, points, rows, joined, stats)
    return np.split(blocked, np.cumsum([len(rays.exclude) for rays in parts])[:-1])


def _world_occlusion(ctx, points, normals, materials, offset, exclude, shares, stats,
                     terminator=None, world_shift=None, spread=None):
    """(m,) the cosine-weighted share of the world hidden from each point (0 for the
    article's Materials), from ``world_samples`` directions of a stratified grid turned into
    each point's normal frame, the grid shifted by the point's pixel (``world_shift`` (m, 2),
    ``core.lights.shifted_cosine_direction``; None: unshifted).  The ambient term
    (``_shade_default``) adds diffuse x world unoccluded; this share of it is taken back.
    With ``shares`` (anti-aliasing samples of S per pixel) the directions are
    max(world_samples, S), each point tracing its share of them.  spread: (m,) to fill, for
    points tracing every direction, with the share's binomial standard deviation
    sqrt(h' (1 - h') / k), h' = (k h + 1) / (k + 2) (``shade``'s world_noise)."""
    physical = ctx.physical.surfaces.physical[materials]
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
    count = ctx.settings.world_samples
    if shares is not None:
        count = max(count, shares.count)
    directions = cosine_directions(count).astype(points.dtype)
    shift = None if world_shift is None else world_shift[chosen]
    origins = take(points, chosen)
    lift = None if terminator is None else terminator.take(chosen)
    shared = None if shares is None else share_weights(shares.take(chosen), len(directions))
    batches = []     # per direction traced: (its index, rows of ``origins`` or None, rays)
    for index, (x, y, z) in enumerate(directions):
        part = _subset(shared, index)
        if part is not None and len(part) == 0:
            continue
        if shift is not None:
            x, y, z = shifted_cosine_direction(
                count, index, shift if part is None else shift[part]).astype(points.dtype)
        if part is None:
            along, rows, starts = x * first + y * second + z * n, chosen, origins
        else:
            along = x * take(first, part) + y * take(second, part) + z * take(n, part)
            rows, starts = chosen[part], take(origins, part)
        batches.append((index, part, _ShadowRays(along, exclude[rows], offset[rows], starts)))
    flags = _blocked_each(ctx, lift, origins, [(part, rays) for _, part, rays in batches],
                          stats)
    for (index, part, _), blocked in zip(batches, flags):
        if part is None:
            hidden[chosen] += blocked / len(directions)
        else:
            hidden[chosen[part]] += blocked * (shared[index, part] / len(directions))
    if spread is not None and shared is None:
        # The share's standard deviation from its own estimate, as if one more ray each way
        # had been traced (Laplace's rule): a point none of whose k rays were blocked can
        # still be partly hidden, and its neighbour's one blocked ray is no edge.
        k = len(directions)
        share = (hidden[chosen] * k + 1) / (k + 2)
        spread[chosen] = np.sqrt(share * (1 - share) / k)
    return hidden


def _batched(parts: list) -> np.ndarray:
    """One array of parts (k_i,) or bundles (3, k_i) laid end to end (the part itself when
    there is one)."""
    if len(parts) == 1:
        return parts[0]
    return np.concatenate(parts, axis=parts[0].ndim - 1)


def _sphere_sample_weights(light, towards):
    """(S, m) weights of a sphere light's samples for points seeing its centre along unit
    ``towards`` (3, m): n_j . w on the hemisphere facing each point, normalised to sum 1
    (``core.lights``); None for lights without a radius."""
    if light.sample_normals is None:
        return None
    weights = np.maximum(-(light.sample_normals.astype(towards.dtype) @ towards), 0)
    return weights / weights.sum(axis=0)


def _shade_blender_lights(ctx, points, normals, directions, materials, exclude, shadow_code,
                          shares, stats, surfaces=None, world_terms=True, terminator=None,
                          world_shift=None, world_noise=None):
    """(radiance (3, m), shadow_code) from Blender's lights (``core.lights``) and the world's
    glossy, emitted and occluded terms (``core.bsdf``) at m points, default semantics.

    materials: (m,) material ids; exclude: (m,) the primitive each point's rays ignore.
    Each light appends a digit to ``shadow_code`` for adaptive anti-aliasing: not reached,
    blocked, partly visible or visible.  (Not quarters of visibility as for the article's
    lights: an area light's penumbra changes smoothly from pixel to pixel, and every pixel of
    it would count as an edge.)  surfaces: the lobes to shade with (default: the model's);
    world_terms: False leaves the world's terms out; terminator, world_shift, world_noise:
    as for ``shade``."""
    physical = ctx.physical
    surfaces = physical.surfaces if surfaces is None else surfaces
    dtype = points.dtype
    m = points.shape[1]
    to_view = -directions
    world = column(ctx.ambient if world_terms else np.zeros(3), dtype)
    colour = np.zeros((3, m), dtype)
    colour += environment(surfaces, materials, normals, to_view, world)
    offset = ray_offsets(points)
    if world.any() and _traces_world(ctx):
        seen_diffuse = diffuse_seen(surfaces, materials, np.clip(dot(normals, to_view), 0, 1))
        spread = None if world_noise is None else np.zeros(m, dtype)
        colour -= _world_occlusion(ctx, points, normals, materials, offset, exclude, shares,
                                   stats, terminator, world_shift, spread) * (seen_diffuse * world)
        if spread is not None:
            world_noise += spread * (seen_diffuse * world)
    for light in physical.lights:
        scale = column(light.scale, dtype)
        shadow_code = shadow_code * np.uint64(SHADOW_CODE_BASE)
        visibility = np.zeros(m, dtype)
        reached = np.zeros(m, bool)
        if light.kind == "area":
            count = len(light.terms)
            shared = None if shares is None else share_weights(shares, count)
            traced = []     # per sample traced: (sample, lit, local, towards, e, rays)
            for sample, origin in enumerate(light.terms):
                part = _subset(shared, sample)
                if part is None:
                    towards, distance, e = area_sample_irradiance(light, sample, points,
                                                                  normals)
                    lit = np.flatnonzero(e > 0)
                else:
                    towards, distance, e = area_sample_irradiance(
                        light, sample, take(points, part), take(normals, part))
                    inside = np.flatnonzero(e > 0)
                    lit = part[inside]
                    towards, distance, e = take(towards, inside), distance[inside], e[inside]
                    e = e * shared[sample, lit]
                if len(lit) == 0:
                    continue
                reached[lit] = True
                local = lit if part is None else np.arange(len(lit))   # into towards, e
                to_light, reach = take(towards, local), distance[local]
                ignored, ends = exclude[lit], offset[lit]
                traced.append((sample, lit, local, towards, e,
                               _ShadowRays(-to_light, ignored, ends, origin=origin,
                                           reach=reach)))
            flags = _blocked_each(ctx, terminator, points,
                                  [(lit, rays) for _, lit, _, _, _, rays in traced], stats)
            for (sample, lit, local, towards, e, _), blocked in zip(traced, flags):
                seen, seen_local = lit[~blocked], local[~blocked]
                visibility[seen] += (1 if shared is None else shared[sample, seen]) / count
                colour[:, seen] += scale * light_response(
                    surfaces, materials[seen], take(normals, seen), take(to_view, seen),
                    take(towards, seen_local), e[seen_local])
        else:
            towards, distance, e = centre_irradiance(light, points, normals)
            lit = np.flatnonzero(e > 0)
            if len(lit) == 0:
                continue
            reached[lit] = True
            lit_points, lit_towards = take(points, lit), take(towards, lit)
            lit_lift = None if terminator is None else terminator.take(lit)
            weights = _sphere_sample_weights(light, lit_towards)
            shared = None
            if shares is not None and len(light.samples) > 1:
                shared = share_weights(shares.take(lit), len(light.samples))
                if weights is not None:
                    weights, shared = weights * shared, None
            # Per sample traced: (rows of lit_points or None, rays, and the visibility each
            # open ray adds: an array, or None for 1 / the sample count).
            traced = []
            for sample, position in enumerate(light.samples):
                if weights is not None:
                    facing = np.flatnonzero(weights[sample] > 0)
                    from_sample, reach = normalize(take(lit_points, facing)
                                                   - column(position, dtype))
                    ignored, ends = exclude[lit[facing]], offset[lit[facing]]
                    traced.append((facing, _ShadowRays(from_sample, ignored, ends,
                                                       origin=light.terms[sample], reach=reach),
                                   weights[sample, facing]))
                    continue
                if shared is not None:   # a sun's share of its directions
                    part = np.flatnonzero(shared[sample])
                    rows = lit[part]
                    along = np.repeat(position.astype(dtype)[:, None], len(part), axis=1)
                    starts, ignored, offsets = take(lit_points, part), exclude[rows], offset[rows]
                    traced.append((part, _ShadowRays(along, ignored, offsets, starts),
                                   shared[sample, part] / len(light.samples)))
                    continue
                ignored, ends = exclude[lit], offset[lit]
                if light.kind == "sun":
                    along = (lit_towards if len(light.samples) == 1 else
                             np.repeat(position.astype(dtype)[:, None], len(lit), axis=1))
                    rays = _ShadowRays(along, ignored, ends, lit_points)
                else:
                    rays = _ShadowRays(-lit_towards, ignored, ends, origin=light.terms[sample],
                                       reach=distance[lit])
                traced.append((None, rays, None))
            flags = _blocked_each(ctx, lit_lift, lit_points,
                                  [(rows, rays) for rows, rays, _ in traced], stats)
            for (rows, _, adds), blocked in zip(traced, flags):
                if adds is None:
                    visibility[lit] += (~blocked) / len(light.samples)
                else:
                    visibility[lit[rows]] += (~blocked) * adds
            seen = lit[visibility[lit] > 0]
            colour[:, seen] += scale * visibility[seen] * light_response(
                surfaces, materials[seen], take(normals, seen), take(to_view, seen),
                take(towards, seen), e[seen])
        shadow_code += np.select([~reached, visibility <= 0, visibility < 1 - 1e-6],
                                 [0, 1, 2], 3).astype(np.uint64)
    return colour, shadow_code
