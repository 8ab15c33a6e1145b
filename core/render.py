"""``render``: a scene in, an (H, W, 4) image out, tile by tile.

Tiles bound the working memory whatever the resolution (every array a tile creates is
proportional to its pixel count, never to the image's), give culling its small cones, and are
the unit of parallelism: a thread pool renders them (NumPy releases the GIL in its loops),
each tile writing only its own slice of the image, so the result does not depend on the number
of threads.  Anti-aliasing happens inside a tile: 'fixed' traces every pixel with ``samples``
stratified sub-pixel positions; 'adaptive' traces the tile and a two-pixel apron at pixel
centres, picks the pixels whose path signature (the surfaces hit and the shadows met at every
bounce) differs from a 4-neighbour's where the colour steps by more than EDGE_CONTRAST (or by
more than LINE_CONTRAST anywhere), and supersamples those in rounds: FIRST_SAMPLES samples,
then twice as many while their estimated error exceeds SAMPLE_ERROR, up to ``samples``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .camera import camera_rays, has_aperture
from .colour import linear_to_srgb
from .context import RayStats, TraceContext, make_context, path_traced
from .passes import PASS_CHANNELS, PrimaryPasses, fill_tile_passes, store_first_hits
from .path import render_path_tile
from .progressive import ProgressiveFrame, WorkQueue
from .geometry import DEFAULT_POLICY, GeometryPolicy
from .geometry.cull import PACKET_SIZE
from . import memory
from .memory import GUIDE_CHANNELS
from .frame import canonical_scene, scene_frame
from .lights import SampleShares, pixel_shares, pixel_shifts
from .precision import choose_precision
from .scene import RenderSettings, Scene, SceneError
from .shading import shares_matter, traces_from_points, traces_world_occlusion
from .trace import trace_bundle, traces_bounces
from . import allocator, cluster, workers


#: Tiles are traced in BLOCK x BLOCK pixel blocks: one culling packet each.
BLOCK = math.isqrt(PACKET_SIZE)
#: How often the thread loop polls should_cancel while tiles are running.
CANCEL_POLL_SECONDS = 0.1
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


class _Asked:
    """A tile's ``stop`` on the render's own thread: ``is_set`` asks ``should_cancel``, as a
    threading.Event set by the thread loop would answer."""

    def __init__(self, should_cancel):
        self.should_cancel = should_cancel

    def is_set(self) -> bool:
        return self.should_cancel is not None and bool(self.should_cancel())


class RenderCancelled(Exception):
    """``should_cancel()`` answered True; the render stopped between tiles."""


class RenderError(RuntimeError):
    """The tracer produced something no accepted scene should (a bug); the message is one
    line saying where."""


@dataclass
class RenderResult:
    """image: (H, W, 4) in the render's precision (or the ``image_dtype`` asked for), row 0 =
    top; RGB: article semantics the article's display values clipped to [0, 1], default
    semantics unclipped scene-linear radiance (Cycles' units; Blender's colour management
    turns it into display values); alpha: the mean over the pixel's samples of 1 - what
    escaped or was held out (``RenderSettings.film``, ``core.trace``): without holdouts and
    Transparent BSDFs, the fraction of samples whose camera ray hit something.  stats:
    RayStats.  precision: 'float64' or 'float32'.
    missed_colour: (3,) float64, what a camera sample that hits nothing adds to its pixel's RGB
    (the background in default semantics, black in the article's and with film
    'transparent').
    semantics: the semantics rendered.
    parallelism: how the tiles ran: 'threads' (the calling thread or a thread pool),
    'processes' (``core.workers``), which can differ from the setting's (small renders, or
    processes unavailable), or 'cluster' (a Dask cluster, ``RenderSettings.cluster``)."""

    image: np.ndarray
    stats: RayStats
    precision: str
    missed_colour: np.ndarray
    semantics: str = "article"
    parallelism: str = "threads"
    passes: Optional[PrimaryPasses] = None   # render(passes=True): see core.passes
    #: (H, W, 3) the first hits' albedo and shading normal (``RenderSettings.guides``, path
    #: integrator), denoising's guides; None otherwise.
    albedo: Optional[np.ndarray] = None
    normal: Optional[np.ndarray] = None
    #: Why tiles that were to go to worker processes or a cluster ran on threads (they
    #: cannot start here: ``core.workers.unavailable_reason``; the Emission pass, which
    #: stays here), else None; the front ends show it.
    fallback: Optional[str] = None

    def display(self) -> np.ndarray:
        """(H, W, 4) display values in [0, 1] for an 8-bit file: the image itself in article
        semantics; default semantics' radiance through view transform Standard (clipped,
        sRGB-encoded), as Blender would show it with that view transform."""
        if self.semantics == "article":
            return self.image
        shown = np.array(self.image, np.float64, copy=True)
        shown[..., :3] = linear_to_srgb(np.clip(shown[..., :3], 0, 1))
        return shown


def sample_offsets(count: int) -> np.ndarray:
    """count sub-pixel positions (count, 2) in [0, 1)^2: the R2 low-discrepancy sequence
    (Roberts 2018), deterministic, well spread for any count; the first is the centre."""
    g = 1.32471795724474602596
    k = np.arange(count)[:, None]
    return (0.5 + k * np.array([1 / g, 1 / (g * g)])) % 1.0


def _tiles(width: int, height: int, size: int):
    return [(y, min(y + size, height), x, min(x + size, width))
            for y in range(0, height, size) for x in range(0, width, size)]


def _even_tail(tiles: list, count: int) -> list:
    """tiles with the last one cut across its longer side (at multiples of BLOCK where it
    can be) into as many pieces as make their number a multiple of ``count`` (the workers'):
    tiles of similar cost land about ``count`` at a time, so a frame of 15 tiles on 2 workers
    ended on one tile with the other worker idle (the lead's points.pkl: 0.25-0.30 s between
    its last two tiles).  Pieces cost more than their share (smaller batches: the two halves
    of that tile 0.37 s of thread time against 0.34 s); the frame's 2-worker schedule replayed
    with each tile's thread time took 3.22 s against 3.26 s (instances.pkl 2.69 against
    2.77), where cutting the last 3 or 5 tiles in halves gained nothing.  The image is the
    same for any tiles."""
    extra = -len(tiles) % count
    if count < 2 or extra == 0:
        return tiles
    y0, y1, x0, x1 = tiles[-1]
    across_x = x1 - x0 >= y1 - y0
    low, high = (x0, x1) if across_x else (y0, y1)
    pieces = extra + 1
    step = (high - low) / pieces
    if step >= BLOCK:
        cuts = [low] + [low + BLOCK * round(k * step / BLOCK) for k in range(1, pieces)] + [high]
    else:
        cuts = [low + round(k * step) for k in range(pieces)] + [high]
    if len(set(cuts)) < len(cuts):      # (a tile too small to cut that many times)
        return tiles
    parts = [(y0, y1, a, b) if across_x else (a, b, x0, x1) for a, b in zip(cuts, cuts[1:])]
    return tiles[:-1] + parts


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
    if ctx.article:   # clipped in place (np.clip's wrapper costs ~30 us a bundle)
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
        shares = pixel_shares(cols[part], rows[part], count)   # (per bundle: its memory)
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
    if ctx.article:
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


def missed_colour(scene: Scene, settings: RenderSettings) -> np.ndarray:
    """(3,) what a camera sample that escapes adds to its pixel (see RenderResult): the
    tracer adds the background only in default semantics, unclipped (only the article's
    samples are clipped, and it adds none), and not with film 'transparent'."""
    if settings.semantics != "default" or settings.film == "transparent":
        return np.zeros(3)
    return np.asarray(scene.background, np.float64)


def _in_processes(settings: RenderSettings, pixels: int, tiles: int, threads: int,
                  tree: bool = False, path: bool = False) -> bool:
    """Whether this render's tiles go to worker processes (``RenderSettings.parallelism``).
    A single tile or a small render stays in this process (starting a worker costs more
    than it gains there): its work is its camera samples, weighted for a scene with a tree
    (``workers.TREE_SAMPLE_WEIGHT``).  'auto' asks for more than one worker (one only moves
    the work out of this process), and in a process that renders once
    (``workers.one_render``) for warm workers or a render heavy enough to pay for their
    start-up."""
    per_pixel = settings.samples if settings.anti_aliasing == "fixed" or path else 1
    work = pixels * per_pixel * (workers.TREE_SAMPLE_WEIGHT if tree else 1)
    if tiles < 2 or work < workers.MIN_PIXELS:
        return False
    if settings.parallelism != "auto":
        return settings.parallelism == "processes"
    if threads < 2:
        return False
    return (not workers.one_render or workers.warm(threads)
            or work >= workers.COLD_MIN_SAMPLES)


def _fallback_line(reason: str) -> str:
    return f"worker processes unavailable ({reason}): rendered on threads"


@allocator.small_pages()   # (the tiles' and the tree's large arrays: see core.allocator)
def render(scene: Scene, settings: Optional[RenderSettings] = None, *,
           progress: Optional[Callable[[float], None]] = None,
           should_cancel: Optional[Callable[[], bool]] = None,
           image_dtype=None, reserve_bytes: int = 0,
           on_tile: Optional[Callable[[tuple, np.ndarray], None]] = None,
           passes: "bool | PrimaryPasses" = False,
           on_pass: Optional[Callable[[int, np.ndarray], None]] = None,
           geometry_policy: GeometryPolicy = DEFAULT_POLICY) -> RenderResult:
    """Render ``scene``; see ``core`` for the result's layout.  image_dtype: the image's
    dtype (default: the render's precision); float32 halves a float64 render's largest array
    for callers that keep no more than float32 anyway (Blender's render results).
    reserve_bytes: memory the caller will need besides the render (counted in the plan).
    on_tile(tile, rgba): called on the calling thread as each tile lands (before
    ``progress``), with tile = (y0, y1, x0, x1) (rows from the top) and its (h, w, 4) pixels,
    a view of the image: copy what must outlive the call.  Tiles land in any order; a
    cancelled render has passed on exactly the tiles that finished.
    on_pass(samples, image): for a path-traced frame, called as each progressive pass
    completes (``core.progressive``), with the samples a pixel has had so far and the
    frame's image as it stands (a view: copy what must outlive the call).
    passes: also fill ``RenderResult.passes`` (``core.passes``: depth, position, normal,
    primitive and material of each pixel centre's first hit, in world units); a
    PrimaryPasses of the image's size is filled in place, so ``on_tile`` can read each tile's
    passes as the tile lands.
    geometry_policy: the thresholds by which the geometry picks its strategies
    (``core.geometry.GeometryPolicy``: tests and benchmarks try others; the image is the
    same for any).

    Before anything is allocated, the render's memory is planned (``core.memory``) and a
    render that cannot fit raises memory.NotEnoughMemory, a SceneError."""
    if not isinstance(scene, Scene):
        raise SceneError(f"scene must be a core.Scene, got {type(scene).__name__}")
    settings = RenderSettings() if settings is None else settings
    if not isinstance(settings, RenderSettings):
        raise SceneError(f"settings must be a core.RenderSettings, got {type(settings).__name__}")
    allocator.configure_if_opted_in()  # only if GLINT_MALLOC_TUNING asks (core.allocator)
    if getattr(scene.camera, "sees_nothing", False):
        # Cycles renders such a camera's frame black (``BlenderCamera``), opaque or, with a
        # transparent film, transparent: an empty scene, tile by tile as any frame.
        scene = Scene(camera=scene.camera)
    world = None if settings.semantics == "article" else scene_frame(scene)  # for passes
    scene = canonical_scene(scene, settings)  # positions and units stop mattering
    dtype = choose_precision(scene, settings.precision)
    width, height = scene.camera.width, scene.camera.height
    threads = settings.threads or os.cpu_count() or 1
    image_dtype = dtype if image_dtype is None else np.dtype(image_dtype)
    if passes:  # the passes' arrays, beside the image
        per_pixel = PrimaryPasses.BYTES_PER_PIXEL
        if isinstance(passes, PrimaryPasses) and passes.emission is not None:
            per_pixel += PrimaryPasses.EMISSION_BYTES_PER_PIXEL
        reserve_bytes += per_pixel * width * height
    tiles = _tiles(width, height, settings.tile_size)
    # Passes are filled in this process, beside each tile (``work``) or, where the tiles go
    # to worker processes, as each lands (``land``): their trace stops at the first hits,
    # a small part of a tile's work.  The Emission pass follows whole camera paths, so it
    # keeps the tiles here.
    emission_pass = isinstance(passes, PrimaryPasses) and passes.emission is not None
    on_cluster = bool(settings.cluster) and not emission_pass
    kept_here = (f"the Emission pass is rendered on this machine, not on the cluster at "
                 f"{settings.cluster}") if settings.cluster and emission_pass else None
    tree = geometry_policy.builds_tree(scene.sphere_count, scene.triangle_count)
    in_processes = not emission_pass and not on_cluster and _in_processes(
        settings, width * height, len(tiles), threads, tree, path_traced(scene, settings))
    memory_plan = memory.plan(scene, settings, image_dtype, threads, reserve_bytes)
    if in_processes:  # plus the workers' interpreters and the scene's shared copy
        memory_plan = dataclasses.replace(memory_plan, other=memory_plan.other + workers.
                                          planned_bytes(threads, memory_plan.scene))
    memory.check(memory_plan, width, height)
    if in_processes:
        workers.prestart(threads)  # they start while the context is built
        tiles = _even_tail(tiles, threads)
    ctx = make_context(scene, settings, dtype, threads=threads,   # (the tree: on threads)
                       frame=world, geometry_policy=geometry_policy)
    # What the frame's tiles would each build on first use (in every worker process), built
    # once here on the render's threads: the eye's bins, the occlusion trails' tables.
    shared_eye = ctx.camera_origin is not None and not has_aperture(scene.camera)
    tracing_paths = ctx.paths is not None
    ctx.geometry.build_frame_tables(ctx.camera_origin.position if shared_eye else None,
                                    bounces=tracing_paths or traces_bounces(ctx),
                                    trails=tracing_paths or traces_from_points(ctx),
                                    threads=threads)
    shape = (height, width, 4 + (GUIDE_CHANNELS if settings.guides else 0))
    stats = RayStats()
    if isinstance(passes, PrimaryPasses):
        if passes.depth.shape != (height, width):
            raise SceneError(f"passes are {passes.depth.shape[1]}x{passes.depth.shape[0]}, "
                             f"the image {width}x{height}")
        primary = passes
    else:
        primary = PrimaryPasses.empty(width, height) if passes else None

    def fill_passes(tile, tile_stats):
        """A tile's passes, if asked for: beside the tile on a thread, or here as it lands
        from a worker process."""
        if primary is not None:
            fill_tile_passes(primary, ctx, scene.camera, tile, tile_stats, world)

    if tracing_paths:
        return _render_progressive(ctx, scene, settings, tiles, shape, image_dtype, dtype,
                                   threads, in_processes, fill_passes, primary, on_tile,
                                   progress, should_cancel, on_pass, on_cluster, kept_here)

    def work(ctx, camera, tile, stop=None):
        rgba, tile_stats = render_tile(ctx, camera, tile, stop)
        fill_passes(tile, tile_stats)
        return rgba, tile_stats

    def land(tile, pixels, tile_stats, done, finite, worker_tile=False):
        """A finished tile: pixels its (h, w, 4) view of the image, finite whether the
        values it was made from are all finite (workers check their own tiles, sparing this
        process a pass over the image); worker_tile: rendered by ``core.workers`` (its
        passes are not filled yet)."""
        if not finite:  # never a silently wrong picture, even from a bug
            y0, y1, x0, x1 = tile
            raise RenderError(f"pixels {x0}-{x1 - 1} x {y0}-{y1 - 1} came out NaN or "
                              f"infinite; please report this scene")
        if worker_tile:
            fill_passes(tile, tile_stats)
        stats.add(tile_stats)
        if on_tile is not None:
            on_tile(tile, pixels[..., :4])
        if progress is not None:
            progress(done / len(tiles))

    def finish(tile, rgba, tile_stats, done):
        """A tile rendered in this process: into the image, then landed."""
        y0, y1, x0, x1 = tile
        finite = bool(np.isfinite(rgba).all())
        if finite:
            image[y0:y1, x0:x1] = rgba
        land(tile, image[y0:y1, x0:x1], tile_stats, done, finite)

    def cancelled():
        return should_cancel is not None and should_cancel()

    if on_cluster:   # (tiles land as worker processes' do: their passes filled here)
        image = cluster.render_tiles(settings.cluster, ctx, scene.camera, tiles, shape,
                                     image_dtype, functools.partial(land, worker_tile=True),
                                     should_cancel)
        return _result(image, stats, dtype, scene, settings, parallelism="cluster",
                       passes=primary)
    fallback = kept_here
    if in_processes:
        try:
            # The workers write their tiles straight into the image they share with this
            # process, which is the result (core.workers: no copy of any tile here).
            image, unavailable = workers.render_tiles(
                ctx, scene.camera, tiles, shape, image_dtype, threads,
                functools.partial(land, worker_tile=True), should_cancel)
            if unavailable is not None:  # the workers failed after some tiles landed
                return _result(image, stats, dtype, scene, settings, parallelism="threads",
                               passes=primary, fallback=_fallback_line(unavailable))
            return _result(image, stats, dtype, scene, settings, parallelism="processes",
                           passes=primary)
        except workers.WorkersBusy:
            pass  # another render (a viewport) has them: threads, without a word
        except workers.ProcessesUnavailable as error:
            fallback = _fallback_line(str(error))
        # No tile has landed yet: the same tiles on threads, below.

    image = np.zeros(shape, image_dtype)

    if threads == 1 or len(tiles) == 1:
        asked = _Asked(should_cancel)   # (a deep tile polls it between bounces)
        for done, tile in enumerate(tiles, 1):
            if cancelled():
                raise RenderCancelled("render cancelled")
            finish(tile, *work(ctx, scene.camera, tile, asked), done)
        return _result(image, stats, dtype, scene, settings, passes=primary,
                       fallback=fallback)

    stop = threading.Event()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        pending = {}
        queue = iter(tiles)
        done = 0
        try:
            while True:
                # Keep only a few tiles in flight so a cancel is honoured promptly.
                while len(pending) < 2 * threads:
                    tile = next(queue, None)
                    if tile is None:
                        break
                    pending[pool.submit(work, ctx, scene.camera, tile, stop)] = tile
                if not pending:
                    break
                # Wake up regularly to poll should_cancel while long tiles run.
                finished, _ = wait(pending, timeout=CANCEL_POLL_SECONDS,
                                   return_when=FIRST_COMPLETED)
                for future in finished:
                    tile = pending.pop(future)
                    rgba, tile_stats = future.result()
                    done += 1
                    finish(tile, rgba, tile_stats, done)
                if cancelled():
                    raise RenderCancelled("render cancelled")
        except BaseException:
            # Cancelled, a tile failed, or an exception (KeyboardInterrupt) arrived: stop
            # the other tiles at their next bundle instead of finishing them.
            stop.set()
            for future in pending:
                future.cancel()
            raise
    return _result(image, stats, dtype, scene, settings, passes=primary, fallback=fallback)


def _render_progressive(ctx, scene, settings, tiles, shape, image_dtype, dtype, threads,
                        in_processes, fill_passes, primary, on_tile, progress,
                        should_cancel, on_pass=None, on_cluster=False,
                        fallback=None) -> RenderResult:
    """A path-traced frame, pass by pass (``core.progressive``), its tiles' passes on
    worker processes, a cluster or threads like any frame's tiles."""
    image = np.zeros(shape, image_dtype)
    # The passes of what each pixel's first sample hit come with the tiles' sums; the
    # Emission pass follows whole camera paths of its own (``fill_passes``).
    carried = primary is not None and primary.emission is None
    frame = ProgressiveFrame(settings, tiles, image, guides=settings.guides, passes=carried)
    queue = WorkQueue(frame)
    stats = RayStats()
    total_samples = settings.samples

    def landed(job, sums, tile_stats, first_pass):
        if not np.isfinite(sums).all():   # never a silently wrong picture, even from a bug
            y0, y1, x0, x1 = job[:4]
            raise RenderError(f"pixels {x0}-{x1 - 1} x {y0}-{y1 - 1} came out NaN or "
                              f"infinite; please report this scene")
        if carried:
            if first_pass:
                store_first_hits(primary, job[:4], sums[..., -PASS_CHANNELS:])
            sums = sums[..., :-PASS_CHANNELS]
        elif first_pass:
            fill_passes(job[:4], tile_stats)
        view = frame.land(job, sums)
        stats.add(tile_stats)
        if on_tile is not None:
            on_tile(job[:4], view[..., :4])
        if progress is not None:
            before = frame.done_samples - frame.sizes[frame.passes_made - 1]
            share = 1 - frame.outstanding / max(len(tiles), 1)
            progress(min(1.0, (before + share * (frame.done_samples - before))
                         / total_samples))
        if on_pass is not None and frame.pass_complete():
            on_pass(frame.done_samples, image)
        queue.refill()

    def cancelled():
        return should_cancel is not None and should_cancel()

    def finish(job, sums, tile_stats, done, finite):
        """A job from worker processes or a cluster: its sums as they arrived (float32)."""
        landed(job, np.array(sums, np.float64), tile_stats, job.first == 0)

    sums_shape = (shape[0], shape[1], frame.channels + (PASS_CHANNELS if carried else 0))
    if on_cluster:
        cluster.render_tiles(settings.cluster, ctx, scene.camera, queue, sums_shape,
                             np.float32, finish, should_cancel)
        return _result(image, stats, dtype, scene, settings, passes=primary,
                       parallelism="cluster")
    if in_processes:
        try:
            _, unavailable = workers.render_tiles(ctx, scene.camera, queue, sums_shape,
                                                  np.float32, threads, finish, should_cancel)
            return _result(image, stats, dtype, scene, settings, passes=primary,
                           parallelism="threads" if unavailable else "processes",
                           fallback=_fallback_line(unavailable) if unavailable else None)
        except workers.WorkersBusy:
            pass
        except workers.ProcessesUnavailable as error:
            fallback = _fallback_line(str(error))
        queue = WorkQueue(ProgressiveFrame(settings, tiles, image, guides=settings.guides,
                                           passes=carried))
        frame = queue.frame

    if threads == 1 or len(tiles) == 1:
        asked = _Asked(should_cancel)
        while queue:
            if cancelled():
                raise RenderCancelled("render cancelled")
            job = queue.popleft()
            sums, tile_stats = render_tile(ctx, scene.camera, job, asked)
            landed(job, sums, tile_stats, job.first == 0)
        return _result(image, stats, dtype, scene, settings, passes=primary,
                       fallback=fallback)

    stop = threading.Event()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        pending = {}
        try:
            while queue or pending:
                while len(pending) < 2 * threads and queue:
                    job = queue.popleft()
                    pending[pool.submit(render_tile, ctx, scene.camera, job, stop)] = job
                if not pending:
                    break
                finished, _ = wait(pending, timeout=CANCEL_POLL_SECONDS,
                                   return_when=FIRST_COMPLETED)
                for future in finished:
                    job = pending.pop(future)
                    sums, tile_stats = future.result()
                    landed(job, sums, tile_stats, job.first == 0)
                if cancelled():
                    raise RenderCancelled("render cancelled")
        except BaseException:
            stop.set()
            for future in pending:
                future.cancel()
            raise
    return _result(image, stats, dtype, scene, settings, passes=primary, fallback=fallback)


def _result(image, stats, dtype, scene, settings, **extra) -> RenderResult:
    """The RenderResult of a frame whose tiles filled ``image`` (H, W, 4 or 4 + guides)."""
    albedo = normal = None
    if image.shape[2] > 4:
        albedo, normal = image[..., 4:7], image[..., 7:10]
    return RenderResult(image[..., :4], stats, dtype.name, missed_colour(scene, settings),
                        settings.semantics, albedo=albedo, normal=normal, **extra)
