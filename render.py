"""Render a .blend (or the article's scene) with Glint to an 8-bit RGBA PNG or an OpenEXR.

    blender -b scene.blend --python render.py -- --output OUT.png [options]
    python render.py [scene.blend] --output OUT.png [options]        (pip bpy)
    python render.py scene.blend --output "out/frame_####.png" --frames 1-250 \
        --no-overwrite --placeholder                  (an animation several processes share)

Both do the same job.  Without a .blend, the article's scene is built in Blender
(``addon.utils.article_scene``).  Options override the scene's settings; everything else
(camera, objects, materials, world, Film > Transparent, ...) comes from the .blend.  The
frame is rendered by Glint's render engine, exactly as F12 would render it, and the PNG is
what Blender's colour management (view transform, look, exposure) makes of it: the pixels F12
saves and the Render button's Image shows (``write_output``).  With Film > Transparent, alpha
is the coverage (less holdouts and what Transparent BSDFs let through) and the background is
transparent.

How the add-on is loaded: this file sits in the repository root, which is the extension
package itself (``__init__.py``, ``addon/``, ``core/``).  ``import_glint`` loads that directory
as the package ``glint`` (``importlib.util.spec_from_file_location`` with
``submodule_search_locations``), whatever the checkout's directory is called, so the
add-on's relative imports work; it is then registered for this session (an installed Glint
extension, if enabled, is disabled for the session so the two do not clash).  Tests use the
same function.

Animations (``--frames``), Blender's frame claiming (overwrite / placeholders), the progress
line on stderr and EXR output (single layer, or multilayer with every view layer and pass)
are described at ``render_animation``, ``FrameClaim``, ``ProgressLine`` and ``write_exr``.

Errors (missing or unreadable .blend, no camera, unwritable or write-protected output, bad
option, invalid values, a render that cannot fit in memory) print one line and exit non-zero;
the PNG is written through a temporary file beside the output (the file a symlink points to)
and renamed, so a failure never leaves a partial file and never touches the previous one.
Ctrl-C (SIGINT) or SIGTERM cancels the render within about a tile's time, writes nothing and
exits 128 + the signal's number (130, 143), with one line saying so.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import re
import signal
import sys
import time

REPOSITORY = os.path.dirname(os.path.abspath(__file__))
PACKAGE_NAME = "glint"
PROGRAM = "render.py"

#: Limits checked before anything is loaded: Blender's resolution_x/y hard limits, and the
#: core's (core.scene.MAX_SAMPLES, MAX_DEPTH; repeated, as the package is imported later).
MIN_RESOLUTION, MAX_RESOLUTION = 4, 65536
MAX_SAMPLES = 16384
MAX_DEPTH = 256

EXIT_USAGE = 2   # bad option (argparse's convention)
EXIT_FAILURE = 1  # the render could not be made
#: Exit status after a signal cancelled the run: the shell's convention, 128 + its number.
EXIT_SIGNAL_BASE = 128


class RenderScriptError(Exception):
    """A problem reported to the user as one line."""


class Interruption:
    """SIGINT and SIGTERM, caught so that they cancel the render instead of raising inside
    Blender's or NumPy's code: the handler only records the signal; the engine polls
    ``requested`` between tiles (through its FrameRequest), the PNG writer between row blocks,
    and ``main`` between steps.  A second signal gets the default action (ends the process at
    once).  SIGINT is left alone when it is ignored, as a shell does for a command started
    in the background with '&'; SIGTERM then does the same job with its own exit status."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signal_number = None

    def install(self) -> None:
        for number in self.SIGNALS:
            if signal.getsignal(number) is not signal.SIG_IGN:
                signal.signal(number, self._handle)

    def _handle(self, number, frame) -> None:
        self.signal_number = number
        signal.signal(number, signal.SIG_DFL)

    def requested(self) -> bool:
        return self.signal_number is not None

    def check(self) -> None:
        if self.requested():
            raise Interrupted(self.signal_number)


class Interrupted(Exception):
    """The run was cancelled by a signal; nothing was written."""

    def __init__(self, signal_number: int):
        super().__init__(signal_number)
        self.signal_number = signal_number

    @property
    def exit_code(self) -> int:
        return EXIT_SIGNAL_BASE + self.signal_number

    def __str__(self) -> str:
        name = signal.Signals(self.signal_number).name
        how = " (Ctrl-C)" if self.signal_number == signal.SIGINT else ""
        return f"cancelled by {name}{how}; nothing written"


def import_glint():
    """The repository as the package ``glint`` (see the module docstring)."""
    module = sys.modules.get(PACKAGE_NAME)
    if module is not None:
        if os.path.realpath(os.path.dirname(module.__file__)) != os.path.realpath(REPOSITORY):
            raise RenderScriptError(f"another package named '{PACKAGE_NAME}' is already "
                                    f"imported from {module.__file__}")
        return module
    spec = importlib.util.spec_from_file_location(
        PACKAGE_NAME, os.path.join(REPOSITORY, "__init__.py"),
        submodule_search_locations=[REPOSITORY])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE_NAME] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[PACKAGE_NAME]
        raise
    return module


def register_glint(glint) -> None:
    """Register this checkout's add-on unless it already is; disable another Glint first."""
    import addon_utils
    import bpy

    from glint.addon.engine.final import GlintRenderEngine

    if GlintRenderEngine.is_registered:
        return
    for name in list(bpy.context.preferences.addons.keys()):
        if name.rsplit(".", 1)[-1] == PACKAGE_NAME:
            addon_utils.disable(name, default_set=False)
    glint.register()


# --------------------------------------------------------------------------------------------
# Arguments

class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        raise SystemExit(_fail(message, EXIT_USAGE))


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _at_most(maximum: int, minimum: int = 1):
    def parse(text: str) -> int:
        value = _positive_int(text)
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum}, got {value}")
        if value < minimum:  # Blender would silently raise it
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value
    return parse


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _percentage(text: str) -> int:
    value = _positive_int(text)
    if value > 10000:  # Blender's own limit for resolution_percentage
        raise argparse.ArgumentTypeError(f"must be at most 10000, got {value}")
    return value


def load_choices():
    """``core/choices.py`` (the choice lists, defined once; it imports nothing) loaded on its
    own, so the arguments are checked before the package and Blender are."""
    spec = importlib.util.spec_from_file_location(
        f"{PACKAGE_NAME}_choices", os.path.join(REPOSITORY, "core", "choices.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = _OneLineParser(prog=PROGRAM, description=__doc__.split("\n\n")[0])
    parser.add_argument("blend", nargs="?", help="scene .blend (default: the article's scene, "
                                                 "or the .blend Blender opened)")
    parser.add_argument("--output", required=True,
                        help="PNG or EXR file to write; #### is replaced by the frame number, "
                             "zero-padded to the number of #")
    parser.add_argument("--width", type=_at_most(MAX_RESOLUTION, MIN_RESOLUTION),
                        help="resolution X in pixels")
    parser.add_argument("--height", type=_at_most(MAX_RESOLUTION, MIN_RESOLUTION),
                        help="resolution Y in pixels")
    parser.add_argument("--percentage", type=_percentage, help="resolution percentage")
    parser.add_argument("--samples", type=_at_most(MAX_SAMPLES),
                        help="rays per anti-aliased pixel; turns Fixed anti-aliasing on if the "
                             "scene has it off")
    parser.add_argument("--max-depth", type=_at_most(MAX_DEPTH), help="bounces per path")
    parser.add_argument("--frame", type=_integer, help="frame to render")
    choices = load_choices()
    parser.add_argument("--semantics", choices=choices.SEMANTICS)
    parser.add_argument("--precision", choices=choices.PRECISIONS)
    parser.add_argument("--parallelism", choices=choices.PARALLELISM,
                        help=choices.help_text(choices.PARALLELISM_CHOICES) +
                             " (default: the scene's Glint > Performance > Parallelism)")
    parser.add_argument("--cluster", metavar="ADDRESS",
                        help="render the tiles on the Dask scheduler at ADDRESS "
                             "(tcp://HOST:8786 or tls://HOST:8786; default: the scene's "
                             "Glint > Performance > Cluster, empty for this computer)")
    add_animation_arguments(parser)
    args = parser.parse_args(argv)
    if args.cluster and importlib.util.find_spec("distributed") is None:
        parser.error('--cluster needs Dask\'s distributed scheduler: pip install '
                     '"dask[distributed]"')

    if not args.output.lower().endswith(OUTPUT_EXTENSIONS):
        parser.error(f"--output must name a .png or .exr file, got {args.output!r}")
    check_animation_arguments(parser, args)
    output = os.path.abspath(args.output)
    folder = os.path.dirname(output)
    if os.path.isdir(output):
        parser.error(f"--output {args.output!r} is a directory")
    if not os.path.isdir(folder):
        parser.error(f"--output folder does not exist: {folder}")
    target = os.path.realpath(output)  # a symlink is written through
    if not os.path.isdir(os.path.dirname(target)):
        parser.error(f"--output {args.output!r} links into a folder that does not exist: "
                     f"{os.path.dirname(target)}")
    if not os.access(os.path.dirname(target), os.W_OK):
        parser.error(f"--output folder is not writable: {os.path.dirname(target)}")
    if write_protected(target):
        parser.error(f"--output {args.output!r} is write-protected: make it writable or "
                     f"choose another file")
    args.output = output
    if args.blend is not None:
        args.blend = os.path.abspath(args.blend)
        if not os.path.isfile(args.blend):
            parser.error(f"no such .blend file: {args.blend}")
    return args


def write_protected(path: str) -> bool:
    """core.png's rule, without importing the package before the arguments are checked."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return False
    return not (mode & 0o222) or not os.access(path, os.W_OK)


def script_arguments(argv: list[str]) -> list[str]:
    """The script's own arguments: after '--' if present (required under Blender, whose own
    arguments come first), else everything after the script name (``python render.py ...``).
    """
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return [] if running_in_blender() else argv[1:]


def running_in_blender() -> bool:
    """True inside the Blender program (``blender --python``), False with the pip module,
    whose ``bpy.app.binary_path`` is empty."""
    bpy = sys.modules.get("bpy")
    return bpy is not None and bool(bpy.app.binary_path)


# --------------------------------------------------------------------------------------------
# The job

def open_scene(blend):
    """The scene to render: ``blend`` opened, the .blend Blender already opened, or None when
    the article's scene must be built (the file is reset to an empty one first)."""
    import bpy

    if blend is not None:
        try:
            bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(f"cannot open {blend}: {reason}") from None
        return bpy.context.scene
    if bpy.data.filepath:
        return bpy.context.scene
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return None


def apply_options(scene, args) -> None:
    render, settings = scene.render, scene.glint
    if args.width is not None:
        render.resolution_x = args.width
    if args.height is not None:
        render.resolution_y = args.height
    if args.percentage is not None:
        render.resolution_percentage = args.percentage
    if args.samples is not None:
        settings.samples = args.samples
        if settings.anti_aliasing == 'OFF':
            settings.anti_aliasing = 'FIXED'
    if args.max_depth is not None:
        settings.max_depth = args.max_depth
    if args.semantics is not None:
        settings.semantics = args.semantics.upper()
    if args.precision is not None:
        settings.precision = args.precision.upper()
    if args.parallelism is not None:
        settings.parallelism = args.parallelism.upper()
    if args.cluster is not None:
        settings.cluster_address = args.cluster
    if args.frame is not None:
        frame = type(scene).bl_rna.properties["frame_current"]
        if not frame.hard_min <= args.frame <= frame.hard_max:
            raise RenderScriptError(f"--frame {args.frame} is outside Blender's frame range "
                                    f"{frame.hard_min} to {frame.hard_max}")
        scene.frame_set(args.frame)
    render.engine = "GLINT"
    # One view layer, and no compositing or sequencer work whose result is not written.
    render.use_single_layer = True
    render.use_compositing = False
    render.use_sequencer = False


def render_scene(scene, interruption: Interruption, progress=None, fill_render_result=False):
    """(RenderJob, JobResult) of the current frame, rendered by Glint's engine exactly as F12
    renders it; the engine hands the core's image over through a FrameRequest and leaves
    Blender's render result empty (this script writes the PNG itself) unless
    ``fill_render_result`` (EXR output, which Blender writes from its render result).
    progress(job, fraction): as tiles land."""
    import bpy

    from glint.addon.engine.final import FrameRequest, requesting_frames

    if scene.camera is None:  # Blender refuses before the engine runs, less clearly
        raise RenderScriptError(f"scene '{scene.name}' has no camera: add one and make it the "
                                f"scene camera")
    request = FrameRequest(should_cancel=interruption.requested,
                           fill_render_result=fill_render_result, progress=progress)
    with requesting_frames(request):
        try:
            bpy.ops.render.render(scene=scene.name)
        except RuntimeError as error:
            interruption.check()
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(reason) from None
    interruption.check()
    if not request.frames:
        raise RenderScriptError("render failed: Glint's engine produced no image")
    return request.frames[-1]


def write_output(path: str, image, should_cancel=None, *, scene=None, job=None) -> None:
    """Write the frame as an 8-bit RGBA PNG, atomically.

    With the Blender ``scene`` and the ``job`` that rendered ``image`` (the job's image, row
    0 = top): what Blender's colour management makes of the render result, as F12 saves it
    and as the Render button's Image shows it (one pipeline): the job's scene-linear pixels
    (``RenderJob.scene_linear``) go into a temporary float Image in the working space with
    *View as Render* on, which ``Image.save_render`` writes through the scene's view
    transform, look, exposure, gamma and dither; the scene's output format is left as it
    was.  Without them: the image's own values (display values) straight into the PNG."""
    from glint.addon.utils.colour import unpremultiply
    from glint.core.png import write_atomically, write_png

    try:
        if scene is None or job is None:
            # PNG stores straight alpha.
            write_png(path, image, convert=unpremultiply, should_cancel=should_cancel)
        else:
            write_atomically(path, _colour_managed_png(scene, _to_blender_rows(image, job)))
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None


#: Rows converted at a time by ``_to_blender_rows``: bounds its temporaries (float64 for the
#: sRGB curve) to a block instead of the frame.
ROW_BLOCK = 256


def _to_blender_rows(image, job):
    """The job's (H, W, 4) float32 image (row 0 = top) turned, in place and a block of rows at
    a time, into what Blender's render result holds (``RenderJob.scene_linear``), rows from
    the bottom; returns it.  In place because at 8K or 16K every full-frame copy is another
    0.5 or 4.3 GB (the image is not used after it is written)."""
    import numpy as np

    height = image.shape[0]
    for start in range(0, height, ROW_BLOCK):
        rows = slice(start, min(start + ROW_BLOCK, height))
        image[rows] = job.scene_linear(image[rows])
    half = height // 2
    for start in range(0, half, ROW_BLOCK):   # flip the rows, swapping blocks
        end = min(start + ROW_BLOCK, half)
        top = image[start:end].copy()
        image[start:end] = image[height - end:height - start][::-1]
        image[height - end:height - start] = top[::-1]
    return np.ascontiguousarray(image, np.float32)   # no copy for the job's float32 image


def _colour_managed_png(scene, blender_rows) -> bytes:
    """PNG bytes of premultiplied scene-linear (H, W, 4) pixels (row 0 = bottom, as
    ``_to_blender_rows`` gives them) saved by Blender with ``scene``'s colour management
    (``write_output``)."""
    import tempfile

    import bpy
    import numpy as np

    from glint.addon.utils.image import COLOUR_SPACE

    height, width = blender_rows.shape[:2]
    image = bpy.data.images.new(".glint render.py output", width, height, alpha=True,
                                float_buffer=True)
    settings = scene.render.image_settings
    names = [name for name in ("media_type", "file_format", "color_mode", "color_depth")
             if hasattr(settings, name)]
    previous = {name: getattr(settings, name) for name in names}
    handle, temporary = tempfile.mkstemp(prefix=".glint-", suffix=".png")
    os.close(handle)
    try:
        image.colorspace_settings.name = COLOUR_SPACE
        image.alpha_mode = 'PREMUL'
        image.use_view_as_render = True
        image.pixels.foreach_set(blender_rows.reshape(-1))
        if "media_type" in previous:
            settings.media_type = 'IMAGE'
        settings.file_format, settings.color_mode, settings.color_depth = 'PNG', 'RGBA', '8'
        try:
            image.save_render(temporary, scene=scene)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise OSError(reason) from None
        with open(temporary, "rb") as stream:
            return stream.read()
    finally:
        for name, value in previous.items():
            setattr(settings, name, value)
        bpy.data.images.remove(image)
        os.unlink(temporary)


# --------------------------------------------------------------------------------------------
# Animations, frame claiming, the progress line and EXR output

OUTPUT_EXTENSIONS = (".png", ".exr")
#: --format: PNG (the core's 8-bit values), single-layer EXR (Combined, float) or multilayer
#: EXR (every view layer with its passes).
FORMATS = {"png": ".png", "exr": ".exr", "multilayer-exr": ".exr"}
_FRAME_RANGE = re.compile(r"^(-?\d+)(?:-(-?\d+))?$")


def add_animation_arguments(parser) -> None:
    parser.add_argument(
        "--frames", nargs="?", const="scene", metavar="START-END",
        help="render frames START to END (or one frame N) to --output, whose #### becomes "
             "each frame's number; without a value, the scene's frame range and step")
    parser.add_argument(
        "--overwrite", action=argparse.BooleanOptionalAction,
        help="with --frames: re-render frames whose file exists (default: the .blend's "
             "Output > Overwrite)")
    parser.add_argument(
        "--placeholder", action=argparse.BooleanOptionalAction,
        help="with --frames: claim a frame by creating its (empty) file before rendering it, "
             "so other processes skip it (default: the .blend's Output > Placeholders)")
    parser.add_argument(
        "--format", choices=sorted(FORMATS),
        help="output format (default from --output's extension: .png -> png, .exr -> exr, "
             "or multilayer-exr when the .blend's output is a multilayer image)")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress line on stderr (shown only on a terminal anyway)")


def check_animation_arguments(parser, args) -> None:
    args.frame_range = None
    if args.frames is not None and args.frame is not None:
        parser.error("--frame and --frames exclude each other")
    if args.frames not in (None, "scene"):
        match = _FRAME_RANGE.match(args.frames)
        if match is None:
            parser.error(f"--frames must be START-END or N, got {args.frames!r}")
        start = int(match.group(1))
        end = int(match.group(2)) if match.group(2) is not None else start
        if end < start:
            parser.error(f"--frames {args.frames}: the end frame comes before the start")
        args.frame_range = (start, end)
    if args.format is not None and not args.output.lower().endswith(FORMATS[args.format]):
        parser.error(f"--format {args.format} writes {FORMATS[args.format]} files, but --output "
                     f"is {args.output!r}")


def frame_path(template: str, frame: int, animation: bool = False) -> str:
    """Blender's frame numbering of output paths: the last run of '#' in the file name becomes
    the frame number, zero-padded to its length (``frame_####.png``, frame 7 ->
    ``frame_0007.png``; negative frames keep their sign).  Without '#', an animation's frame
    number goes before the extension in four digits (``out.png`` -> ``out0007.png``), a single
    frame's path is the template itself."""
    folder, name = os.path.split(template)
    runs = list(re.finditer(r"#+", name))
    if runs:
        run = runs[-1]
        digits = f"{frame:0{len(run.group())}d}" if frame >= 0 else \
            f"-{-frame:0{len(run.group()) - 1}d}"
        return os.path.join(folder, name[:run.start()] + digits + name[run.end():])
    if not animation:
        return template
    stem, extension = os.path.splitext(name)
    return os.path.join(folder, f"{stem}{frame:04d}{extension}")


def animation_frames(scene, args) -> list[int]:
    """The frames --frames asks for: its START-END, or the scene's range and step."""
    if args.frame_range is not None:
        start, end = args.frame_range
        return list(range(start, end + 1))
    return list(range(scene.frame_start, scene.frame_end + 1, scene.frame_step))


class FrameClaim:
    """Blender's Output > Overwrite and Placeholders, as several processes or machines sharing
    one output folder use them to split an animation:

    * overwrite off: a frame whose file exists is skipped;
    * placeholders on: a frame is claimed by creating its empty file before it is rendered.
      The claim is atomic (``O_CREAT | O_EXCL``), so of two processes reaching a free frame at
      once exactly one renders it; the other skips it when overwrite is off (with overwrite
      on, as in Blender, everyone renders every frame).

    ``release`` removes this process's placeholder if the frame was not written (a failure or
    a cancel), so another run picks the frame up, as Blender does on a cancelled render."""

    def __init__(self, path: str, overwrite: bool, placeholder: bool):
        self.path, self.placeholder_created = path, False
        self.claimed = self._claim(overwrite, placeholder)

    def _claim(self, overwrite: bool, placeholder: bool) -> bool:
        target = os.path.realpath(self.path)
        if not overwrite and os.path.exists(target):
            return False
        if not placeholder:
            return True
        try:
            descriptor = os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            return overwrite
        except OSError as error:
            raise RenderScriptError(f"cannot create placeholder {self.path}: "
                                    f"{error.strerror or error}") from None
        os.close(descriptor)
        self.placeholder_created = True
        return True

    def release(self) -> None:
        target = os.path.realpath(self.path)
        if self.placeholder_created and os.path.isfile(target) and \
                os.path.getsize(target) == 0:
            os.remove(target)


class ProgressLine:
    """``render.py: frame 12 (3/10)  45%  61/135 tiles  2.1 s elapsed  ~2.6 s left`` on
    stderr, rewritten in place (carriage return) at most every UPDATE_SECONDS and wiped when
    the frame ends; silent when the stream is not a terminal (logs, farms, pipes) or quiet.
    The time left assumes the tiles still to come cost what the finished ones did."""

    UPDATE_SECONDS = 0.1

    def __init__(self, stream, quiet: bool = False, label: str = ""):
        self.stream, self.label = stream, label
        self.enabled = not quiet and hasattr(stream, "isatty") and stream.isatty()
        self.start = time.perf_counter()
        self._last = -math.inf
        self._shown = False

    def text(self, done_tiles: int, total_tiles: int, fraction: float, elapsed: float) -> str:
        left = f"  ~{elapsed * (1 - fraction) / fraction:.1f} s left" if fraction > 0 else ""
        label = f" {self.label}" if self.label else ""
        return (f"{PROGRAM}:{label}  {100 * fraction:3.0f}%  {done_tiles}/{total_tiles} tiles  "
                f"{elapsed:.1f} s elapsed{left}")

    def __call__(self, job, fraction: float) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < self.UPDATE_SECONDS and fraction < 1:
            return
        self._last = now
        width, height = job.size
        size = job.settings.tile_size
        total = math.ceil(width / size) * math.ceil(height / size)
        line = self.text(round(fraction * total), total, fraction, now - self.start)
        self.stream.write(f"\r{line}\x1b[K")
        self.stream.flush()
        self._shown = True

    def end(self) -> None:
        if self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False


def output_format(scene, args) -> str:
    if args.format is not None:
        return args.format
    if args.output.lower().endswith(".png"):
        return "png"
    settings = scene.render.image_settings
    multilayer = getattr(settings, "media_type", None) == 'MULTI_LAYER_IMAGE' or \
        settings.file_format == 'OPEN_EXR_MULTILAYER'
    return "multilayer-exr" if multilayer else "exr"


def write_exr(scene, path: str, multilayer: bool) -> None:
    """Blender's render result as an OpenEXR file (scene-linear float, what Blender's own EXR
    output holds): single-layer RGBA of the Combined pass, or multilayer with every view layer
    and pass.  Written to a temporary file beside the target and renamed over it, so a failure
    leaves no partial file.  The .blend's EXR codec is kept."""
    import bpy

    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5.0
        settings.media_type = 'MULTI_LAYER_IMAGE' if multilayer else 'IMAGE'
    if not multilayer:
        settings.file_format = 'OPEN_EXR'
        settings.color_mode = 'RGBA'
    settings.color_depth = '32'
    target = os.path.realpath(path)
    folder, name = os.path.split(target)
    temporary = os.path.join(folder, f".{name}.{os.getpid()}.tmp.exr")
    try:
        bpy.data.images["Render Result"].save_render(filepath=temporary, scene=scene)
        os.replace(temporary, target)
    except (OSError, RuntimeError) as error:
        if os.path.exists(temporary):
            os.remove(temporary)
        reason = getattr(error, "strerror", None) or str(error).strip().splitlines()[-1]
        raise RenderScriptError(f"cannot write {path}: {reason}") from None


def render_frame(scene, args, interruption: Interruption, path: str, label: str = ""):
    """Render the scene's current frame and write it to ``path`` in the output format, with a
    progress line; (RenderJob, JobResult)."""
    fmt = output_format(scene, args)
    if fmt == "multilayer-exr":
        scene.render.use_single_layer = False  # every view layer goes into the file
    progress = ProgressLine(sys.stderr, quiet=args.quiet, label=label)
    try:
        job, result = render_scene(scene, interruption, progress=progress,
                                   fill_render_result=fmt != "png")
    finally:
        progress.end()
    if fmt == "png":
        write_output(path, result.image, should_cancel=interruption.requested, scene=scene,
                     job=job)
    else:
        write_exr(scene, path, multilayer=fmt == "multilayer-exr")
    return job, result


def render_animation(scene, args, interruption: Interruption) -> int:
    """--frames: every frame of the range not skipped by FrameClaim, each written to its
    frame_path; one line per frame on stdout and a summary."""
    frames = animation_frames(scene, args)
    overwrite = scene.render.use_overwrite if args.overwrite is None else args.overwrite
    placeholder = scene.render.use_placeholder if args.placeholder is None else args.placeholder
    start = time.perf_counter()
    rendered, skipped = [], []
    for index, frame in enumerate(frames, 1):
        interruption.check()
        path = frame_path(args.output, frame, animation=True)
        claim = FrameClaim(path, overwrite, placeholder)
        if not claim.claimed:
            skipped.append(frame)
            print(f"{PROGRAM}: skipped frame {frame}: {path} exists (overwrite is off)")
            continue
        began = time.perf_counter()
        try:
            scene.frame_set(frame)
            job, result = render_frame(scene, args, interruption, path,
                                       label=f"frame {frame} ({index}/{len(frames)})")
        except BaseException:
            claim.release()
            raise
        rendered.append(frame)
        width, height = job.size
        print(f"{PROGRAM}: wrote {path} (frame {frame}, {width}x{height}, {result.precision}) "
              f"in {time.perf_counter() - began:.2f} s", flush=True)
    print(f"{PROGRAM}: rendered {len(rendered)} of {len(frames)} frames, skipped "
          f"{len(skipped)}, in {time.perf_counter() - start:.2f} s")
    return 0


def main(argv: list[str] | None = None, own_process: bool = False) -> int:
    """own_process: run as the program; with pip bpy the process is then Glint's own and gets
    its malloc settings (``core.allocator``), never inside Blender's (``running_in_blender``),
    where they would change the allocator of Blender and every add-on."""
    argv = sys.argv if argv is None else argv
    args = parse_args(script_arguments(argv))
    interruption = Interruption()
    interruption.install()
    try:
        import bpy  # noqa: F401  (the pip module, or Blender's own)
    except ImportError:
        return _fail("needs Blender's Python or the bpy module (pip install bpy)")
    try:
        glint = import_glint()
        if own_process and not running_in_blender():
            from glint.core import allocator

            allocator.configure()
        if own_process and args.frames is None:
            # One frame, then exit: 'auto' weighs the workers' start-up (core.workers).
            from glint.core import workers

            workers.expect_one_render()
        if args.blend is not None:
            # Before the file loads, so that its render engine GLINT is known (Blender reports
            # "Engine 'GLINT' not available" otherwise); the article's scene is built after a
            # factory reset, which the registration must follow.
            register_glint(glint)
        scene = open_scene(args.blend)
        register_glint(glint)
        interruption.check()
        if scene is None:
            from glint.addon.utils.article_scene import build_article_scene

            scene = build_article_scene()
        apply_options(scene, args)
        interruption.check()
        start = time.perf_counter()
        if args.frames is not None:
            return render_animation(scene, args, interruption)
        job, result = render_frame(scene, args, interruption, frame_path(args.output,
                                                                         scene.frame_current))
    except Interrupted as interrupted:
        return _fail(str(interrupted), interrupted.exit_code)
    except RenderScriptError as error:
        return _fail(str(error))
    except Exception as error:
        if interruption.requested():  # e.g. the PNG writer stopped between row blocks
            return _fail(str(Interrupted(interruption.signal_number)),
                         EXIT_SIGNAL_BASE + interruption.signal_number)
        from glint.addon.engine.job import failure_message

        return _fail(failure_message(error))
    elapsed = time.perf_counter() - start
    width, height = job.size
    print(f"{PROGRAM}: wrote {frame_path(args.output, scene.frame_current)} "
          f"({width}x{height}, {result.precision}, "
          f"{job.settings.semantics} semantics) in {elapsed:.2f} s")
    return 0


def _fail(message: str, code: int = EXIT_FAILURE) -> int:
    print(f"{PROGRAM}: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main(own_process=True))
