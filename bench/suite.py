"""What ``python -m bench`` runs: the workloads, their contenders, and the cost curves.

Workloads (``--only NAME``):

* article-small, article-hd, article-uhd: the article's scene, depth 3, at 300x200,
  1920x1080 and 3840x2160.
* spheres: 1,000 small random spheres over the article's floor (``bench.scenes``), 1920x1080.
* spheres-nofloor: the same spheres without the floor: an ordinary small scene, the kind
  precision 'auto' renders in float32.
* aa-adaptive, aa-fixed16: the article's scene at 1920x1080 with anti-aliasing.
* aa-dense: a dense field of 10,000 random spheres (``bench.scenes``' sphere set) at 640x360,
  where almost every pixel is an edge: adaptive against fixed 16, time and RMS error against
  fixed AA at ``dense_reference_samples`` (errors at the same size as the times).
* cost-pixels, cost-spheres: time and peak memory against pixel count (up to 7680x4320) and
  against sphere count (1 to 100,000 ``core.Sphere`` objects).
* cost-sphere-sets: time and peak memory of Glint default/auto against sphere count when the
  spheres are one ``core.SphereSet`` (1 to 1,000,000 at 640x360, and 1,000 and 1,000,000 at
  1920x1080; ``bench.scenes``); the report fits each curve's exponent (time ~ count^k).
* malloc: the article's scene at article-hd's size (article/float64, 1 thread) in child
  processes with glibc's defaults and with ``core.allocator``'s settings: minor page faults,
  system and user time per render (``bench.allocation``).
* parallelism: the article's scene at article-hd's size (800x450 with --quick, so that
  processes are used), article/float64 and default/auto, on 1 and 2 threads and 1 and 2
  worker processes (``core.workers``), images checked bit for bit against one thread, CPU
  per frame in this process and in the workers; the processes' start-up is paid in the
  warm-up, and once more, alone, in a "cold" row (workers ended first).

* scale-points, scale-instances, scale-suzanne: the scale rows (``bench.scale``):
  scenes built in bpy (a million Geometry Nodes points; 100,000 UV spheres as Geometry Nodes
  instances, vertex instances and linked duplicates; Suzanne subdivided to 1,007,616
  triangles over a floor at 1920x1080), Glint's F12 (export + render, AA off) against
  Cycles' F12 at 1 spp, both in one child process per case, with their similarity.
* scale-noise: speed against noise (``bench.noise``): Glint's F12 at several world-sample
  counts and Cycles' at several sample counts on the instances scene, each image's noise
  against its own engine's converged image, and Cycles' time at Glint's noise.
* scale-export: ``export_scene`` alone on 100,000 and 1,000,000 instances, read in bulk and
  walked one by one, and on a million points (``bench.export_scale``).

For article-hd and spheres, Glint article/float64 and default/auto render once more on one
thread for the per-phase timers (``RayStats.phases``) that the report prints.

Contenders: Glint in each precision and semantics; the baseline (``bench.baseline``); the
article's per-pixel program (``bench.per_pixel``), timed small and scaled per pixel; Cycles
(CPU, 1 and 16 samples) and Workbench through bpy (``bench.blender``).

Errors are in 8-bit steps against a float64 reference of the same semantics: for the article's
semantics the baseline's image (the article's algorithm, checked against the article's own
image at 300x200 in every run); for Glint's default semantics, Glint in float64 with
``contribution_cutoff=0`` (no path is cut short).  ``--quick`` shrinks every size (the plan
is printed with the table).
"""

from __future__ import annotations

import glob
import hashlib
import os
import sys
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Optional

import numpy as np

from core import RenderSettings, Scene, render

from . import baseline, per_pixel
from .measure import Timing, cpu_seconds, measure, rgb_error, silhouette_mismatches
from .scenes import article_scene, random_sphere_set_scene, random_spheres_scene

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The article's own image: shared/ beside the checkout, else the tests' copy of it.
ARTICLE_REFERENCES = (
    os.path.join(os.path.dirname(REPOSITORY), "shared", "reference", "article_300x200.npy"),
    os.path.join(REPOSITORY, "tests", "data", "article_300x200.npy"),
)
#: The baseline must reproduce the article's own image this closely.
BASELINE_TOLERANCE = 1e-9
MAX_DEPTH = 3

Size = tuple[int, int]


@dataclass(frozen=True)
class Plan:
    """Sizes and counts of one bench run (``FULL`` or ``QUICK``)."""

    article_sizes: dict            # workload name -> (width, height)
    spheres_size: Size
    spheres_error_size: Size       # errors of the sphere scenes are computed at this size
    sphere_count: int
    aa_size: Size
    aa_error_size: Size            # AA errors (against the 256-spp reference) at this size
    aa_reference_samples: int
    adaptive_samples: tuple
    dense_size: Size               # aa-dense: timed and compared at this size
    dense_count: int
    dense_reference_samples: int
    per_pixel_article_size: Size
    per_pixel_spheres_size: Size
    cycles16_max_pixels: int       # Cycles at 16 spp only up to this many pixels
    pixel_curve: tuple
    sphere_curve_size: Size
    sphere_counts: tuple
    sphere_set_size: Size          # the cost-sphere-sets curve's size and counts
    sphere_set_counts: tuple
    sphere_set_hd: tuple           # (size, counts): the set curve's points at a large size
    baseline_max_elements: int     # rays x spheres of the baseline's one broadcast
    repeats: int
    budget: float                  # seconds of timed runs per contender after its warm-up
    # The scale-* workloads: workload name -> its bench.scale case specs, and the instance
    # counts of scale-export's bench.export_scale cases.
    scale_cases: dict = field(default_factory=dict)
    scale_export_counts: tuple = ()
    # scale-noise's bench.noise case: (spec, Glint's world samples, Glint's reference count,
    # Cycles' samples, Cycles' reference count).
    noise_case: tuple = ()


FULL = Plan(
    article_sizes={"article-small": (300, 200), "article-hd": (1920, 1080),
                   "article-uhd": (3840, 2160)},
    spheres_size=(1920, 1080), spheres_error_size=(480, 270), sphere_count=1000,
    aa_size=(1920, 1080), aa_error_size=(640, 360), aa_reference_samples=256,
    adaptive_samples=(16, 32),
    dense_size=(640, 360), dense_count=10_000, dense_reference_samples=64,
    per_pixel_article_size=(60, 40), per_pixel_spheres_size=(16, 9),
    cycles16_max_pixels=1920 * 1080,
    pixel_curve=((160, 90), (320, 180), (640, 360), (1280, 720), (1920, 1080), (3840, 2160),
                 (7680, 4320)),
    sphere_curve_size=(640, 360), sphere_counts=(1, 10, 100, 1000, 3000, 10000, 100_000),
    sphere_set_size=(640, 360),
    sphere_set_counts=(1, 10, 100, 1_000, 10_000, 100_000, 1_000_000),
    sphere_set_hd=((1920, 1080), (1_000, 1_000_000)),
    baseline_max_elements=40_000_000, repeats=3, budget=40.0)

QUICK = Plan(
    article_sizes={"article-small": (300, 200), "article-hd": (480, 270),
                   "article-uhd": (640, 360)},
    spheres_size=(480, 270), spheres_error_size=(96, 54), sphere_count=1000,
    aa_size=(300, 200), aa_error_size=(160, 90), aa_reference_samples=256,
    adaptive_samples=(16, 32),
    dense_size=(320, 180), dense_count=10_000, dense_reference_samples=64,
    per_pixel_article_size=(30, 20), per_pixel_spheres_size=(6, 4),
    cycles16_max_pixels=300 * 200,
    pixel_curve=((160, 90), (320, 180), (640, 360), (960, 540)),
    sphere_curve_size=(160, 90), sphere_counts=(1, 10, 100, 1000),
    sphere_set_size=(160, 90), sphere_set_counts=(1, 100, 10_000, 100_000),
    sphere_set_hd=((320, 180), (1_000, 100_000)),
    baseline_max_elements=5_000_000, repeats=1, budget=5.0)

#: The scale rows (``bench.scale``: Glint and Cycles through F12 on scenes built in
#: bpy, in child processes); KIND:COUNT:WIDTHxHEIGHT, COUNT being Suzanne's subdivision levels.
FULL = replace(FULL, scale_cases={
    "scale-points": ("points:1000000:640x360",),
    "scale-instances": ("instances:100000:640x360", "vertex-instances:100000:640x360",
                        "duplicates:100000:640x360"),
    "scale-suzanne": ("suzanne:5:1920x1080",)}, scale_export_counts=(100_000, 1_000_000),
    noise_case=("instances:100000:640x360", (1, 4, 9, 16), 256, (1, 2, 4, 8, 16, 32), 1024))
QUICK = replace(QUICK, scale_cases={
    "scale-points": ("points:1000:160x90",),
    "scale-instances": ("instances:1000:160x90", "vertex-instances:1000:160x90",
                        "duplicates:300:160x90"),
    "scale-suzanne": ("suzanne:2:320x180",)}, scale_export_counts=(10_000,),
    noise_case=("instances:1000:160x90", (1, 4, 9), 64, (1, 4, 16), 256))
SCALE_WORKLOADS = ("scale-points", "scale-instances", "scale-suzanne", "scale-noise",
                   "scale-export")

SCENE_WORKLOADS = ("article-small", "article-hd", "article-uhd", "spheres", "spheres-nofloor")
AA_WORKLOADS = ("aa-adaptive", "aa-fixed16", "aa-dense")
CURVES = ("cost-pixels", "cost-spheres", "cost-sphere-sets")
WORKLOADS = SCENE_WORKLOADS + AA_WORKLOADS + CURVES + ("parallelism", "malloc")
WORKLOADS = WORKLOADS + SCALE_WORKLOADS
#: Workloads whose Glint rows (CURVE_GLINTS) also get a per-phase breakdown.
PHASE_WORKLOADS = ("article-hd", "spheres")


@dataclass(frozen=True)
class Glint:
    """A Glint configuration."""

    semantics: str
    precision: str
    anti_aliasing: str = "off"
    samples: int = 16
    threads: Optional[int] = None          # None: one per core
    parallelism: str = "threads"

    def settings(self, **overrides) -> RenderSettings:
        values = dict(semantics=self.semantics, precision=self.precision, max_depth=MAX_DEPTH,
                      anti_aliasing=self.anti_aliasing, samples=self.samples,
                      threads=self.threads, parallelism=self.parallelism)
        values.update(overrides)
        return RenderSettings(**values)

    @property
    def label(self) -> str:
        text = f"Glint {self.semantics}/{self.precision}"
        if self.anti_aliasing != "off":
            text += f", {self.anti_aliasing} {self.samples} spp"
        if self.threads is not None:
            one, many = (("thread", "threads") if self.parallelism == "threads"
                         else ("process", "processes"))
            text += f", {self.threads} {one if self.threads == 1 else many}"
        return text


GLINT_PLAIN = tuple(Glint(s, p) for s in ("article", "default")
                    for p in ("float64", "float32", "auto"))
#: The two configurations the cost curves follow: float64-accurate, and Glint's defaults.
CURVE_GLINTS = (Glint("article", "float64"), Glint("default", "auto"))
#: The sphere-set curve's contender (a million spheres: one configuration is enough).
SET_CURVE_GLINT = Glint("default", "auto")
BASELINE_LABEL = "Baseline (vectorised NumPy)"
PER_PIXEL_LABEL = "Per-pixel (article's program)"


@dataclass
class Row:
    """One contender on one workload.  Errors are in 8-bit steps; None: not applicable."""

    workload: str                  # workload name (--only)
    title: str                     # e.g. "article 1920x1080"
    contender: str
    kind: str                      # glint | baseline | per-pixel | cycles | workbench
    timing: Timing
    seconds: float                 # median (scaled for the per-pixel program)
    semantics: Optional[str] = None
    precision: Optional[str] = None
    memory_kind: str = "traced"    # traced (tracemalloc peak) | rss (resident delta)
    max_error: Optional[float] = None
    rms_error: Optional[float] = None
    max_error_raw: Optional[float] = None  # in [0, 1] units
    silhouette: Optional[int] = None
    silhouette_outside_band: Optional[int] = None  # outside the floor's horizon band
    is_reference: bool = False
    glint: Optional[Glint] = None
    notes: list = field(default_factory=list)


@dataclass
class CurvePoint:
    curve: str                     # cost-pixels | cost-spheres | cost-sphere-sets
    contender: str
    width: int
    height: int
    spheres: int
    seconds: float
    runs: int
    peak_bytes: Optional[int]
    image_bytes: int
    #: Glint's tiles alone (``RayStats.seconds_tiles``, summed over its threads or workers):
    #: the tracing, without the frame's set-up (the tree's build, the context); None for the
    #: baseline.
    tile_seconds: Optional[float] = None
    #: Glint's rays traced (camera, shadow and reflection rays) and the box and primitive
    #: tests they made (``RayStats``), which split a curve's time into the rays a scene
    #: makes and the cost of each; None for the baseline.
    rays: Optional[int] = None
    tests: Optional[int] = None

    @property
    def pixels(self) -> int:
        return self.width * self.height


_START = time.perf_counter()


def log(message: str) -> None:
    print(f"[bench {time.perf_counter() - _START:6.1f} s] {message}", file=sys.stderr, flush=True)


def _source_hash(*patterns) -> str:
    digest = hashlib.sha256()
    for pattern in patterns:
        for path in sorted(glob.glob(os.path.join(REPOSITORY, pattern))):
            with open(path, "rb") as source:
                digest.update(source.read())
    return digest.hexdigest()[:12]


class Bench:
    """Runs workloads and curves, collecting ``rows`` and ``curve_points``."""

    def __init__(self, plan: Plan, out_dir: str, use_blender: bool = True):
        self.plan = plan
        self.out_dir = out_dir
        self.use_blender = use_blender
        self.rows: list[Row] = []
        self.curve_points: list[CurvePoint] = []
        self.notes: list[str] = []
        self._blender = None
        self._blender_error: Optional[str] = None
        self._blender_results = {}   # BlenderJob -> (Timing, image)
        self._timings = {}           # (scene key, contender key) -> (Timing, image bytes)
        self._tile_stats = {}        # (scene key, contender key) -> a render's RayStats
        self._floor_bands = {}       # size -> bool mask
        self.phases: list[tuple] = []  # (workload title, contender, RayStats) per-phase timers
        self.scale_results: list[dict] = []  # bench.scale's JSON result per scale case

    # ---------------------------------------------------------------------------------------
    # Measuring one contender

    def _measure(self, key, work: Callable[[], object], image_bytes: Callable[[object], int]):
        """(warm-up result or None if reused, Timing, image bytes), reusing a measurement of
        the same contender on the same scene made earlier in this run."""
        if key in self._timings:
            timing, size = self._timings[key]
            return None, timing, size
        result, timing = measure(work, self.plan.repeats, self.plan.budget)
        size = image_bytes(result)
        self._timings[key] = (timing, size)
        return result, timing, size

    def measure_glint(self, scene_key, scene: Scene, glint: Glint):
        """(RenderResult or None if reused, Timing, image bytes)."""
        settings = glint.settings()
        return self._measure((scene_key, glint), lambda: render(scene, settings),
                             lambda result: result.image.nbytes)

    def measure_phases(self, title: str, scene: Scene, glint: Glint) -> None:
        """One more render on one thread, outside tracemalloc: its per-phase timers."""
        stats = render(scene, glint.settings(threads=1)).stats
        self.phases.append((title, glint.label + ", 1 thread", stats))

    def measure_baseline(self, scene_key, scene: Scene):
        """(image or None if reused, Timing, image bytes)."""
        return self._measure((scene_key, "baseline"), lambda: baseline.render(scene, MAX_DEPTH),
                             lambda image: image.nbytes)

    def baseline_fits(self, scene: Scene) -> bool:
        if scene.sphere_sets or scene.meshes:
            return False          # the baseline knows spheres listed one by one only
        elements = scene.camera.width * scene.camera.height * len(scene.spheres)
        return elements <= self.plan.baseline_max_elements

    # ---------------------------------------------------------------------------------------
    # References

    def check_baseline(self) -> None:
        """The baseline must compute the article's image: asserted on every run."""
        # Explicit raises rather than assert statements, which python -O would drop.
        path = next((p for p in ARTICLE_REFERENCES if os.path.exists(p)), None)
        if path is None:
            raise FileNotFoundError(f"the article's image is missing: {ARTICLE_REFERENCES}")
        image = baseline.render(article_scene(300, 200), MAX_DEPTH)
        error = float(np.abs(image[..., :3] - np.load(path)).max())
        if not error <= BASELINE_TOLERANCE:
            raise AssertionError(f"the baseline differs from {path} by {error:.3g} "
                                 f"(> {BASELINE_TOLERANCE:g})")
        self.notes.append(f"Baseline vs the article's own 300x200 image ({path}): max "
                          f"difference {error:.2g} (asserted <= {BASELINE_TOLERANCE:g}).")

    def _cached(self, name: str, compute: Callable[[], np.ndarray]) -> np.ndarray:
        os.makedirs(self.out_dir, exist_ok=True)
        path = os.path.join(self.out_dir, name)
        if os.path.exists(path):
            return np.load(path)
        log(f"computing {name}")
        image = compute()
        np.save(path + ".tmp.npy", image)
        os.replace(path + ".tmp.npy", path)
        return image

    def article_reference(self, scene_key, scene: Scene) -> np.ndarray:
        """The baseline's image of ``scene`` computed band by band (cached in out_dir, keyed
        by the baseline's and the scenes' source)."""
        key = "-".join(str(part) for part in scene_key)
        name = f"reference-article-{key}-{_source_hash('bench/baseline.py', 'bench/scenes.py')}.npy"
        return self._cached(name, lambda: baseline.render_in_chunks(scene, MAX_DEPTH))

    @staticmethod
    def default_reference(scene: Scene) -> np.ndarray:
        return render(scene, Glint("default", "float64").settings(contribution_cutoff=0.0)).image

    def aa_reference(self, semantics: str, size: Size) -> np.ndarray:
        """Glint float64 with fixed AA at ``aa_reference_samples`` per pixel (cached, keyed by
        the core's source)."""
        samples = self.plan.aa_reference_samples
        name = (f"reference-aa-{semantics}-{size[0]}x{size[1]}-{samples}spp-"
                f"{_source_hash('core/*.py')}.npy")
        settings = Glint(semantics, "float64", "fixed", samples).settings()
        return self._cached(name, lambda: render(article_scene(*size), settings).image)

    # ---------------------------------------------------------------------------------------
    # Blender

    def blender(self):
        if not self.use_blender:
            return None
        if self._blender is None and self._blender_error is None:
            from .blender import BlenderSession, BlenderUnavailable

            try:
                self._blender = BlenderSession()
            except BlenderUnavailable as error:
                self._blender_error = str(error)
                self.notes.append(f"Blender contenders skipped: {error}.")
        return self._blender

    def blender_result(self, job):
        """(Timing, image (H, W, 4)) of a Blender job, measured once per run."""
        if job not in self._blender_results:
            from .blender import measure_memory

            session = self.blender()
            log(f"{job.label} {job.width}x{job.height}")
            session.scene(job)
            _, timing = measure(lambda: session.render(job), self.plan.repeats,
                                self.plan.budget, trace_memory=False)
            image = session.last_image(job)
            timing.peak_bytes = measure_memory(job)
            self._blender_results[job] = (timing, image)
        return self._blender_results[job]

    def workbench_mask(self, size: Size) -> Optional[np.ndarray]:
        """Workbench's coverage (alpha > 0.5) of the article's scene, or None without Blender."""
        from .blender import WORKBENCH, BlenderJob

        if self.blender() is None:
            return None
        _, image = self.blender_result(BlenderJob(WORKBENCH, 1, *size))
        return image[..., 3] > 0.5

    def floor_band(self, size: Size) -> np.ndarray:
        """Pixels where the article's analytic floor sphere and Blender's UV-sphere floor
        disagree about coverage: the floor mesh's facets (sagitta ~10 units) put its horizon
        rows away from the sphere's, so silhouettes are also compared outside this band."""
        from .blender import WORKBENCH, BlenderJob

        if size not in self._floor_bands:
            job = BlenderJob(WORKBENCH, 1, *size, floor_only=True)
            self.blender().render(job)
            mesh = self.blender().last_image(job)[..., 3] > 0.5
            floor_only = article_scene(*size)
            floor_only = Scene(camera=floor_only.camera, spheres=floor_only.spheres[-1:],
                               lights=floor_only.lights)
            origins, directions = baseline.camera_rays(floor_only.camera)
            index, _ = baseline.nearest(baseline.article_arrays(floor_only), origins, directions)
            analytic = (index >= 0).reshape(size[1], size[0])
            self._floor_bands[size] = analytic != mesh
        return self._floor_bands[size]

    def set_silhouette(self, row: Row, mask: np.ndarray, size: Size) -> None:
        workbench = self.workbench_mask(size)
        if workbench is None:
            return
        row.silhouette = silhouette_mismatches(mask, workbench)
        outside = ~self.floor_band(size)
        row.silhouette_outside_band = silhouette_mismatches(mask[outside], workbench[outside])

    # ---------------------------------------------------------------------------------------
    # Workloads

    def run(self, names) -> None:
        self.check_baseline()
        for name in names:
            if name in self.plan.article_sizes:
                self.article_workload(name)
            elif name == "spheres":
                self.spheres_workload(name, floor=True)
            elif name == "spheres-nofloor":
                self.spheres_workload(name, floor=False)
            elif name in AA_WORKLOADS:
                self.aa_workload(name)
            elif name == "cost-pixels":
                self.pixel_curve()
            elif name == "cost-spheres":
                self.sphere_curve()
            elif name == "cost-sphere-sets":
                self.sphere_set_curve()
            elif name == "parallelism":
                self.parallelism_workload(name)
            elif name == "malloc":
                self.malloc_workload(name)
            elif name == "scale-export":
                self.scale_export_workload(name)
            elif name == "scale-noise":
                self.noise_workload(name)
            elif name in SCALE_WORKLOADS:
                self.scale_workload(name)
            else:
                raise ValueError(f"unknown workload {name!r}")

    def article_workload(self, name: str) -> None:
        width, height = self.plan.article_sizes[name]
        scene = article_scene(width, height)
        jobs = self._blender_jobs(width, height)
        self.scene_workload(name, f"article {width}x{height}", ("article", width, height),
                            scene, lambda w, h: article_scene(w, h), (width, height),
                            self.plan.per_pixel_article_size, jobs)

    def spheres_workload(self, name: str, floor: bool) -> None:
        width, height = self.plan.spheres_size
        count = self.plan.sphere_count

        def make(w, h):
            return random_spheres_scene(count, w, h, floor=floor)

        title = f"{count} spheres{'' if floor else ', no floor'} {width}x{height}"
        self.scene_workload(name, title, ("spheres", count, floor, width, height),
                            make(width, height), make, self.plan.spheres_error_size,
                            self.plan.per_pixel_spheres_size, ())

    def _blender_jobs(self, width: int, height: int):
        from .blender import CYCLES, WORKBENCH, BlenderJob

        jobs = [BlenderJob(WORKBENCH, 1, width, height), BlenderJob(CYCLES, 1, width, height)]
        if width * height <= self.plan.cycles16_max_pixels:
            jobs.append(BlenderJob(CYCLES, 16, width, height))
        else:
            self.notes.append(f"Cycles at 16 spp not run at {width}x{height} "
                              f"(it would take minutes; it runs at sizes up to "
                              f"{self.plan.cycles16_max_pixels} pixels).")
        return jobs

    def scene_workload(self, name, title, scene_key, scene, make_scene, error_size,
                       per_pixel_size, blender_jobs) -> None:
        """Glint in every precision and semantics, the baseline, the per-pixel program and
        the Blender jobs on one scene."""
        size = (scene.camera.width, scene.camera.height)
        at_size = error_size == size
        error_scene = scene if at_size else make_scene(*error_size)
        error_note = "" if at_size else f"errors at {error_size[0]}x{error_size[1]}"
        masks = {}
        rows = []

        references = {}
        if self.baseline_fits(scene):
            log(f"{title}: {BASELINE_LABEL}")
            image, timing, _ = self.measure_baseline(scene_key, scene)
            if image is None:  # measured earlier in this run: the reference is needed again
                image = baseline.render(scene, MAX_DEPTH)
            row = Row(name, title, BASELINE_LABEL, "baseline", timing, timing.median,
                      semantics="article", precision="float64", is_reference=True,
                      notes=["1 thread; the article-semantics reference"])
            masks[row.contender] = image[..., 3] > 0.5
            rows.append(row)
            references["article"] = image if at_size else self.article_reference(
                (*scene_key[:-2], *error_size), error_scene)
            del image
        else:
            elements = scene.camera.width * scene.camera.height * len(scene.spheres)
            self.notes.append(
                f"{title}: the baseline's one broadcast would hold {elements:.2g} ray-sphere "
                f"pairs ({baseline.one_broadcast_bytes(scene) / 2**30:.1f} GiB per (m, n) "
                f"array, about ten of them at once); not run.")
            references["article"] = self.article_reference(
                (*scene_key[:-2], *error_size), error_scene)
        references["default"] = self.default_reference(error_scene)

        for glint in GLINT_PLAIN:
            log(f"{title}: {glint.label}")
            result, timing, _ = self.measure_glint(scene_key, scene, glint)
            if name in PHASE_WORKLOADS and glint in CURVE_GLINTS:
                self.measure_phases(title, scene, glint)
            if result is None:
                result = render(scene, glint.settings())
            error_image = result.image if at_size else render(error_scene, glint.settings()).image
            row = Row(name, title, glint.label, "glint", timing, timing.median,
                      semantics=glint.semantics, precision=result.precision, glint=glint)
            self._set_errors(row, error_image, references[glint.semantics], error_note)
            masks[row.contender] = result.image[..., 3] > 0.5
            rows.append(row)
            del result, error_image

        rows.append(self._per_pixel_row(name, title, make_scene, size, per_pixel_size))

        if blender_jobs and self.blender() is not None:
            for job in blender_jobs:
                timing, image = self.blender_result(job)
                row = Row(name, title, job.label, "cycles" if job.engine == "CYCLES"
                          else "workbench", timing, timing.median, memory_kind="rss",
                          notes=["all cores"])
                if job.engine == "CYCLES":
                    self._set_errors(row, image, references["article"], "",
                                     "vs the article reference: a different light model "
                                     "(physically based, 1/d^2 falloff)")
                else:
                    row.notes.append("RGB not comparable (studio lighting)")
                masks[row.contender] = image[..., 3] > 0.5
                rows.append(row)
            for row in rows:
                if row.contender in masks:
                    self.set_silhouette(row, masks[row.contender], size)
        self.rows.extend(rows)

    def _set_errors(self, row: Row, image, reference, where: str = "", note: str = "") -> None:
        row.max_error, row.rms_error = rgb_error(image, reference)
        row.max_error_raw = row.max_error / 255.0
        for text in (where, note):
            if text:
                row.notes.append(text)

    def _per_pixel_row(self, name, title, make_scene, size, small_size) -> Row:
        small = make_scene(*small_size)
        log(f"{title}: {PER_PIXEL_LABEL} at {small_size[0]}x{small_size[1]}")
        image, timing = measure(lambda: per_pixel.render(small, MAX_DEPTH), self.plan.repeats,
                                self.plan.budget)
        scale = (size[0] * size[1]) / (small_size[0] * small_size[1])
        row = Row(name, title, PER_PIXEL_LABEL, "per-pixel", timing, timing.median * scale,
                  semantics="article", precision="float64",
                  notes=[f"timed at {small_size[0]}x{small_size[1]} and scaled x{scale:.0f} "
                         f"per pixel; memory and errors at {small_size[0]}x{small_size[1]}"])
        self._set_errors(row, image, baseline.render_in_chunks(small, MAX_DEPTH))
        return row

    def dense_reference(self, semantics: str) -> np.ndarray:
        """The dense field in Glint float64 with fixed AA at ``dense_reference_samples``
        (cached, keyed by the core's and the scenes' source)."""
        (width, height), samples = self.plan.dense_size, self.plan.dense_reference_samples
        name = (f"reference-dense-{semantics}-{self.plan.dense_count}-{width}x{height}-"
                f"{samples}spp-{_source_hash('core/*.py', 'bench/scenes.py')}.npy")
        scene = random_sphere_set_scene(self.plan.dense_count, width, height)
        settings = Glint(semantics, "float64", "fixed", samples).settings()
        return self._cached(name, lambda: render(scene, settings).image)

    def dense_workload(self, name: str) -> None:
        """Adaptive against fixed 16 where nearly every pixel is an edge."""
        width, height = self.plan.dense_size
        count = self.plan.dense_count
        scene = random_sphere_set_scene(count, width, height)
        title = f"{count:,} spheres {width}x{height}, AA"
        glints = [Glint("article", "float64", "fixed", 16)]
        glints += [Glint("article", "float64", "adaptive", samples)
                   for samples in self.plan.adaptive_samples]
        glints += [Glint("default", "auto", "fixed", 16),
                   Glint("default", "auto", "adaptive", self.plan.adaptive_samples[0])]
        rows = {}
        for glint in glints:
            log(f"{title}: {glint.label}")
            result, timing, _ = self.measure_glint(("sphere-set", count, width, height), scene,
                                                   glint)
            if result is None:
                result = render(scene, glint.settings())
            row = Row(name, title, glint.label, "glint", timing, timing.median,
                      semantics=glint.semantics, precision=result.precision, glint=glint)
            self._set_errors(row, result.image, self.dense_reference(glint.semantics),
                             f"errors vs Glint {self.plan.dense_reference_samples} spp")
            pixels = width * height
            row.notes.append(f"supersampled {result.stats.supersampled_pixels / pixels:.0%} "
                             f"of pixels, {result.stats.camera_rays / pixels:.1f} camera "
                             f"rays per pixel")
            rows[glint] = row
        for glint, row in rows.items():
            fixed = rows[Glint(glint.semantics, glint.precision, "fixed", 16)]
            if glint.anti_aliasing == "adaptive":
                row.notes.append(f"{row.seconds / fixed.seconds:.2f} of fixed 16's time, RMS "
                                 f"{row.rms_error:.3g} vs its {fixed.rms_error:.3g}")
        self.rows.extend(rows.values())

    def aa_workload(self, name: str) -> None:
        if name == "aa-dense":
            return self.dense_workload(name)
        width, height = self.plan.aa_size
        error_size = self.plan.aa_error_size
        scene = article_scene(width, height)
        error_scene = article_scene(*error_size)
        if name == "aa-adaptive":
            glints = [Glint("article", "float64", "adaptive", samples)
                      for samples in self.plan.adaptive_samples]
            glints.append(Glint("default", "auto", "adaptive", self.plan.adaptive_samples[0]))
        else:
            glints = [Glint("article", "float64", "fixed", 16), Glint("default", "auto", "fixed", 16)]
        title = f"article {width}x{height}, {name[3:]} AA"
        samples = self.plan.aa_reference_samples
        rows = []
        for glint in glints:
            log(f"{title}: {glint.label}")
            result, timing, _ = self.measure_glint(("article", width, height), scene, glint)
            if result is None:
                result = render(scene, glint.settings())
            row = Row(name, title, glint.label, "glint", timing, timing.median,
                      semantics=glint.semantics, precision=result.precision, glint=glint)
            self._set_errors(row, render(error_scene, glint.settings()).image,
                             self.aa_reference(glint.semantics, error_size),
                             f"errors vs Glint {samples} spp at {error_size[0]}x{error_size[1]}")
            if self.blender() is not None:
                self.set_silhouette(row, result.image[..., 3] > 0.5, (width, height))
            rows.append(row)
        if name == "aa-fixed16" and self.blender() is not None:
            from .blender import CYCLES, BlenderJob

            job = BlenderJob(CYCLES, 16, width, height)
            timing, image = self.blender_result(job)
            row = Row(name, title, job.label, "cycles", timing, timing.median,
                      memory_kind="rss", notes=["all cores; AA error not comparable "
                                                "(different light model)"])
            self.set_silhouette(row, image[..., 3] > 0.5, (width, height))
            rows.append(row)
        self.rows.extend(rows)

    # ---------------------------------------------------------------------------------------
    # Cost curves

    def _curve_point(self, curve, scene_key, scene, contender) -> None:
        stats = None
        if contender == "baseline":
            label = BASELINE_LABEL
            _, timing, image_bytes = self.measure_baseline(scene_key, scene)
        else:
            label = contender.label
            result, timing, image_bytes = self.measure_glint(scene_key, scene, contender)
            if result is not None:   # the warm-up's; a reused measurement keeps its own
                self._tile_stats[scene_key, contender] = result.stats
            stats = self._tile_stats.get((scene_key, contender))
        traced = None if stats is None else dict(
            tile_seconds=stats.seconds_tiles,
            rays=stats.camera_rays + stats.shadow_rays + stats.reflection_rays,
            tests=stats.node_tests + stats.sphere_tests + stats.triangle_tests)
        self.curve_points.append(CurvePoint(
            curve, label, scene.camera.width, scene.camera.height, scene.sphere_count,
            timing.median, len(timing.runs), timing.peak_bytes, image_bytes, **(traced or {})))

    def pixel_curve(self) -> None:
        for width, height in self.plan.pixel_curve:
            scene = article_scene(width, height)
            contenders = list(CURVE_GLINTS) + (["baseline"] if self.baseline_fits(scene) else [])
            for contender in contenders:
                log(f"cost-pixels {width}x{height}: "
                    f"{contender if contender == 'baseline' else contender.label}")
                self._curve_point("cost-pixels", ("article", width, height), scene, contender)

    def sphere_curve(self) -> None:
        width, height = self.plan.sphere_curve_size
        for count in self.plan.sphere_counts:
            scene = random_spheres_scene(count, width, height)
            contenders = list(CURVE_GLINTS) + (["baseline"] if self.baseline_fits(scene) else [])
            for contender in contenders:
                log(f"cost-spheres {count} spheres: "
                    f"{contender if contender == 'baseline' else contender.label}")
                self._curve_point("cost-spheres", ("spheres", count, True, width, height),
                                  scene, contender)

    def sphere_set_curve(self) -> None:
        """The set curve at its size, then its large-size points (a million spheres at
        1920x1080 against a thousand)."""
        hd_size, hd_counts = self.plan.sphere_set_hd
        points = [(self.plan.sphere_set_size, count) for count in self.plan.sphere_set_counts]
        for (width, height), count in points + [(hd_size, count) for count in hd_counts]:
            scene = random_sphere_set_scene(count, width, height)
            log(f"cost-sphere-sets {count} spheres {width}x{height}: {SET_CURVE_GLINT.label}")
            self._curve_point("cost-sphere-sets", ("sphere-set", count, width, height), scene,
                              SET_CURVE_GLINT)

    def parallelism_workload(self, name: str) -> None:
        """Threads against worker processes, 1 and 2 of each, on the article's scene, in
        article/float64 and default/auto."""
        from core import workers

        width, height = self.plan.article_sizes["article-hd"]
        if width * height < workers.MIN_PIXELS:   # --quick: big enough to use processes
            width, height = 800, 450
        title = f"article {width}x{height}, parallelism"
        scene = article_scene(width, height)
        for semantics, precision in (("article", "float64"), ("default", "auto")):
            reference = None
            medians = {}
            for parallelism in ("threads", "processes"):
                for count in (1, 2):
                    glint = Glint(semantics, precision, threads=count, parallelism=parallelism)
                    log(f"{title}: {glint.label}")
                    result, timing, _ = self.measure_glint(("article", width, height), scene,
                                                           glint)
                    row = Row(name, title, glint.label, "glint", timing, timing.median,
                              semantics=semantics, precision=result.precision, glint=glint)
                    medians[parallelism, count] = timing.median
                    if reference is None:
                        reference = result.image
                        row.notes.append("the reference of this workload's images")
                    elif np.array_equal(result.image, reference):
                        row.notes.append("image identical to 1 thread's")
                    else:
                        raise AssertionError(f"{glint.label}: image differs from 1 thread's")
                    row.notes.append(self._cpu_per_frame(scene, glint.settings()))
                    if result.parallelism != parallelism:
                        row.notes.append(f"ran on {result.parallelism} (core.workers."
                                         f"MIN_PIXELS or processes unavailable)")
                    elif parallelism == "processes":
                        row.notes.append("memory: this process only")
                    if (parallelism, count) == ("processes", 2):
                        row.notes.append(
                            f"{medians['processes', 1] / timing.median:.2f}x 1 process, "
                            f"{medians['threads', 1] / timing.median:.2f}x 1 thread (medians "
                            f"of this run)")
                    self.rows.append(row)
        glint = Glint("article", "float64", threads=2, parallelism="processes")
        settings = glint.settings()
        workers.shutdown()
        start = time.perf_counter()
        ran = render(scene, settings).parallelism
        cold = time.perf_counter() - start
        self.rows.append(Row(name, title, glint.label + ", cold", "glint", Timing([cold]), cold,
                             semantics="article", precision="float64", glint=glint,
                             notes=["workers started in this run" if ran == "processes"
                                    else f"ran on {ran}"]))

    @staticmethod
    def _cpu_per_frame(scene, settings) -> str:
        """CPU seconds of one more render, in this process and in the workers."""
        from core import workers

        pids = workers.worker_pids() if settings.parallelism == "processes" else []
        before = cpu_seconds(), cpu_seconds(pids)
        render(scene, settings)
        after = cpu_seconds(), cpu_seconds(pids)
        if None in before + after:
            return "CPU per frame not measured (no /proc)"
        here = after[0] - before[0]
        if not pids:
            return f"CPU per frame {here:.2f} s (one more render)"
        there = (after[1] - after[0]) - (before[1] - before[0])
        return (f"CPU per frame {here + there:.2f} s: {here:.3f} s in this process, "
                f"{there:.2f} s in workers (one more render)")

    def malloc_workload(self, name: str) -> None:
        """Faults and system time per render, glibc's defaults against core.allocator."""
        from . import allocation

        width, height = self.plan.article_sizes["article-hd"]
        title = f"article {width}x{height}, malloc"
        log(f"{title}: child processes, glibc defaults and tuned")
        results = allocation.compare(width, height, threads=1, renders=self.plan.repeats)
        for mode, runs in results.items():
            label = f"Glint article/float64, 1 thread, malloc {mode}"
            if runs is None:
                self.notes.append(f"{title}: tuned malloc not applicable (not Linux with glibc)")
                continue
            timing = Timing([run["wall"] for run in runs])
            self.rows.append(Row(name, title, label, "glint", timing, timing.median,
                                 semantics="article", precision="float64",
                                 notes=[allocation.summary(runs) + " per render, in 2 child "
                                        "processes after a warm-up render each"]))

    # ---------------------------------------------------------------------------------------
    # The scale rows against Cycles

    def skipped_without_blender(self, name: str) -> bool:
        """True (and a note) when --no-blender leaves out a workload whose contenders are
        all Blender renders."""
        if not self.use_blender:
            self.notes.append(f"{name}: not run (--no-blender; both contenders are Blender "
                              f"renders)")
        return not self.use_blender

    def scale_workload(self, name: str) -> None:
        """Glint (F12: export + render) and Cycles at 1 spp on each of the workload's
        ``bench.scale`` cases, both in one child process per case."""
        from . import scale

        if self.skipped_without_blender(name):
            return
        for spec in self.plan.scale_cases[name]:
            case = scale.Case.parse(spec)
            log(f"{case.title}: Glint and Cycles (bench.scale child)")
            (result,) = scale.run([case], self.plan.repeats, self.plan.budget, self.out_dir)
            self.scale_results.append(result)
            self.rows.extend(scale_rows(name, result))

    def noise_workload(self, name: str) -> None:
        """Glint's world samples against Cycles' samples, time and noise (``bench.noise``),
        in one child process."""
        from . import noise, scale

        if self.skipped_without_blender(name):
            return
        spec, glint_counts, glint_reference, cycles_counts, cycles_reference = \
            self.plan.noise_case
        case = scale.Case.parse(spec)
        log(f"{case.title}: noise against samples, Glint and Cycles (bench.noise child)")
        result = noise.run(case, glint_counts, glint_reference, cycles_counts,
                           cycles_reference, self.plan.repeats, self.plan.budget, self.out_dir)
        self.scale_results.append(dict(result, kind="noise"))
        self.rows.extend(noise_rows(name, result))

    def scale_export_workload(self, name: str) -> None:
        """export_scene alone on a million points and instances (``bench.export_scale``'s
        cases: in bulk from Geometry Nodes, and walked one by one)."""
        from . import export_scale

        for case in export_scale.CASES:
            for count in self.plan.scale_export_counts:
                log(f"export of {count:,} {case}")
                result = export_scale.run_child(case, count, self.plan.repeats)
                timing = Timing(result["runs"])
                self.scale_results.append(dict(result, kind="export"))
                self.rows.append(Row(
                    name, f"export of {count:,} {case}", "Glint export_scene", "glint", timing,
                    timing.median, notes=[
                        f"{result['drawn']:,} drawn; Blender's depsgraph evaluation before "
                        f"it {result['depsgraph_s']:.2f} s (not Glint's)"]))


SCALE_GLINT_LABEL = "Glint default/auto, AA off, F12 (export + render)"
SCALE_CYCLES_LABEL = "Cycles CPU, 1 spp, F12"


def scale_rows(name: str, result: dict) -> list:
    """The Glint and Cycles rows of one ``bench.scale`` case's result."""
    glint, cycles, alike = result["glint"], result["cycles"], result["similarity"]
    drawn = glint["drawn"]
    shapes = ", ".join(f"{drawn[key]:,} {label}" for key, label in
                       (("spheres", "spheres"), ("triangles", "triangles"))
                       if drawn[key]) or "nothing"
    glint_notes = [f"export {glint['export_s']:.3g} s + core render {glint['core_s']:.3g} s "
                   f"(within the F12; the rest is Blender's)",
                   f"drew {shapes}", _largest_phase(glint), _first(glint),
                   f"scene built in bpy in {result['build_s']:.3g} s"]
    glint_notes += [f"warning: {text}" for text in glint["warnings"]]
    r = "—" if alike["r"] is None else f"{alike['r']:.3f}"
    box = alike["box"]
    cycles_notes = ["all cores; default light paths", _first(cycles),
                    f"vs Glint: r {r} (RGB in {box}x{box} boxes), brightness Glint/Cycles "
                    f"{alike['brightness_ratio']:.2f}, coverage differs on "
                    f"{alike['coverage_mismatch']:,} of {alike['pixels']:,} pixels",
                    f"picture {os.path.basename(result['picture'])} (Glint left)"]
    return [Row(name, result["title"], SCALE_GLINT_LABEL, "glint", Timing(glint["runs"]),
                glint["median_s"], semantics="default", precision=glint["precision"],
                memory_kind="rss", notes=glint_notes),
            Row(name, result["title"], SCALE_CYCLES_LABEL, "cycles", Timing(cycles["runs"]),
                cycles["median_s"], memory_kind="rss", notes=cycles_notes)]


def noise_rows(name: str, result: dict) -> list:
    """A row per Glint world-sample count and per Cycles sample count of a ``bench.noise``
    result, each noting its noise against its own engine's converged image."""
    from .noise import BOX

    matched = {m["world_samples"]: m for m in result["equal_noise"]}
    rows = []
    for engine, label, kind in (("glint", "Glint default/auto, AA off, {} world samples, F12",
                                 "glint"), ("cycles", "Cycles CPU, {} spp, F12", "cycles")):
        reference = result[engine + "_reference"]["samples"]
        for entry in result[engine]:
            notes = [f"noise against the same engine at {reference}: RMS {entry['rms']:.3g} "
                     f"steps a pixel, {entry['box_rms']:.2g} in {BOX}x{BOX} boxes"]
            match = matched.get(entry["samples"]) if engine == "glint" else None
            if match is not None:
                how = "extrapolated" if match["extrapolated"] else "interpolated"
                notes.append(f"Cycles at the same noise: {match['seconds']:.3g} s "
                             f"(~{match['samples']:.3g} spp, {how})")
            rows.append(Row(name, result["title"] + ", noise", label.format(entry["samples"]),
                            kind, Timing(entry["runs"]), entry["median_s"],
                            semantics="default" if kind == "glint" else None,
                            memory_kind="rss", notes=notes))
    return rows


def _largest_phase(glint: dict) -> str:
    """The core render's costliest phase (``RayStats.phases``, summed over threads) and its
    rays, for where the time goes."""
    phases = {k: v for k, v in glint["phases"].items() if k != "tiles"}
    name = max(phases, key=phases.get)
    rays = glint["rays"]
    camera = max(rays["camera"], 1)
    return (f"core's largest phase: {name} {phases[name]:.3g} of {glint['phases']['tiles']:.3g} "
            f"thread-s; per camera ray {rays['shadow'] / camera:.2g} shadow rays, "
            f"{rays['node_tests'] / camera:.3g} node tests")


def _first(contender: dict) -> str:
    if contender["first_counted"]:
        return "one render, no warm-up (it took longer than the budget)"
    return f"warm-up render {contender['first_s']:.3g} s"
