"""The tile kernel: a tile of the image rendered by either integrator (``render_tile``).

The path integrator's tiles are its progressive passes (``render_path_tile``).  The Whitted
integrator's anti-aliasing happens inside a tile: 'fixed' traces every pixel with ``samples``
stratified sub-pixel positions; 'adaptive' traces the tile and a two-pixel apron at pixel
centres, picks the pixels whose path signature (the surfaces hit and the shadows met at every
bounce) differs from a 4-neighbour's where the colour steps by more than EDGE_CONTRAST (or by
more than LINE_CONTRAST anywhere), and supersamples those in rounds: FIRST_SAMPLES samples,
then twice as many while their estimated error exceeds SAMPLE_ERROR, up to ``samples``.
Every array a tile creates is proportional to its pixel count, never to the image's.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import time
from typing import Optional

import numpy as np

from .camera import BlenderCamera, camera_rays, camera_to_world, has_aperture
from .colour import linear_to_srgb
from .context import RayStats, TraceContext
from .failures import RenderCancelled
from .geometry.cull import PACKET_SIZE
from .memory import GUIDE_CHANNELS
from .passes import PASS_CHANNELS, first_hit_channels
from .path import filter_offsets, trace_paths
from .progressive import GUIDE_SUM_CHANNELS, SUM_CHANNELS
from .sampler import (PIXEL_GROUP, SampleShares, pixel_seeds, pixel_shares, pixel_shifts,
                      sample_group)
from .shading import shares_matter, traces_world_occlusion
from .trace import trace_bundle

#: Tiles are traced in BLOCK x BLOCK pixel blocks: one culling packet each.
BLOCK = math.isqrt(PACKET_SIZE)
#: Adaptive AA supersamples a pixel whose path signature differs from a 4-neighbour's only
#: where the colour also *steps* between their centres by more than this: the difference of
#: their display values (``_display``: sRGB-encoded radiance or the article's values, and
#: alpha) that the colour's slope on either side (the next pixels' differences along the same
#: line) does not explain, in some channel.  Why a step, and why this much: a pixel's
#: anti-aliased value is the mean over its area; where the colour across it is a gradient
#: (a lit floor's falloff, however many facets it has) that mean is the centre's value, and
#: where it steps by s somewhere in the pixel the mean is off the centre's by at most s (s / 2
#: for a step through the middle).  So a pixel whose steps to every neighbour are at most
#: EDGE_CONTRAST errs by at most 2 of the 256 levels of an 8-bit image, about what an eye can
#: tell between two neighbouring pixels.  Silhouettes step in alpha (0 against 1) and are
#: always kept; a thin feature steps on both sides.  Without it, a backdrop of many flat
#: facets of nearly one orientation (``Aggregate.surface_keys`` keys each facet) is an "edge"
#: at every pixel.
EDGE_CONTRAST = 2 / 255
#: A step this large is an edge even where the signatures agree: a feature thinner than a
#: pixel on one surface (a highlight's or a reflection's bright line, a reflected sphere) that
#: the centres catch on one row or column only.  Well above what a facet backdrop or a smooth
#: gradient steps (those are EDGE_CONTRAST's case).  On the bench's dense field (10,000
#: spheres, 640x360) it adds 2 % of the pixels and removes 70 % of the error the unsampled
#: pixels left.
LINE_CONTRAST = 16 / 255
#: Where pixel centres' colours carry the world's occlusion noise (its directions are shifted
#: per pixel, ``core.lights.shifted_cosine_direction``), a step between two of them counts
#: only beyond this many standard deviations of that noise on each side
#: (``trace.BundleResult.world_noise``): without it every crease of a smooth mesh and every
#: facet of a backdrop under a bright world stepped by more than EDGE_CONTRAST somewhere,
#: and adaptive AA took the corpus' tineler_scenes_cubes to 32 % of its pixels (8.4 % with
#: the directions the same for every pixel).
NOISE_ALLOWANCE = 2.0
#: Staged supersampling: an edge pixel first gets FIRST_SAMPLES samples (its centre is the
#: first of them), then twice as many, and so on up to ``samples``, only while its estimated
#: error exceeds SAMPLE_ERROR (4 of the 256 levels of an 8-bit image).  The estimate after n
#: samples: the larger of the range of their display values (``_display``, any channel) and
#: the colour step its centre makes to a neighbour (``_edges``), over n: about how far the
#: mean of n well-spread samples can be off where an edge of that contrast crosses the
#: pixel.  The step term keeps a high-contrast edge from stopping because its first samples
#: fell on one side of it.  Tuned on the bench's article scene (whose adaptive 16 must still
#: reach fixed 16's error: 0.625 against 0.628 RMS 8-bit steps at 640x360) and its dense field.
FIRST_SAMPLES = 4
SAMPLE_ERROR = 4 / 255
#: Pixels of centres traced around a tile for adaptive AA: its neighbours, and theirs for the
#: slopes EDGE_CONTRAST compares with.
APRON = 2


def sample_offsets(count: int) -> np.ndarray:
    """count sub-pixel positions (count, 2) in [0, 1)^2: the R2 low-discrepancy sequence
    (Roberts 2018), deterministic, well spread for any count; the first is the centre."""
    g = 1.32471795724474602596
    k = np.arange(count)[:, None]
    return (0.5 + k * np.array([1 / g, 1 / (g * g)])) % 1.0

def _trace_positions(ctx: TraceContext, camera, xs, ys, stats, lens=None, shares=None,
                     stop=None):
    """(rgb (n, 3), alpha (n,), signature (n,), noise (n, 3) or None) for sample positions
    xs, ys (n,); rgb clipped to [0, 1] per sample in article semantics, unclipped radiance
    otherwise; noise: the standard deviation of rgb's world occlusion
    (``trace.BundleResult.world_noise``); lens: aperture positions (2, n) for a thin-lens
    camera; shares: the soft lights' sample shares of anti-aliasing samples
    (``core.lights.pixel_shares``), None at pixel centres; stop: ``trace_bundle``'s."""
    start = time.perf_counter()
    rays = camera_rays(camera, xs, ys, ctx.dtype, lens)
    if shares is not None:
        rays = dataclasses.replace(rays, shares=shares)
    if traces_world_occlusion(ctx):
        rays = dataclasses.replace(rays, world_shift=pixel_shifts(np.floor(xs), np.floor(ys)))
    traced = time.perf_counter()
    result = trace_bundle(ctx, rays, stats, stop=stop)
    stats.seconds_camera += traced - start
    stats.seconds_bounces += time.perf_counter() - traced
    rgb = result.colour.T
    if ctx.shading.display_values:   # in place (np.clip's wrapper costs ~30 us a bundle)
        np.minimum(np.maximum(rgb, 0, out=rgb), 1, out=rgb)
    noise = None if result.world_noise is None else result.world_noise.T
    return rgb, result.alpha, result.signature, noise


def _pixel_grid(y0, y1, x0, x1):
    """(cols, rows) (n,) of the pixels of a region, in BLOCK x BLOCK block order, so that the
    tracer's packets of consecutive rays cover square blocks (``core.geometry.cull``)."""
    cols, rows, _ = _block_order(y1 - y0, x1 - x0)
    return cols + x0, rows + y0


@functools.lru_cache(maxsize=16)
def _block_order(h, w):
    """(cols, rows, inverse) (h w,) for an h x w region at the origin: its pixels in block
    order (``_pixel_grid``), and for each pixel in row-major order its place in that order
    (``_assemble``).  Every full tile has the same: computed once (read-only)."""
    blocks_y, blocks_x = -(-h // BLOCK), -(-w // BLOCK)
    rows, cols = np.mgrid[0:blocks_y * BLOCK, 0:blocks_x * BLOCK]

    def in_blocks(grid):
        return grid.reshape(blocks_y, BLOCK, blocks_x, BLOCK).transpose(0, 2, 1, 3).ravel()

    rows, cols = in_blocks(rows), in_blocks(cols)
    inside = (rows < h) & (cols < w)
    cols, rows = cols[inside], rows[inside]
    inverse = np.empty(h * w, np.intp)
    inverse[rows * w + cols] = np.arange(h * w)
    for array in (cols, rows, inverse):
        array.flags.writeable = False
    return cols, rows, inverse


def _assemble(rgba, rgb, coverage):
    """Fill a tile's rgba (h, w, 4) from rgb (n, 3) and coverage (n,) in block order: a
    gather per channel through ``_block_order``'s inverse, several times cheaper than
    scattering through (rows, cols)."""
    h, w = rgba.shape[:2]
    inverse = _block_order(h, w)[2]
    flat = rgba.reshape(h * w, 4)
    for channel in range(3):
        flat[:, channel] = rgb[:, channel].take(inverse)
    flat[:, 3] = coverage.take(inverse)


def _scatter(values, cols, rows, x0, y0, shape):
    """Values (n, ...) of pixels (cols, rows) as a (h, w, ...) grid whose corner is (x0, y0)."""
    grid = np.empty(shape + values.shape[1:], values.dtype)
    grid[rows - y0, cols - x0] = values
    return grid


def _sample_bundles(ctx, camera, cols, rows, count, ks, stats, stop=None):
    """Trace samples ``ks`` (k,) of the ``sample_offsets(count)`` sequence in each pixel
    (cols, rows) (n,), yielding (part (a slice of the n pixels), rgb (p, k, 3), hit (p, k))
    bundle by bundle.

    A pixel's samples are traced side by side (so packets stay coherent), in bundles of at
    most tile_size^2 rays so memory stays bounded by the tile.  Each sample traces its share
    of the soft lights' samples (``core.lights.pixel_shares``: sample k of a pixel has the
    same slot whichever other samples are traced with it), so a pixel traces about as many
    shadow rays per light as its centre alone would; with an aperture each sample has its
    lens position (``lens_samples``)."""
    offsets = sample_offsets(count)[ks]
    n, k = len(cols), len(ks)
    aperture = has_aperture(camera)
    per_bundle = max(1, ctx.settings.tile_size ** 2 // k)
    for first in range(0, n, per_bundle):
        if stop is not None and stop.is_set():
            raise RenderCancelled("render cancelled")
        part = slice(first, first + per_bundle)
        xs = (cols[part, None] + offsets[None, :, 0]).ravel()
        ys = (rows[part, None] + offsets[None, :, 1]).ravel()
        lens = lens_samples(cols[part], rows[part], offsets) if aperture else None
        # (Per bundle: its memory.  None where they change nothing, ``shares_matter``.)
        shares = pixel_shares(cols[part], rows[part], count) if shares_matter(ctx) else None
        if shares is not None and k < count:
            shares = SampleShares(shares.slot.reshape(-1, count)[:, ks].ravel(), count)
        colour, hit, _, _ = _trace_positions(ctx, camera, xs, ys, stats, lens, shares, stop)
        yield part, colour.reshape(-1, k, 3), hit.reshape(-1, k)


def _supersample(ctx, camera, cols, rows, count, stats, stop=None):
    """Mean (rgb (n, 3), coverage (n,)) over ``count`` samples in each pixel (cols, rows)
    (``_sample_bundles``)."""
    rgb = np.empty((len(cols), 3), ctx.dtype)
    coverage = np.empty(len(cols), ctx.dtype)
    for part, colour, hit in _sample_bundles(ctx, camera, cols, rows, count,
                                             np.arange(count), stats, stop):
        rgb[part] = colour.mean(axis=1)
        coverage[part] = hit.mean(axis=1)
    stats.supersampled_pixels += len(cols)
    return rgb, coverage


def lens_samples(cols, rows, offsets) -> np.ndarray:
    """(2, n * count) aperture positions in [0, 1)^2 for ``count`` samples in each pixel
    (cols, rows) (n,): the pixel offsets' sequence with its axes swapped (so a sample's lens
    position is not its pixel position), shifted per pixel by an R2 point of the pixel's own
    index (Cranley-Patterson rotation), so neighbouring pixels do not repeat one pattern."""
    g = 1.32471795724474602596
    index = (rows.astype(np.float64) * 7919.0 + cols)[:, None]
    shift = (index * np.array([1 / g, 1 / (g * g)])) % 1.0            # (n, 2)
    lens = (offsets[None, :, ::-1] + shift[:, None, :]) % 1.0           # (n, count, 2)
    return lens.reshape(-1, 2).T


def _display(ctx: TraceContext, rgb, coverage) -> np.ndarray:
    """(n, 4) the display values (RGB, 1 at white, and alpha) that adaptive AA compares
    (EDGE_CONTRAST): the article's values, or radiance through the sRGB curve up to 1 and
    1 + ln(radiance) / 2.4 above it (the curve's own slope at 1, continued in stops as
    view transforms such as AgX and Filmic show highlights: an edge between two highlights
    stays an edge, while a highlight's smooth gradient counts no more than a midtone's)."""
    if ctx.shading.display_values:
        display = rgb
    else:
        radiance = np.maximum(rgb, 0)
        display = np.where(radiance <= 1, linear_to_srgb(np.minimum(radiance, 1)),
                           1 + np.log(np.maximum(radiance, 1)) / 2.4)
    return np.concatenate([display, coverage[:, None]], axis=1)


def _steps(display: np.ndarray, axis: int) -> np.ndarray:
    """How much the colour steps between neighbours along ``axis`` (0: rows, 1: columns) of
    display values (h, w, 4): each difference less the nearer of its two neighbouring
    differences along the same line (the slope on either side; none past the image's
    border), largest over the channels; shape (h - 1, w) or (h, w - 1)."""
    difference = np.diff(display, axis=axis)
    pad = [(0, 0)] * difference.ndim
    pad[axis] = (1, 1)
    padded = np.pad(difference, pad, constant_values=np.inf)
    count = difference.shape[axis]
    before = np.take(padded, np.arange(count), axis=axis)
    after = np.take(padded, np.arange(2, count + 2), axis=axis)
    with np.errstate(invalid="ignore"):
        unexplained = np.minimum(np.abs(difference - before), np.abs(difference - after))
    return unexplained.max(axis=-1)


def _edges(signature: np.ndarray, display: np.ndarray, allowance: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """(edge (h, w) bool, step (h, w)): edge the pixels whose signature (h, w) differs from a
    4-neighbour's where the colour between their display values (h, w, 4) steps by more than
    EDGE_CONTRAST (``_steps``), or whose colour steps to a neighbour by more than
    LINE_CONTRAST whatever the signatures; step each pixel's largest step to a 4-neighbour.
    allowance: (h, w) how far noise may move each pixel's display value
    (NOISE_ALLOWANCE), taken off every step it is a side of; or None."""
    edge = np.zeros(signature.shape, bool)
    step = np.zeros(signature.shape, display.dtype)
    for axis, same in ((0, signature[1:, :] == signature[:-1, :]),
                       (1, signature[:, 1:] == signature[:, :-1])):
        steps = _steps(display, axis)
        first = (slice(1, None), slice(None)) if axis == 0 else (slice(None), slice(1, None))
        second = (slice(None, -1), slice(None)) if axis == 0 else (slice(None), slice(None, -1))
        if allowance is not None:
            steps = np.maximum(steps - allowance[first] - allowance[second], 0)
        pair = np.where(same, steps > LINE_CONTRAST, steps > EDGE_CONTRAST)
        for side in (first, second):
            edge[side] |= pair
            np.maximum(step[side], steps, out=step[side])
    return edge, step


def _staged_supersample(ctx, camera, cols, rows, count, centre_rgb, centre_coverage, step,
                        stats, stop=None):
    """Mean (rgb (n, 3), coverage (n,)) of edge pixels (cols, rows) (n,) over between
    FIRST_SAMPLES and ``count`` of the ``sample_offsets(count)`` positions each: a first round,
    then doubling rounds for the pixels whose estimated error (SAMPLE_ERROR) is still too
    large.  A pixel's samples are always a prefix of the one sequence, with the soft lights'
    shares of ``count`` samples (``core.lights.pixel_shares``), so a pixel that goes to
    ``count`` gets fixed AA's samples, and a pixel's value depends only on its own samples and
    its centre's step (n,) to its neighbours: never on the tile.  Where the shares change
    nothing (``core.shading.shares_matter``: article semantics, or only point lights) a
    pixel's centre is its sample 0 and is not traced again."""
    n = len(cols)
    rgb_sum = np.zeros((n, 3), np.float64)
    coverage_sum = np.zeros(n, np.float64)
    low = np.full((n, 4), np.inf)
    high = np.full((n, 4), -np.inf)
    counts = np.zeros(n)
    centre = not shares_matter(ctx)   # the first round starts from the centres
    live = np.arange(n)
    done, target = 0, min(FIRST_SAMPLES, count)
    while len(live):
        ks = np.arange(int(centre) if done == 0 else done, target)
        rounds = (_sample_bundles(ctx, camera, cols[live], rows[live], count, ks, stats, stop)
                  if len(ks) else [(slice(None), np.zeros((n, 0, 3), ctx.dtype),
                                    np.zeros((n, 0), ctx.dtype))])
        for part, colour, hit in rounds:
            part = live[part]
            if centre and done == 0:   # sample 0 first, so sums run in the samples' order
                colour = np.concatenate([centre_rgb[part, None], colour], axis=1)
                hit = np.concatenate([centre_coverage[part, None], hit], axis=1)
            display = _display(ctx, colour.reshape(-1, 3), hit.ravel()).reshape(
                len(part), -1, 4)
            rgb_sum[part] += colour.sum(axis=1)
            coverage_sum[part] += hit.sum(axis=1)
            low[part] = np.minimum(low[part], display.min(axis=1))
            high[part] = np.maximum(high[part], display.max(axis=1))
        counts[live] = target
        done = target
        if done >= count:
            break
        spread = np.maximum((high[live] - low[live]).max(axis=1), step[live])
        live = live[spread / done > SAMPLE_ERROR]
        target = min(2 * done, count)
    stats.supersampled_pixels += n
    return ((rgb_sum / counts[:, None]).astype(ctx.dtype),
            (coverage_sum / counts).astype(ctx.dtype))


def render_tile(ctx: TraceContext, camera, tile, stop: Optional[threading.Event] = None
                ) -> tuple[np.ndarray, RayStats]:
    """(rgba (h, w, 4), stats) for tile (y0, y1, x0, x1) of the image.  stop: once set, the
    tile raises RenderCancelled at its next bundle of rays (a cancel need not wait for whole
    supersampled tiles)."""
    if ctx.paths is not None:
        return render_path_tile(ctx, camera, tile, stop)
    rgba, stats = _render_whitted_tile(ctx, camera, tile, stop)
    if ctx.settings.guides:     # (no guides: the image's other channels stay 0)
        rgba = np.concatenate([rgba, np.zeros(rgba.shape[:2] + (GUIDE_CHANNELS,),
                                              rgba.dtype)], axis=2)
    return rgba, stats


def camera_space(camera, normal):
    """(3, n) world normals in Cycles' camera space (x right, y up, z along the view), the
    space of its Denoising Normal pass."""
    if not isinstance(camera, BlenderCamera):
        return normal
    rotation = camera_to_world(camera)[0].astype(normal.dtype)
    local = rotation.T @ normal
    local[2] *= -1
    return local


def render_path_tile(ctx, camera, job, stop=None):
    """(sums (h, w, channels), stats) of a ``core.progressive.TileJob``: the tile's live
    pixels traced with samples job.first..job.last, each positioned by the pixel filter's
    density; per pixel the sums ``core.progressive`` adds up (radiance, twice the odd
    samples' radiance, alpha, the count, and with guides their sums), then for a job with
    passes ``core.passes.PASS_CHANNELS`` more, the passes of what sample 0 hit first (0 in
    later passes).  A pixel's sums depend only on its own samples: never on the tile."""
    start = time.perf_counter()
    settings = ctx.settings
    dtype = ctx.dtype
    y0, y1, x0, x1 = job[:4]
    h, w = y1 - y0, x1 - x0
    stats = RayStats(tiles=1)
    cols, rows = _pixel_grid(y0, y1, x0, x1)
    live = job.live_pixels()
    if live is not None:
        chosen = live[rows - y0, cols - x0]
        cols, rows = cols[chosen], rows[chosen]
    n = len(cols)
    seeds = pixel_seeds(cols, rows, settings.seed)
    bits = ctx.paths.index_bits
    aperture = has_aperture(camera)
    channels = SUM_CHANNELS + (GUIDE_SUM_CHANNELS if settings.guides else 0)
    sums = np.zeros((channels, n))
    # A frame with passes: its jobs carry them after the sums, filled by the first sample.
    passes = np.zeros((n, PASS_CHANNELS)) if job.passes else None
    first_hits = job.passes and job.first == 0
    count = job.last - job.first
    per_bundle = max(1, max(1024, settings.tile_size ** 2) // count)
    for first in range(0, n, per_bundle):
        if stop is not None and stop.is_set():
            raise RenderCancelled("render cancelled")
        chunk = np.arange(first, min(first + per_bundle, n))
        pixel = np.repeat(chunk, count)
        sample = np.tile(np.arange(job.first, job.last), len(chunk))
        u = sample_group(seeds[pixel], sample, PIXEL_GROUP, bits)
        xs = cols[pixel] + 0.5 + filter_offsets(u[0], settings.filter_type,
                                                settings.filter_width)
        ys = rows[pixel] + 0.5 + filter_offsets(u[1], settings.filter_type,
                                                settings.filter_width)
        began = time.perf_counter()
        rays = camera_rays(camera, xs, ys, dtype, u[2:4] if aperture else None)
        traced = time.perf_counter()
        result = trace_paths(ctx, rays, seeds[pixel], sample, stats, first_hits=first_hits)
        if first_hits:
            # As Cycles' passes: what each pixel's first sample hit.
            zero = np.flatnonzero(sample == 0)
            t, primitive, material = (values[zero] for values in result.first_hits)
            origins = rays.origins if rays.origins.shape[1] == 1 else rays.origins[:, zero]
            passes[pixel[zero]] = first_hit_channels(
                camera, origins, rays.directions[:, zero], t, primitive, material,
                result.normal[:, zero], ctx.paths.frame)
        stats.seconds_camera += traced - began
        stats.seconds_bounces += time.perf_counter() - traced
        odd = (sample & 1).astype(np.float64) * 2
        columns = [result.colour[0], result.colour[1], result.colour[2],
                   result.colour[0] * odd, result.colour[1] * odd, result.colour[2] * odd,
                   result.alpha, None]
        if channels > SUM_CHANNELS:
            columns += list(result.albedo) + list(camera_space(camera, result.normal))
        for row, values in enumerate(columns):
            if values is not None:
                sums[row] += np.bincount(pixel, values, n)
    sums[7] = count
    if passes is not None:
        sums = np.concatenate([sums, passes.T])
    # float32, the sums worker processes hand over (``core.workers``' shared array): a
    # frame's image is then the same bit for bit on threads and on processes.
    grid = np.zeros((h, w, len(sums)), np.float32)
    grid[rows - y0, cols - x0] = sums.T
    stats.seconds_tiles += time.perf_counter() - start
    return grid, stats


def _render_whitted_tile(ctx: TraceContext, camera, tile, stop=None):
    """``render_tile`` with the Whitted integrator (``core.trace``)."""
    start = time.perf_counter()
    y0, y1, x0, x1 = tile
    h, w = y1 - y0, x1 - x0
    stats = RayStats(tiles=1)
    mode = ctx.settings.anti_aliasing
    if mode == "adaptive" and has_aperture(camera):
        mode = "fixed"  # defocus blurs every pixel, not only those on an edge
    rgba = np.empty((h, w, 4), ctx.dtype)
    cols, rows = _pixel_grid(y0, y1, x0, x1)
    if mode == "fixed":
        rgb, coverage = _supersample(ctx, camera, cols, rows, ctx.settings.samples, stats,
                                     stop)
    elif mode == "off":
        rgb, coverage, _, _ = _trace_positions(ctx, camera, cols + 0.5, rows + 0.5, stats,
                                              stop=stop)
    else:
        # Trace the tile and an apron at pixel centres, then supersample the pixels whose
        # path signature differs from a 4-neighbour's where the colour steps (_edges).
        width, height = camera.width, camera.height
        ay0, ax0 = max(y0 - APRON, 0), max(x0 - APRON, 0)
        apron = (min(y1 + APRON, height) - ay0, min(x1 + APRON, width) - ax0)
        apron_cols, apron_rows = _pixel_grid(ay0, ay0 + apron[0], ax0, ax0 + apron[1])
        centre_rgb, centre_coverage, signature, noise = _trace_positions(
            ctx, camera, apron_cols + 0.5, apron_rows + 0.5, stats, stop=stop)
        inner = (rows - ay0) * apron[1] + (cols - ax0)
        order = np.empty(len(apron_cols), np.intp)
        order[(apron_rows - ay0) * apron[1] + (apron_cols - ax0)] = np.arange(len(apron_cols))
        rgb = centre_rgb[order[inner]]
        coverage = centre_coverage[order[inner]].astype(ctx.dtype)
        display = _display(ctx, centre_rgb, centre_coverage)
        allowance = None
        if noise is not None:   # (NOISE_ALLOWANCE standard deviations, in display values)
            allowance = (_display(ctx, centre_rgb + NOISE_ALLOWANCE * noise, centre_coverage)
                         - display)[:, :3].max(axis=1)
            allowance = _scatter(allowance, apron_cols, apron_rows, ax0, ay0, apron)
        edge, step = _edges(_scatter(signature, apron_cols, apron_rows, ax0, ay0, apron),
                            _scatter(display, apron_cols, apron_rows, ax0, ay0, apron),
                            allowance)
        chosen = np.flatnonzero(edge.ravel()[inner])
        if len(chosen):
            rgb[chosen], coverage[chosen] = _staged_supersample(
                ctx, camera, cols[chosen], rows[chosen], ctx.settings.samples, rgb[chosen],
                coverage[chosen], step.ravel()[inner][chosen], stats, stop)
    _assemble(rgba, rgb, coverage)
    stats.seconds_tiles += time.perf_counter() - start
    return rgba, stats
