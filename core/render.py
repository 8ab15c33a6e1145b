"""``render``: a scene in, an (H, W, 4) image out, tile by tile.

The frame's orchestrator: it plans the memory, builds the trace context, cuts the frame into
tiles and runs them on this thread, a thread pool, worker processes (``core.workers``) or a
Dask cluster (``core.cluster``).  Tiles bound the working memory whatever the resolution and
are the unit of parallelism: each writes only its own slice of the image, so the result does
not depend on how they ran.  A tile itself is ``core.tiles``'s.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import os
import threading
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .camera import has_aperture
from .colour import linear_to_srgb
from .context import RayStats, make_context, path_traced
from .failures import RenderCancelled, RenderError
from .passes import PASS_CHANNELS, PrimaryPasses, fill_tile_passes, store_first_hits
from .progressive import ProgressiveFrame, WorkQueue
from .geometry import DEFAULT_POLICY, GeometryPolicy
from . import memory
from .memory import GUIDE_CHANNELS
from .frame import canonical_scene, scene_frame
from .precision import choose_precision
from .scene import Scene
from .settings import RenderSettings
from .validation import SceneError
from .shading import traces_from_points
from .tiles import BLOCK, render_tile
from .trace import traces_bounces
from . import allocator, cluster, workers


#: How often the thread loop polls should_cancel while tiles are running.
CANCEL_POLL_SECONDS = 0.1


class _Asked:
    """A tile's ``stop`` on the render's own thread: ``is_set`` asks ``should_cancel``, as a
    threading.Event set by the thread loop would answer."""

    def __init__(self, should_cancel):
        self.should_cancel = should_cancel

    def is_set(self) -> bool:
        return self.should_cancel is not None and bool(self.should_cancel())


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

    queue = iter(tiles)
    tile_numbers = itertools.count(1)
    _run_on_threads(lambda: next(queue, None),
                    lambda tile, stop: work(ctx, scene.camera, tile, stop),
                    lambda tile, result: finish(tile, *result, next(tile_numbers)),
                    1 if len(tiles) == 1 else threads, should_cancel)
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

    _run_on_threads(lambda: queue.popleft() if queue else None,
                    lambda job, stop: render_tile(ctx, scene.camera, job, stop),
                    lambda job, result: landed(job, *result, job.first == 0),
                    1 if len(tiles) == 1 else threads, should_cancel)
    return _result(image, stats, dtype, scene, settings, passes=primary, fallback=fallback)


def _run_on_threads(next_job, run, land, threads: int, should_cancel) -> None:
    """Run every job ``next_job()`` hands out (None: none now; landing one may make more)
    as ``run(job, stop)`` and give its result to ``land(job, result)`` on this thread as it
    finishes: on this thread alone for one thread, else on a pool of ``threads`` with a few
    jobs in flight, so that a cancel (``should_cancel()``) is honoured promptly.  ``stop``
    tells a running job to raise RenderCancelled at its next bundle of rays."""
    def cancelled():
        return should_cancel is not None and should_cancel()

    if threads == 1:
        asked = _Asked(should_cancel)   # (a deep tile polls it between bounces)
        while True:
            if cancelled():
                raise RenderCancelled("render cancelled")
            job = next_job()
            if job is None:
                return
            land(job, run(job, asked))
    stop = threading.Event()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        pending = {}
        try:
            while True:
                while len(pending) < 2 * threads:
                    job = next_job()
                    if job is None:
                        break
                    pending[pool.submit(run, job, stop)] = job
                if not pending:
                    return
                # Wake up regularly to poll should_cancel while long tiles run.
                finished, _ = wait(pending, timeout=CANCEL_POLL_SECONDS,
                                   return_when=FIRST_COMPLETED)
                for future in finished:
                    land(pending.pop(future), future.result())
                if cancelled():
                    raise RenderCancelled("render cancelled")
        except BaseException:
            # Cancelled, a tile failed, or an exception (KeyboardInterrupt) arrived: stop
            # the other tiles at their next bundle instead of finishing them.
            stop.set()
            for future in pending:
                future.cancel()
            raise


def _result(image, stats, dtype, scene, settings, **extra) -> RenderResult:
    """The RenderResult of a frame whose tiles filled ``image`` (H, W, 4 or 4 + guides)."""
    albedo = normal = None
    if image.shape[2] > 4:
        albedo, normal = image[..., 4:7], image[..., 7:10]
    return RenderResult(image[..., :4], stats, dtype.name, missed_colour(scene, settings),
                        settings.semantics, albedo=albedo, normal=normal, **extra)
