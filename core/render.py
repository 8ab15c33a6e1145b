"""``render``: a scene in, an (H, W, 4) image out, tile by tile.

The frame's orchestrator: it plans the memory, builds the trace context, cuts the frame into
tiles, picks a scheduler (a thread pool, ``core.threads``; worker processes,
``core.workers``; a Dask cluster, ``core.cluster``) and runs it, the tiles landing here as
they finish.  Tiles bound the working memory whatever the resolution and are the unit of
parallelism: each writes only its own slice of the image, so the result does not depend on
how they ran.  A tile itself is ``core.tiles``'s.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .camera import has_aperture
from .colour import linear_to_srgb
from .context import RayStats, make_context, path_traced
from .failures import RenderError
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
from .tiles import BLOCK
from .trace import traces_bounces
from . import allocator, cluster, threads, workers


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
    plan = _plan(scene, settings, image_dtype, reserve_bytes, passes, geometry_policy)
    if plan.where == "processes":
        workers.prestart(plan.threads)  # they start while the context is built
    ctx = _context(scene, settings, plan, world, geometry_policy)
    primary = _primary_passes(passes, scene.camera)
    kind = _ProgressiveLanding if ctx.paths is not None else _TileLanding
    landing = kind(ctx, scene.camera, settings, plan, primary, world, on_tile, progress,
                   on_pass)
    image, parallelism, fallback = _run(landing, plan, ctx, scene.camera, settings,
                                        should_cancel)
    return _result(landing.image_from(image), landing.stats, plan.dtype, scene, settings,
                   parallelism=parallelism, passes=primary, fallback=fallback)


@dataclass
class _Plan:
    """How a frame runs, settled before anything large is allocated."""

    dtype: np.dtype          # the render's precision
    image_dtype: np.dtype
    threads: int             # tiles at once: threads or worker processes
    tiles: list              # (y0, y1, x0, x1) each, rows from the top
    where: str               # 'threads', 'processes' or 'cluster'
    #: Why tiles meant for the cluster run on this machine (the Emission pass), else None.
    kept_here: Optional[str] = None


def _plan(scene, settings, image_dtype, reserve_bytes, passes, geometry_policy) -> _Plan:
    """The frame's precision, tiles and scheduler; raises memory.NotEnoughMemory where the
    render cannot fit (``core.memory``)."""
    dtype = choose_precision(scene, settings.precision)
    width, height = scene.camera.width, scene.camera.height
    count = settings.threads or os.cpu_count() or 1   # (tiles at once: threads or workers)
    image_dtype = dtype if image_dtype is None else np.dtype(image_dtype)
    if passes:  # the passes' arrays, beside the image
        per_pixel = PrimaryPasses.BYTES_PER_PIXEL
        if isinstance(passes, PrimaryPasses) and passes.emission is not None:
            per_pixel += PrimaryPasses.EMISSION_BYTES_PER_PIXEL
        reserve_bytes += per_pixel * width * height
    tiles = _tiles(width, height, settings.tile_size)
    # Passes are filled in this process, beside each tile on its thread or, where the tiles
    # go to worker processes or a cluster, as each lands (``_TileLanding``): their trace
    # stops at the first hits, a small part of a tile's work.  The Emission pass follows
    # whole camera paths, so it keeps the tiles here.
    emission_pass = isinstance(passes, PrimaryPasses) and passes.emission is not None
    on_cluster = bool(settings.cluster) and not emission_pass
    kept_here = (f"the Emission pass is rendered on this machine, not on the cluster at "
                 f"{settings.cluster}") if settings.cluster and emission_pass else None
    tree = geometry_policy.builds_tree(scene.sphere_count, scene.triangle_count)
    in_processes = not emission_pass and not on_cluster and _in_processes(
        settings, width * height, len(tiles), count, tree, path_traced(scene, settings))
    memory_plan = memory.plan(scene, settings, image_dtype, count, reserve_bytes)
    if in_processes:  # plus the workers' interpreters and the scene's shared copy
        memory_plan = dataclasses.replace(memory_plan, other=memory_plan.other + workers.
                                          planned_bytes(count, memory_plan.scene))
    memory.check(memory_plan, width, height)
    if in_processes:
        tiles = _even_tail(tiles, count)
    where = "cluster" if on_cluster else "processes" if in_processes else "threads"
    return _Plan(dtype, image_dtype, count, tiles, where, kept_here)


def _context(scene, settings, plan, world, geometry_policy):
    """The frame's TraceContext, with what its tiles would each build on first use (in every
    worker process) built once here on the render's threads: the eye's bins, the occlusion
    trails' tables."""
    ctx = make_context(scene, settings, plan.dtype, threads=plan.threads,   # (the tree: on
                       frame=world, geometry_policy=geometry_policy)        # threads)
    shared_eye = ctx.camera_origin is not None and not has_aperture(scene.camera)
    tracing_paths = ctx.paths is not None
    ctx.geometry.build_frame_tables(ctx.camera_origin.position if shared_eye else None,
                                    bounces=tracing_paths or traces_bounces(ctx),
                                    trails=tracing_paths or traces_from_points(ctx),
                                    threads=plan.threads)
    return ctx


def _primary_passes(passes, camera) -> Optional[PrimaryPasses]:
    """The passes the frame fills: the caller's PrimaryPasses (of the image's size), new
    ones for passes=True, else None."""
    width, height = camera.width, camera.height
    if isinstance(passes, PrimaryPasses):
        if passes.depth.shape != (height, width):
            raise SceneError(f"passes are {passes.depth.shape[1]}x{passes.depth.shape[0]}, "
                             f"the image {width}x{height}")
        return passes
    return PrimaryPasses.empty(width, height) if passes else None


def _run(landing, plan: _Plan, ctx, camera, settings, should_cancel) -> tuple:
    """(image, parallelism, fallback): the frame's jobs run by the scheduler the plan chose,
    each landing here as it finishes: a cluster (``core.cluster``), worker processes
    (``core.workers``) or threads (``core.threads``), which take over from worker processes
    that cannot start.  image: the one the scheduler filled."""
    if plan.where == "cluster":
        image = cluster.render_tiles(settings.cluster, ctx, camera, landing.jobs(),
                                     landing.shape, landing.dtype, landing.land_from_afar,
                                     should_cancel)
        return image, "cluster", None
    fallback = plan.kept_here
    if plan.where == "processes":
        try:
            # The workers write their tiles straight into the image they share with this
            # process, which is the result (core.workers: no copy of any tile here).
            image, unavailable = workers.render_tiles(
                ctx, camera, landing.jobs(), landing.shape, landing.dtype, plan.threads,
                landing.land_from_afar, should_cancel)
            if unavailable is not None:  # the workers failed after some tiles landed
                return image, "threads", _fallback_line(unavailable)
            return image, "processes", None
        except workers.WorkersBusy:
            pass  # another render (a viewport) has them: threads, without a word
        except workers.ProcessesUnavailable as error:
            fallback = _fallback_line(str(error))
        # No tile has landed yet: the same jobs on threads, below.
    count = 1 if len(plan.tiles) == 1 else plan.threads
    image = threads.render_tiles(ctx, camera, landing.jobs(), landing.shape_here,
                                 landing.dtype, count, landing.land, should_cancel,
                                 beside=landing.beside)
    return image, "threads", fallback


def _refuse_non_finite(tile) -> None:
    """Never a silently wrong picture, even from a bug."""
    y0, y1, x0, x1 = tile[:4]
    raise RenderError(f"pixels {x0}-{x1 - 1} x {y0}-{y1 - 1} came out NaN or "
                      f"infinite; please report this scene")


class _Landing:
    """Where a frame's tiles land, on the calling thread, whichever scheduler rendered them
    (``_run``): the frame's stats, passes, ``on_tile`` and ``progress``.  A scheduler takes
    ``jobs()``, renders them into an image of ``shape`` and ``dtype`` (threads: of
    ``shape_here``, None for none), and hands each to ``land`` (threads, which run
    ``beside`` on the tile's thread first) or ``land_from_afar`` (worker processes, a
    cluster) as (job, pixels, stats, done, finite)."""

    beside = None

    def __init__(self, ctx, camera, settings, plan: _Plan, primary, world, on_tile,
                 progress, on_pass):
        self.ctx, self.camera, self.settings = ctx, camera, settings
        self.tiles = plan.tiles
        self.primary, self.world = primary, world
        self.on_tile, self.progress, self.on_pass = on_tile, progress, on_pass
        self.stats = RayStats()
        self.image_shape = (camera.height, camera.width,
                            4 + (GUIDE_CHANNELS if settings.guides else 0))

    def fill_passes(self, tile, tile_stats) -> None:
        """A tile's passes, if asked for."""
        if self.primary is not None:
            fill_tile_passes(self.primary, self.ctx, self.camera, tile, tile_stats, self.world)


class _TileLanding(_Landing):
    """A Whitted frame (``core.tiles``): the scheduler's image is the frame's."""

    def __init__(self, ctx, camera, settings, plan: _Plan, *rest):
        super().__init__(ctx, camera, settings, plan, *rest)
        self.shape, self.dtype = self.image_shape, plan.image_dtype
        self.shape_here = self.shape

    def jobs(self) -> list:
        return self.tiles

    def beside(self, tile, tile_stats) -> None:
        """On threads, a tile's passes are filled beside it, on its thread."""
        self.fill_passes(tile, tile_stats)

    def land(self, tile, pixels, tile_stats, done, finite, passes_filled=True) -> None:
        """A finished tile: pixels its (h, w, C) view of the image, finite whether the
        values it was made from are all finite (the schedulers check their own tiles,
        sparing this thread a pass over the image); passes_filled: by ``beside``."""
        if not finite:
            _refuse_non_finite(tile)
        if not passes_filled:
            self.fill_passes(tile, tile_stats)
        self.stats.add(tile_stats)
        if self.on_tile is not None:
            self.on_tile(tile, pixels[..., :4])
        if self.progress is not None:
            self.progress(done / len(self.tiles))

    def land_from_afar(self, tile, pixels, tile_stats, done, finite) -> None:
        """A tile from worker processes or a cluster: its passes are filled as it lands."""
        self.land(tile, pixels, tile_stats, done, finite, passes_filled=False)

    def image_from(self, scheduled: np.ndarray) -> np.ndarray:
        return scheduled


class _ProgressiveLanding(_Landing):
    """A path-traced frame, pass by pass (``core.progressive``): each job's sums land in the
    frame's totals and refresh its image; a pass's last job makes the next pass's jobs."""

    def __init__(self, ctx, camera, settings, plan: _Plan, *rest):
        super().__init__(ctx, camera, settings, plan, *rest)
        self.image = np.zeros(self.image_shape, plan.image_dtype)
        # The passes of what each pixel's first sample hit come with the tiles' sums; the
        # Emission pass follows whole camera paths of its own (``fill_passes``).
        self.carried = self.primary is not None and self.primary.emission is None
        self.queue, self.handed_out = self._first_pass(), False
        height, width = self.image_shape[:2]
        self.shape = (height, width,
                      self.queue.frame.channels + (PASS_CHANNELS if self.carried else 0))
        self.dtype = np.float32   # the sums as they travel (``ProgressiveFrame.land``)
        self.shape_here = None    # on threads, a tile's sums land from the tile itself

    def _first_pass(self) -> WorkQueue:
        return WorkQueue(ProgressiveFrame(self.settings, self.tiles, self.image,
                                          guides=self.settings.guides, passes=self.carried))

    def jobs(self) -> WorkQueue:
        """The frame's jobs from its first pass: anew for threads taking over from worker
        processes that could not start (none of their jobs landed)."""
        if self.handed_out:
            self.queue = self._first_pass()
        self.handed_out = True
        return self.queue

    def land(self, job, sums, tile_stats, done, finite) -> None:
        """A job's sums as they arrived (float32 from afar, the tile's own on threads)."""
        frame = self.queue.frame
        sums = np.asarray(sums, np.float64)
        if not (finite and np.isfinite(sums).all()):
            _refuse_non_finite(job)
        first_pass = job.first == 0
        if self.carried:
            if first_pass:
                store_first_hits(self.primary, job[:4], sums[..., -PASS_CHANNELS:])
            sums = sums[..., :-PASS_CHANNELS]
        elif first_pass:
            self.fill_passes(job[:4], tile_stats)
        view = frame.land(job, sums)
        self.stats.add(tile_stats)
        if self.on_tile is not None:
            self.on_tile(job[:4], view[..., :4])
        if self.progress is not None:
            before = frame.done_samples - frame.sizes[frame.passes_made - 1]
            share = 1 - frame.outstanding / max(len(self.tiles), 1)
            self.progress(min(1.0, (before + share * (frame.done_samples - before))
                              / self.settings.samples))
        if self.on_pass is not None and frame.pass_complete():
            self.on_pass(frame.done_samples, self.image)
        self.queue.refill()

    land_from_afar = land   # (the Emission pass is filled as its first pass lands anywhere)

    def image_from(self, scheduled: np.ndarray) -> np.ndarray:
        """The frame's image (the scheduler's held the sums as they travelled)."""
        return self.image


def _result(image, stats, dtype, scene, settings, **extra) -> RenderResult:
    """The RenderResult of a frame whose tiles filled ``image`` (H, W, 4 or 4 + guides)."""
    albedo = normal = None
    if image.shape[2] > 4:
        albedo, normal = image[..., 4:7], image[..., 7:10]
    return RenderResult(image[..., :4], stats, dtype.name, missed_colour(scene, settings),
                        settings.semantics, albedo=albedo, normal=normal, **extra)
