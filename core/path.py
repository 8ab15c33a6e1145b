"""The physically based integrator: unidirectional path tracing with next-event estimation
and multiple importance sampling, in Cycles' units and with Cycles' Light Paths settings.

A bundle of camera rays (one sample of n pixels) is followed bounce by bounce, every path
of the bundle at once (a wavefront): nearest hits (``ctx.geometry.nearest``), the lights
the rays found on the way (``core.emitters.light_hit``) and the world where they escaped,
the surfaces' closures (``core.closures``), their emission, light samples with shadow rays
(``ctx.geometry.occluded``), then one BSDF sample per path that goes on.  Light reached
both ways is weighted by the power heuristic, so a small bright lamp is found by its
samples and a large dim one by the BSDF's.

Bounces follow Cycles (``path_state_next``): a transparent bounce counts only against
``transparent_bounces``; any other counts against ``max_bounces`` and its kind's limit
(diffuse, glossy, transmission).  A path past a limit still traces its next ray, which
collects only emission (so 0 bounces is direct light, from both of its estimators).
Russian roulette, at vertices two bounces or more from the camera (Cycles spares the
first), keeps a path with probability min(1, sqrt(max throughput)), as Cycles does.  Contributions are clamped as Cycles' film
clamps them (the sum of a sample's RGB, direct and indirect apart).

Alpha and holdouts follow ``core.trace``'s rules: a path is on the camera's view while it
went on from the camera only straight through Transparent BSDFs.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from . import closures as lobes
from .camera import CameraRays
from .bsdf import held_share
from .closures import Closures
from .emitters import (SAMPLED_EACH, LightSample, MeshLights, WorldLight, light_hit,
                       light_texture, mesh_light_pdf, sample_light, sample_mesh_light)
from .rays import RayBatch, RayStats, ray_offsets
from .sampler import bounce_groups, index_bits, sample_group
from .shader.input_nodes import (RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_REFLECT, RAY_SHADOW,
                                 RAY_SINGULAR, RAY_TRANSMIT, RAY_TRANSPARENT)
from .shader.program import run
from .surface_points import program_emission, surface_points
from .vectors import dot, facing, take

#: The golden ratio's fraction: successive lights at one vertex shift their sample numbers
#: by it, so that they do not all take the same point of their areas.
_GOLDEN = 0.6180339887498949


@dataclass
class PathResult:
    """colour (3, n) each sample's radiance; alpha (n,) 1 - what the camera's view let
    through (``core.trace``); albedo, normal (3, n): the first hit's albedo and shading
    normal (denoising's guides; 0 where the camera ray escaped)."""

    colour: np.ndarray
    alpha: np.ndarray
    albedo: np.ndarray
    normal: np.ndarray
    #: trace_paths(first_hits=True): each camera ray's first hit, (t, primitive, material)
    #: (n,) each (primitive and material -1 where the ray escaped), the passes' source.
    first_hits: tuple | None = None


#: What the Light Path node sees on a shadow ray, and where a light sample evaluates the
#: world (Cycles' emission evaluation: no ray type).
SHADOW_RAY = {"ray_type": RAY_SHADOW}
LIGHT_SAMPLE_RAY = {"ray_type": 0}
#: Bounces Russian roulette never ends a path at (Cycles' kernel min_bounce: the scene's
#: Min Light Bounces, 0 by default, plus one).
ROULETTE_SPARED_BOUNCES = 1


def _power_heuristic(a, b):
    """a^2 / (a^2 + b^2) per element (0 where both are 0; callers weigh delta lights, whose
    density is infinite, apart)."""
    with np.errstate(invalid="ignore", over="ignore"):
        a2, b2 = a * a, b * b
        total = a2 + b2
        return np.where(total > 0, a2 / np.where(total > 0, total, 1), 0)


def _clamp(values, limit: float):
    """Cycles' film clamp: a contribution (3, k) whose channels sum above three times the
    user's ``limit`` (0: no clamp; Cycles scales the setting by 3 so that it reads as a
    per-channel value for grey light) is scaled down to it."""
    if not limit > 0:
        return values
    limit = 3 * limit
    total = np.abs(values).sum(axis=0)
    return values * np.where(total > limit, limit / np.where(total > 0, total, 1), 1)


def _add(colour, path, values):
    """colour[:, path] += values (3, k), repeats of a path index all adding."""
    for row in range(3):
        colour[row] += np.bincount(path, values[row], colour.shape[1])


def closures_at(ctx, hits, normal, geometric, front, travelled=None, ray=None) -> Closures:
    """The closures of ``hits``: their materials' table rows, and where a material has a
    program (``PathSetup.programs``), its value at those hits (normals facing the ray);
    travelled: (k,) how far each hit's path has come (its footprint's growth); ray: what the
    Light Path node reads of the rays that found them ({'ray_type': codes, depths: (k,)
    each or a number}; None: camera rays), their lengths added here."""
    closures = Closures.from_table(ctx.physical.surfaces, hits.material)
    setup = ctx.paths
    if not setup.programs:
        return closures
    for material, program in setup.programs.items():
        rows = np.flatnonzero(hits.material == material)
        if len(rows) == 0:
            continue
        barycentrics = (None if hits.barycentrics is None
                        else tuple(b[rows] for b in hits.barycentrics))
        shading = take(normal, rows)
        footprint = None
        if travelled is not None:
            footprint = (setup.pixel_base + setup.pixel_spread * travelled[rows]).astype(
                ctx.dtype)
        found = None
        if ray is not None:
            found = {name: (values[rows] if np.ndim(values) else values)
                     for name, values in ray.items()}
            found["ray_length"] = hits.t[rows] * setup.surface_tables.world_scale
        points = surface_points(setup.surface_tables, ctx.geometry, take(hits.points, rows),
                                shading, take(geometric, rows), -take(hits.directions, rows),
                                ~front[rows], hits.primitive[rows], barycentrics, footprint,
                                found)
        value = run(program, points).closures(len(rows), ctx.dtype, shading)
        value.holdout_object = closures.holdout_object[rows]
        if value.normal is not None:
            value.smooth = shading
            if closures.normal is None:
                closures.normal = normal.copy()
                closures.smooth = normal.copy()
        closures.put(rows, value)
    return closures


def world_radiance(ctx, directions, ray=None) -> np.ndarray:
    """(3, k) the world's radiance along unit ``directions`` (3, k): its program's value
    there, or the constant background; ray: the Light Path node's coordinates of those
    rays (``closures_at``; None: camera rays)."""
    setup = ctx.paths
    if setup.world_program is None:
        return np.broadcast_to(setup.world.astype(directions.dtype)[:, None], directions.shape)
    from .shader.world import world_points
    value = run(setup.world_program, world_points(directions, ray))
    return np.broadcast_to(np.maximum(value.emission, 0), directions.shape).astype(
        directions.dtype)


def _transmittance(ctx, points, towards, distance, exclude, lift, stats):
    """(3, k) what reaches points (3, k) from along unit ``towards`` (k,) before ``distance``
    (k,) (inf: never): 1 where nothing is in the way, 0 where something opaque is, and
    where the scene may hold transparent surfaces (``PathSetup.transparent_shadows``) the
    product of their Transparent BSDF colours (Cycles' transparent shadows, up to its
    transparent bounces; glass and every other lobe block, as in Cycles).  exclude (k,): the
    primitive each ray ignores; lift: the points' ``TerminatorLift`` or None."""
    if ctx.paths.transparent_shadows:
        return _blocked(ctx, points, towards, distance, exclude, lift, stats, any_hit=False)
    open_ = ~_blocked(ctx, points, towards, distance, exclude, lift, stats)
    return np.broadcast_to(open_.astype(points.dtype), points.shape)


def _blocked(ctx, points, towards, distance, exclude, lift, stats, any_hit=True):
    """(k,) whether shadow rays from points (3, k) along unit ``towards`` are blocked before
    ``distance`` (k,) (inf: never), ignoring ``exclude`` (k,); ``lift`` the points'
    ``TerminatorLift`` or None.  Segments to a light stop short of it by the light's own
    offset, so an emitting triangle does not block its own light.  any_hit False: (3, k)
    the transmittance through transparent surfaces instead (``_transmittance``)."""
    offset = ray_offsets(points)
    reach = np.where(np.isfinite(distance), distance - ray_offsets(
        points + towards * np.where(np.isfinite(distance), distance, 0)), np.inf)
    origins = points
    exclusion = exclude
    if lift is not None:
        moved, lifted, ignored = lift.origins(points, towards, exclude)
        if len(moved):
            origins = points.copy()
            origins[:, moved] = lifted
            exclusion = exclude.copy()
            exclusion[moved] = ignored
    if any_hit:
        return ctx.geometry.occluded(
            RayBatch(origins, towards, offset, reach, None, exclusion, source=exclusion),
            stats)
    return _through_transparency(ctx, origins, towards, offset, reach, exclusion, stats)


def _through_transparency(ctx, origins, towards, offset, reach, exclude, stats):
    """(3, k) the transmittance of shadow segments through the surfaces they cross: each
    crossing multiplies by the hit's transparency (its closures, programs included), until
    the segment's end, an opaque hit, or the transparent bounce limit."""
    setup = ctx.paths
    k = towards.shape[1]
    dtype = towards.dtype
    result = np.ones((3, k), dtype)
    rows = np.arange(k)
    origins = np.broadcast_to(origins, towards.shape).copy()
    start = np.broadcast_to(np.asarray(offset, dtype), (k,)).copy()
    reach = np.broadcast_to(np.asarray(reach, dtype), (k,)).copy()
    exclude = np.broadcast_to(exclude, (k,)).copy()
    for _ in range(setup.transparent_bounces + 1):
        batch = RayBatch(origins, take(towards, rows), start, reach, None, exclude)
        stats.shadow_rays += len(rows)
        hits = ctx.geometry.nearest(batch, stats)
        if len(hits) == 0:
            return result
        front = hits.front
        normal = facing(hits.shading, front)
        closures = closures_at(ctx, hits, normal, facing(hits.normals, front), front,
                               ray=SHADOW_RAY)
        passed = closures.transparency
        # Only a surface that is nothing but transparent lets light through whole; any other
        # lobe's share blocks (Cycles' shadow rays see the transparent closure's weight).
        index = rows[hits.rays]
        result[:, index] *= passed
        going = np.flatnonzero(np.abs(passed).max(axis=0) > 0)
        if len(going) == 0:
            return result
        rows = index[going]
        points = take(hits.points, going)
        spawned = ctx.geometry.spawn(points, take(hits.normals, going), hits.primitive[going],
                                     take(towards, rows), ~front[going])
        origins = spawned.origins
        exclude = spawned.exclude
        start = np.zeros(len(rows), dtype)
        reach = reach[hits.rays[going]] - hits.t[going]
    result[:, rows] = 0     # past the transparent bounce limit: blocked
    return result


def _next_event(ctx, setup, closures, choice, points, normal, geometric, to_view, exclude,
                lift, u_light, u_pick, stats):
    """(3, k) the light the points receive by light samples: every light source when there
    are few (``SAMPLED_EACH``), else one chosen by power, each times the BSDF and the power
    heuristic against BSDF sampling.  exclude: (2, k) the primitive shadow rays ignore on
    the side the view is on and on the other (``Aggregate.exclusions``).  As in Cycles'
    ``bsdf_eval``, the BSDF sees a light sample by the shading normal alone, on either side
    of the geometric one: near a smooth mesh's terminator its shadow ray decides
    (``core.terminator``)."""
    k = points.shape[1]
    dtype = points.dtype
    total = np.zeros((3, k), dtype)
    sources = setup.sources
    if not sources or k == 0:
        return total
    if len(sources) <= SAMPLED_EACH:
        groups = [(i, np.arange(k), 1.0) for i in range(len(sources))]
    else:
        chosen = np.minimum(np.searchsorted(setup.source_cumulative, u_pick, side="right"),
                            len(sources) - 1)
        groups = [(i, np.flatnonzero(chosen == i), setup.source_probability[i])
                  for i in range(len(sources))]
    for i, rows, probability in groups:
        if len(rows) == 0:
            continue
        shift = (i * _GOLDEN) % 1.0
        u1 = (u_light[0][rows] + shift) % 1.0
        u2 = (u_light[1][rows] + shift * _GOLDEN) % 1.0
        where = take(points, rows)
        source = sources[i]
        if isinstance(source, MeshLights):
            sample = sample_mesh_light(source, where, (u_pick[rows] + shift) % 1.0, u1, u2,
                                       functools.partial(emission_at, ctx))
        elif isinstance(source, WorldLight):
            sample = _sample_world(ctx, source, u1, u2, dtype)
        else:
            sample = sample_light(source, where, u1, u2)
            if source.program is not None:
                textured = light_at(ctx, source, where, sample.towards, sample.distance)
                sample.radiance = sample.radiance * textured
                sample.over_pdf = sample.over_pdf * textured
        part = closures.take(rows)
        part_choice = choice.take(rows)
        shading = take(normal, rows)
        f, pdf = lobes.evaluate(part, part_choice, shading, take(to_view, rows),
                                sample.towards)
        above = dot(take(geometric, rows), sample.towards) > 0
        ignore = np.where(above, exclude[0][rows], exclude[1][rows])
        useful = np.flatnonzero((np.abs(f).max(axis=0) > 0)
                                & (np.abs(sample.over_pdf).max(axis=0) > 0))
        if len(useful) == 0:
            continue
        light_pdf = sample.pdf[useful] * probability
        weight = np.where(np.isinf(light_pdf), 1.0, _power_heuristic(light_pdf, pdf[useful]))
        contribution = f[:, useful] * sample.over_pdf[:, useful] * (weight / probability)
        passed = _transmittance(ctx, take(where, useful), take(sample.towards, useful),
                                sample.distance[useful], ignore[useful],
                                None if lift is None else lift.take(rows[useful]), stats)
        total[:, rows[useful]] += contribution * passed
    return total


def light_at(ctx, light, origins, towards, distance) -> np.ndarray:
    """(3, k) what a light's node tree (``core.emitters.light_texture``) gives at the points
    on it that origins (3, k) (the render's frame) see along unit ``towards`` (3, k) at
    ``distance`` (k,): a point light's surface faces what it lights, an area light's is its
    emitting side."""
    points = origins + towards * distance
    frame = ctx.paths.frame
    if frame is not None:        # (the program sees the scene in its own units)
        points = points / frame.scale + np.asarray(frame.centre, points.dtype)[:, None]
        distance = distance / frame.scale
    incoming = -towards
    if light.kind == "area":
        normal = np.repeat(light.direction.astype(points.dtype)[:, None], points.shape[1], 1)
    else:
        normal = incoming
    return light_texture(light, points, normal, incoming, distance)


def emission_at(ctx, primitive, barycentrics, points, normal, incoming, material, distance):
    """(3, k) the emission of the materials of table rows ``material`` (k,) at points (3, k)
    on triangles ``primitive`` (k,) at ``barycentrics`` (b0, b1, b2), unit normal (3, k),
    seen from unit ``incoming`` (3, k) (towards the viewer) at ``distance`` (k,): what a
    light sample finds there (Cycles evaluates an emitter's shader at the point its light
    sample chose)."""
    setup = ctx.paths
    radiance = np.zeros(points.shape, points.dtype)
    for row in np.unique(material):
        program = setup.programs.get(int(row))
        at = np.flatnonzero(material == row)
        if program is None:
            radiance[:, at] = ctx.physical.surfaces.emission[:, [row]]
            continue
        radiance[:, at] = program_emission(
            program, setup.surface_tables, ctx.geometry, take(points, at), take(normal, at),
            take(incoming, at), primitive[at], tuple(b[at] for b in barycentrics),
            dict(LIGHT_SAMPLE_RAY, ray_length=distance[at] * setup.surface_tables.world_scale))
    return radiance


def _sample_world(ctx, world: WorldLight, u1, u2, dtype) -> LightSample:
    """Directions towards a WorldLight drawn from its map, the world's radiance in each."""
    towards, pdf, _ = world.environment.sample(u1, u2)
    towards = towards.astype(dtype)
    radiance = world_radiance(ctx, towards, LIGHT_SAMPLE_RAY)
    pdf = pdf.astype(dtype)
    over = np.where(pdf > 0, radiance / np.where(pdf > 0, pdf, 1), 0)
    k = len(u1)
    return LightSample(towards, np.full(k, np.inf, dtype), radiance, pdf, over)


def trace_paths(ctx, rays: CameraRays, seeds, sample_index, stats: RayStats,
                first_hits: bool = False) -> PathResult:
    """Follow n camera rays (sample ``sample_index`` (n,) of the pixels whose sampler seeds
    are ``seeds`` (n,)) to the end of their paths (module docstring); first_hits: also
    return what the camera rays hit first (``PathResult.first_hits``)."""
    setup = ctx.paths
    settings = ctx.settings
    dtype = ctx.dtype
    geometry = ctx.geometry
    n = rays.directions.shape[1]
    bits = setup.index_bits
    colour = np.zeros((3, n), dtype)
    transparency = np.zeros(n, dtype)
    albedo = np.zeros((3, n), dtype)
    first_normal = np.zeros((3, n), dtype)
    film = settings.film

    path = np.arange(n)
    throughput = np.ones((3, n), dtype)
    bounce = np.zeros(n, np.int32)
    diffuse_bounce = np.zeros(n, np.int32)
    glossy_bounce = np.zeros(n, np.int32)
    transmission_bounce = np.zeros(n, np.int32)
    transparent_bounce = np.zeros(n, np.int32)
    last_pdf = np.zeros(n, dtype)          # 0: the ray came from the camera or a delta lobe
    camera_view = np.ones(n, bool)
    emission_only = np.zeros(n, bool)      # past a bounce limit: the next hit only emits
    by_diffuse = np.zeros(n, bool)         # the ray left a diffuse or translucent lobe
    min_pdf = np.full(n, np.inf, dtype)    # for Filter Glossy
    travelled = np.zeros(n, dtype)         # the path's length so far (ray footprints)
    ray_type = np.full(n, RAY_CAMERA, np.int64)   # the Light Path node's flags of the ray
    batch = RayBatch(rays.origins, rays.directions, rays.t_min, rays.t_max,
                     ctx.camera_origin if rays.shared_origin else None)
    stats.camera_rays += n
    clamp_direct, clamp_indirect = settings.clamp_direct, settings.clamp_indirect
    for depth in range(setup.max_vertices):
        hits = geometry.nearest(batch, stats)
        t_geometry = np.full(len(batch), np.inf, dtype)
        t_geometry[hits.rays] = hits.t
        if depth == 0 and first_hits:
            first = (t_geometry, np.full(n, -1, np.int64), np.full(n, -1, np.int64))
            first[1][hits.rays] = hits.primitive
            first[2][hits.rays] = hits.material
        seed = seeds[path]
        sample = sample_index[path]
        # Emission found by this depth's rays counts as the bounce before's light (Cycles'
        # ``bounce - 1``): direct for the camera's rays and those of the first hit.
        limit = clamp_direct if depth <= 1 else clamp_indirect
        # Lights found by rays that left surfaces (Blender's lights are hidden from the
        # camera's view, Object > Visibility > Camera off).
        if setup.visible_lights and not camera_view.all():
            ray_origins = np.broadcast_to(batch.origins, batch.directions.shape)
            for light in setup.visible_lights:
                found, t_light, radiance, pdf = light_hit(light, ray_origins,
                                                          batch.directions, t_geometry)
                found &= ~camera_view
                if not found.any():
                    continue
                index = np.flatnonzero(found)
                if light.program is not None:
                    directions = take(batch.directions, index)
                    radiance[:, index] *= light_at(ctx, light, take(ray_origins, index),
                                                   directions, t_light[index])
                weight = np.where(last_pdf[index] > 0, _power_heuristic(
                    last_pdf[index], pdf[index] * setup.light_probability[light]), 1.0)
                _add(colour, path[index], _clamp(throughput[:, index] * radiance[:, index]
                                                 * weight, limit))
        missed = np.flatnonzero(t_geometry == np.inf)
        if len(missed):
            escaped = missed[camera_view[missed]]
            if film != "opaque" and len(escaped):
                np.add.at(transparency, path[escaped], throughput[:, escaped].mean(axis=0))
            shown = missed[~camera_view[missed]] if film == "transparent" else missed
            if len(shown) and setup.world_shines:
                towards = take(batch.directions, shown)
                seen = world_radiance(ctx, towards, _ray_coordinates(
                    shown, ray_type, bounce, diffuse_bounce, glossy_bounce,
                    transmission_bounce, transparent_bounce))
                world = setup.world_light
                if world is not None:
                    # Weighted against the world's light samples, which could have found it.
                    light_pdf = (world.environment.pdf(towards).astype(dtype)
                                 * setup.light_probability[world])
                    before = last_pdf[shown]
                    seen = seen * np.where(before > 0, _power_heuristic(before, light_pdf),
                                           1.0)
                _add(colour, path[shown], _clamp(throughput[:, shown] * seen, limit))
        if len(hits) == 0:
            break
        keep = hits.rays
        path, throughput, seed, sample = path[keep], throughput[:, keep], seed[keep], sample[keep]
        bounce, last_pdf, camera_view = bounce[keep], last_pdf[keep], camera_view[keep]
        ray_type = ray_type[keep]
        emission_only, by_diffuse, min_pdf = emission_only[keep], by_diffuse[keep], min_pdf[keep]
        diffuse_bounce, glossy_bounce = diffuse_bounce[keep], glossy_bounce[keep]
        transmission_bounce, transparent_bounce = (transmission_bounce[keep],
                                                   transparent_bounce[keep])
        arrived_from = np.broadcast_to(batch.origins, batch.directions.shape)
        arrived_from = take(arrived_from, keep) if arrived_from.shape[1] > 1 else arrived_from
        points, directions, front = hits.points, hits.directions, hits.front
        normal = facing(hits.shading, front)
        geometric = facing(hits.normals, front)
        to_view = -directions
        travelled = travelled[keep] + hits.t
        closures = closures_at(ctx, hits, normal, geometric, front, travelled,
                               _ray_coordinates(slice(None), ray_type, bounce, diffuse_bounce,
                                                glossy_bounce, transmission_bounce,
                                                transparent_bounce)
                               if setup.programs else None)
        if closures.normal is not None:
            normal = closures.normal
        lobes.with_specular_normal(closures, geometric, to_view, normal)
        if depth == 0:
            first_normal[:, path] = normal
        # Holdouts on the camera's view.
        held = None
        if setup.any_holdout and camera_view.any():
            held = _hold_out(closures, camera_view, path, throughput, transparency)
        if held is not None:
            # An object holdout hides its shading and emission from the camera; only its
            # transparency lets the ray on (and may meet the object again behind).
            _only_transparency(closures, held)
        # Emission, weighted against the light samples that could have found it.
        emits = np.flatnonzero(np.abs(closures.emission).max(axis=0) > 0)
        if len(emits):
            weight = np.ones(len(emits), dtype)
            mesh = setup.mesh_lights
            if mesh is not None and depth > 0:
                light_pdf = mesh_light_pdf(mesh, hits.primitive[emits], hits.t[emits],
                                           dot(take(hits.normals, emits), take(directions, emits)))
                light_pdf = light_pdf * setup.light_probability[mesh]
                weight = np.where(last_pdf[emits] > 0,
                                  _power_heuristic(last_pdf[emits], light_pdf), 1.0)
            _add(colour, path[emits], _clamp(throughput[:, emits]
                                             * take(closures.emission, emits) * weight, limit))
        # Paths past their limits end here, after their emission; the rest may be cut by
        # Russian roulette.
        alive = ~emission_only
        # The vertex's choices: lobe, light, Russian roulette.
        choices = sample_group(seed, sample, bounce_groups(depth)[1], bits, dtype)
        if depth > 1:
            # Cycles' Russian roulette spares the first bounce (its kernel's min_bounce is
            # Min Light Bounces, 0, plus one): which matters where light is clamped.
            survive = np.minimum(np.sqrt(np.abs(throughput).max(axis=0)), 1.0)
            u_rr = choices[2]
            roulette = bounce > ROULETTE_SPARED_BOUNCES
            alive &= ~roulette | (u_rr < survive)
            throughput = np.where(roulette & (survive > 0), throughput
                                  / np.where(survive > 0, survive, 1), throughput)
        go = np.flatnonzero(alive)
        if len(go) == 0:
            break
        if len(go) < len(alive):
            path, throughput, seed, sample = path[go], throughput[:, go], seed[go], sample[go]
            bounce, camera_view, min_pdf = bounce[go], camera_view[go], min_pdf[go]
            last_pdf, travelled, choices = last_pdf[go], travelled[go], choices[:, go]
            ray_type = ray_type[go]
            by_diffuse = by_diffuse[go]
            diffuse_bounce, glossy_bounce = diffuse_bounce[go], glossy_bounce[go]
            transmission_bounce, transparent_bounce = (transmission_bounce[go],
                                                       transparent_bounce[go])
            points, directions, front = take(points, go), take(directions, go), front[go]
            normal, geometric, to_view = take(normal, go), take(geometric, go), take(to_view, go)
            closures = closures.take(go)
            primitive = hits.primitive[go]
            hit_normals = take(hits.normals, go)
            lift = None if hits.terminator is None else hits.terminator.take(go)
        else:
            primitive = hits.primitive
            hit_normals = hits.normals
            lift = hits.terminator
        _filter_closures(setup, closures, min_pdf, by_diffuse)
        choice = lobes.lobe_albedos(closures, normal, to_view, front)
        if depth == 0:
            albedo[:, path] = np.clip(choice.albedo.sum(axis=0), 0, 1)
        numbers = sample_group(seed, sample, bounce_groups(depth)[0], bits, dtype)
        if setup.sources:
            exclude = (geometry.exclusions(primitive, front),
                       geometry.exclusions(primitive, ~front))
            light = _next_event(ctx, setup, closures, choice, points, normal, geometric,
                                to_view, exclude, lift, numbers[2:4], choices[1], stats)
            _add(colour, path, _clamp(light * throughput,
                                      clamp_direct if depth == 0 else clamp_indirect))
        drawn = lobes.sample(closures, choice, normal, to_view, front, choices[0], numbers[0],
                             numbers[1])
        # The direction must leave on the side its lobe says, of the geometric normal too.
        side = dot(geometric, drawn.directions)
        ok = (drawn.lobe >= 0) & np.where(drawn.through, side < 0, side > 0)
        throughput = throughput * drawn.weight
        ok &= np.abs(throughput).max(axis=0) > 0
        go = np.flatnonzero(ok)
        if len(go) == 0:
            break
        lobe = drawn.lobe[go]
        transparent = lobe == lobes.TRANSPARENT
        ray_type = _next_ray_type(ray_type[go], lobe, drawn.through[go],
                                  closures.alpha[go] > lobes.DELTA_ALPHA)
        path, throughput, seed, sample = path[go], throughput[:, go], seed[go], sample[go]
        bounce, camera_view, min_pdf = bounce[go], camera_view[go], min_pdf[go]
        diffuse_bounce, glossy_bounce = diffuse_bounce[go], glossy_bounce[go]
        transmission_bounce, transparent_bounce = (transmission_bounce[go],
                                                   transparent_bounce[go])
        previous_pdf, travelled = last_pdf[go], travelled[go]
        pdf = drawn.pdf[go]
        through = drawn.through[go]
        # Counting bounces as Cycles does (its limits are the settings plus one).
        transparent_bounce = transparent_bounce + transparent
        solid = ~transparent
        bounce = bounce + solid
        diffuse = solid & ((lobe == lobes.DIFFUSE) | (lobe == lobes.TRANSLUCENT))
        glossy = solid & (lobe == lobes.GLOSSY)
        transmitted = solid & (lobe == lobes.TRANSMISSION)
        diffuse_bounce = diffuse_bounce + diffuse
        glossy_bounce = glossy_bounce + glossy
        transmission_bounce = transmission_bounce + transmitted
        emission_only = ((bounce > setup.max_bounces)
                         | (diffuse_bounce > setup.diffuse_bounces)
                         | (glossy_bounce > setup.glossy_bounces)
                         | (transmission_bounce > setup.transmission_bounces)
                         | (transparent_bounce > setup.transparent_bounces))
        camera_view = camera_view & transparent
        by_diffuse = diffuse
        # A transparent bounce keeps the density of the bounce before it: a light seen
        # through it is weighted as seen from there.
        last_pdf = np.where(transparent, previous_pdf, pdf)
        min_pdf = np.where(solid & (pdf > 0), np.minimum(min_pdf, pdf), min_pdf)
        leave = take(drawn.directions, go)
        leave_front = np.where(through, ~front[go], front[go])
        batch = geometry.spawn(take(points, go), take(hit_normals, go), primitive[go], leave,
                               leave_front)
        stats.reflection_rays += len(go)
    alpha = np.clip(1 - transparency, 0, 1)
    return PathResult(colour, alpha, albedo, first_normal, first if first_hits else None)


def _ray_coordinates(rows, ray_type, bounce, diffuse, glossy, transmission, transparent):
    """The Light Path node's coordinates of the rays ``rows``: their type flags and the
    path's bounces so far, as Cycles' ray depths count them."""
    return {"ray_type": ray_type[rows], "ray_depth": bounce[rows],
            "diffuse_depth": diffuse[rows], "glossy_depth": glossy[rows],
            "transmission_depth": transmission[rows], "transparent_depth": transparent[rows]}


def _next_ray_type(ray_type, lobe, through, rough):
    """The Light Path flags of the rays a vertex sends on (Cycles' ``path_state_next``): a
    transparent bounce keeps the ray's flags; any other lobe makes them its own (diffuse,
    glossy, or singular glossy for sharp mirrors and glass; reflect or transmit)."""
    diffuse = (lobe == lobes.DIFFUSE) | (lobe == lobes.TRANSLUCENT)
    glossy = (lobe == lobes.GLOSSY) | (lobe == lobes.TRANSMISSION)
    kind = np.where(diffuse, RAY_DIFFUSE, 0) | np.where(
        glossy, np.where(rough, RAY_GLOSSY, RAY_GLOSSY | RAY_SINGULAR), 0)
    kind |= np.where(through, RAY_TRANSMIT, RAY_REFLECT)
    return np.where(lobe == lobes.TRANSPARENT, ray_type | RAY_TRANSPARENT, kind)


def _filter_closures(setup, closures: Closures, min_pdf, by_diffuse) -> None:
    """Cycles' Filter Glossy (a path that took an unlikely direction blurs the glossy lobes
    it meets next: alpha >= sqrt(1 - filter min_pdf) / 2) and its caustics settings (glossy
    reflection, refraction, off at surfaces reached by a diffuse bounce), in place."""
    if setup.filter_glossy > 0:
        blur_pdf = setup.filter_glossy * min_pdf
        blurred = blur_pdf < 1
        if blurred.any():
            roughness = np.sqrt(np.clip(1 - blur_pdf, 0, 1)) * 0.5
            closures.alpha[:] = np.where(blurred, np.maximum(closures.alpha, roughness),
                                         closures.alpha)
    if by_diffuse.any():
        if not setup.caustics_reflective:
            closures.f0[:, by_diffuse] = 0
            closures.f90[:, by_diffuse] = 0
        if not setup.caustics_refractive:
            closures.transmission[:, by_diffuse] = 0


def _only_transparency(closures: Closures, rows) -> None:
    """Leave the closures of ``rows`` their transparency alone, in place (an object
    holdout's hits on the camera's view: what passes through it goes on)."""
    for name in ("diffuse", "f0", "f90", "transmission", "translucency", "emission"):
        getattr(closures, name)[:, rows] = 0
    closures.holdout[rows] = 0


def _hold_out(closures: Closures, camera_view, path, throughput, transparency):
    """Add what the holdouts on the camera's view take of their samples to transparency;
    the indices of hits whose shading the camera does not see (object holdouts), or None."""
    viewed = np.flatnonzero(camera_view)
    holdout = closures.holdout[viewed]
    whole = closures.holdout_object[viewed]
    if not (holdout.any() or whole.any()):
        return None
    held = held_share(holdout, whole, take(closures.transparency, viewed),
                      throughput[:, viewed])
    np.add.at(transparency, path[viewed], held)
    return viewed[whole] if whole.any() else None


@dataclass(frozen=True)
class PathSetup:
    """What the path integrator precomputes for a frame: the Light Paths limits, the light
    sources next-event estimation samples (``sources``: ``core.emitters.Light``s and the
    ``MeshLights``) with the probability of choosing each when there are many, the lights
    BSDF rays can find, the world's radiance, and the sampler's index bits."""

    max_bounces: int
    diffuse_bounces: int
    glossy_bounces: int
    transmission_bounces: int
    transparent_bounces: int
    filter_glossy: float
    caustics_reflective: bool
    caustics_refractive: bool
    sources: tuple
    source_probability: np.ndarray
    source_cumulative: np.ndarray
    visible_lights: tuple
    light_probability: dict
    mesh_lights: MeshLights | None
    world: np.ndarray
    any_holdout: bool
    index_bits: int
    programs: dict = None
    surface_tables: object = None
    world_program: object = None
    pixel_base: float = 0.0
    pixel_spread: float = 0.0
    world_light: object = None
    transparent_shadows: bool = False
    #: The ``core.frame.Frame`` that took the scene to the render's frame (passes'
    #: positions and depths go back through it), or None.
    frame: object = None

    @property
    def world_shines(self) -> bool:
        return self.world_program is not None or bool(self.world.any())

    @property
    def max_vertices(self) -> int:
        """An upper bound on the rays a path traces: every bounce and transparent bounce,
        and the last ray that collects emission only."""
        return self.max_bounces + self.transparent_bounces + 2


def path_setup(settings, lights, mesh, world, any_holdout: bool, programs=None,
               surface_tables=None, world_program=None, pixel=(0.0, 0.0),
               world_light=None, transparent_shadows: bool = False,
               frame=None) -> PathSetup:
    """The frame's ``PathSetup`` (settings: ``RenderSettings``; lights: prepared
    ``core.emitters.Light``s; mesh: ``MeshLights`` or None; world: (3,) radiance;
    programs: {material table row: its ShaderProgram}; surface_tables: what the programs'
    shading points read (``core.surface_points.SurfaceTables``); world_program: the
    world's ShaderProgram or None; pixel: (base, spread) of a ray's footprint, base +
    spread x distance travelled: a pixel's size on the view plane at unit depth is the
    perspective's spread, an orthographic pixel's size its base)."""
    sources = (tuple(lights) + ((mesh,) if mesh is not None else ())
               + ((world_light,) if world_light is not None else ()))
    power = np.array([max(source.power, 0.0) for source in sources]) if sources else np.zeros(0)
    if len(power) and power.sum() > 0:
        probability = power / power.sum()
    else:
        probability = np.full(len(sources), 1.0 / max(len(sources), 1))
    each = len(sources) <= SAMPLED_EACH
    light_probability = {source: (1.0 if each else float(p))
                         for source, p in zip(sources, probability)}
    return PathSetup(
        max_bounces=settings.max_bounces, diffuse_bounces=settings.diffuse_bounces,
        glossy_bounces=settings.glossy_bounces,
        transmission_bounces=settings.transmission_bounces,
        transparent_bounces=settings.transparent_bounces,
        filter_glossy=settings.filter_glossy,
        caustics_reflective=settings.caustics_reflective,
        caustics_refractive=settings.caustics_refractive,
        sources=sources, source_probability=probability,
        source_cumulative=np.cumsum(probability),
        visible_lights=tuple(light for light in lights if not light.delta),
        light_probability=light_probability, mesh_lights=mesh,
        world=np.asarray(world, np.float64), any_holdout=any_holdout,
        index_bits=index_bits(settings.samples), programs=dict(programs or {}),
        surface_tables=surface_tables, world_program=world_program,
        pixel_base=float(pixel[0]), pixel_spread=float(pixel[1]), world_light=world_light,
        transparent_shadows=transparent_shadows, frame=frame)


def filter_offsets(u, filter_type: str, width: float):
    """(k,) offsets from a pixel's centre, in pixels, with the density of Cycles' separable
    pixel filter of ``width`` (box, Gaussian or Blackman-Harris) for numbers u (k,) in
    [0, 1): the inverse of the filter's cumulative distribution, tabulated."""
    table = _filter_table(filter_type, float(width))
    return np.interp(u, np.linspace(0, 1, len(table)), table).astype(np.asarray(u).dtype)


_FILTER_TABLES: dict = {}
#: Entries of a filter's inverse distribution, as Cycles' FILTER_TABLE_SIZE.
FILTER_TABLE_SIZE = 1024


def _filter_table(filter_type: str, width: float) -> np.ndarray:
    """The inverse cumulative distribution of Cycles' filter (``film.cpp``'s filter table):
    a box over the width; a Gaussian over three times the width, exp(-2 (6 x / span)^2),
    so its standard deviation is a quarter of the width; Blackman-Harris over twice the
    width (Cycles widens both: their tails are thin)."""
    key = (filter_type, width)
    table = _FILTER_TABLES.get(key)
    if table is None:
        span = {"BLACKMAN_HARRIS": 2 * width, "GAUSSIAN": 3 * width}.get(filter_type, width)
        x = np.linspace(-0.5, 0.5, 4097) * span
        if filter_type == "BOX":
            weight = np.ones_like(x)
        elif filter_type == "GAUSSIAN":
            weight = np.exp(-2 * (6 * x / span) ** 2)
        else:
            t = np.linspace(0, 1, len(x))
            weight = (0.35875 - 0.48829 * np.cos(2 * np.pi * t)
                      + 0.14128 * np.cos(4 * np.pi * t) - 0.01168 * np.cos(6 * np.pi * t))
        cumulative = np.concatenate([[0], np.cumsum((weight[1:] + weight[:-1]) / 2)])
        cumulative /= cumulative[-1]
        table = np.interp(np.linspace(0, 1, FILTER_TABLE_SIZE), cumulative, x)
        _FILTER_TABLES[key] = table
    return table
