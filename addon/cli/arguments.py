"""render.py's options, checked before Blender is loaded (this module imports no Blender
module): every mistake is one line and exit status 2, before anything is read or written."""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import sys

from ...core import choices
from ...core.png import write_protected
from ...core.validation import MAX_DEPTH, MAX_SAMPLES
from .report import EXIT_USAGE, PROGRAM, fail

#: Blender's hard limits, checked here (Blender would silently clamp a value outside them):
#: resolution_x/y, resolution_percentage, and the frame numbers (MINAFRAME, MAXFRAME).
MIN_RESOLUTION, MAX_RESOLUTION = 4, 65536
MAX_PERCENTAGE = 10000
MIN_FRAME, MAX_FRAME = -1048574, 1048574

OUTPUT_EXTENSIONS = (".png", ".exr")
#: --format: PNG (the core's 8-bit values), single-layer EXR (Combined, float) or multilayer
#: EXR (every view layer with its passes).
FORMATS = {"png": ".png", "exr": ".exr", "multilayer-exr": ".exr"}
_FRAME_RANGE = re.compile(r"^(-?\d+)(?:-(-?\d+))?$")

#: Without --output a frame goes where the .blend says; the article's scene has no .blend.
NO_OUTPUT_PATH = "--output is needed for the article's scene (no .blend given), which has no " \
                 "output path of its own"

DESCRIPTION = "Render a .blend (or the article's scene) with Glint to an 8-bit RGBA PNG or " \
              "an OpenEXR, or to the .blend's own output path and format."


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        raise SystemExit(fail(message, EXIT_USAGE))


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _between(minimum: int, maximum: int):
    """A whole number from minimum to maximum (Blender would silently clamp one outside)."""
    def parse(text: str) -> int:
        value = _integer(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum}, got {value}")
        return value
    return parse


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = _OneLineParser(prog=PROGRAM, description=DESCRIPTION)
    parser.add_argument("blend", nargs="?", help="scene .blend (default: the article's scene, "
                                                 "or the .blend Blender opened)")
    parser.add_argument("--output",
                        help="PNG or EXR file to write; #### is replaced by the frame number, "
                             "zero-padded to the number of # (default: the .blend's own output "
                             "path, format and frame numbering, as 'blender -b FILE -f N' "
                             "writes them)")
    parser.add_argument("--width", type=_between(MIN_RESOLUTION, MAX_RESOLUTION),
                        help="resolution X in pixels")
    parser.add_argument("--height", type=_between(MIN_RESOLUTION, MAX_RESOLUTION),
                        help="resolution Y in pixels")
    parser.add_argument("--percentage", type=_between(1, MAX_PERCENTAGE),
                        help="resolution percentage")
    parser.add_argument("--samples", type=_between(1, MAX_SAMPLES),
                        help="rays per anti-aliased pixel; turns Fixed anti-aliasing on if the "
                             "scene has it off")
    parser.add_argument("--max-depth", type=_between(1, MAX_DEPTH), help="bounces per path")
    parser.add_argument("--frame", type=_integer, help="frame to render")
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

    check_animation_arguments(parser, args)
    if args.output is not None:
        args.output = checked_output(parser, args.output)
    elif args.blend is None and not running_in_blender():
        parser.error(NO_OUTPUT_PATH)
    if args.blend is not None:
        args.blend = os.path.abspath(args.blend)
        if not os.path.isfile(args.blend):
            parser.error(f"no such .blend file: {args.blend}")
    return args


def checked_output(parser, output: str) -> str:
    """--output as an absolute path, refused in one line unless a PNG or EXR file can be
    written there (the folder exists and is writable, the file is not write-protected)."""
    if not output.lower().endswith(OUTPUT_EXTENSIONS):
        parser.error(f"--output must name a .png or .exr file, got {output!r}")
    path = os.path.abspath(output)
    folder = os.path.dirname(path)
    if os.path.isdir(path):
        parser.error(f"--output {output!r} is a directory")
    if not os.path.isdir(folder):
        parser.error(f"--output folder does not exist: {folder}")
    target = os.path.realpath(path)  # a symlink is written through
    if not os.path.isdir(os.path.dirname(target)):
        parser.error(f"--output {output!r} links into a folder that does not exist: "
                     f"{os.path.dirname(target)}")
    if not os.access(os.path.dirname(target), os.W_OK):
        parser.error(f"--output folder is not writable: {os.path.dirname(target)}")
    if write_protected(target):
        parser.error(f"--output {output!r} is write-protected: make it writable or "
                     f"choose another file")
    return path


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
    """--frame, --frames (START-END or N: ``args.frame_range``, None for the scene's range)
    and --format, each refused in one line if it cannot be rendered as asked: every frame
    within Blender's frame range (``frame_set`` would clamp one outside it)."""
    args.frame_range = None
    if args.frames is not None and args.frame is not None:
        parser.error("--frame and --frames exclude each other")
    if args.frame is not None and not MIN_FRAME <= args.frame <= MAX_FRAME:
        parser.error(f"--frame {args.frame} is outside Blender's frame range {MIN_FRAME} to "
                     f"{MAX_FRAME}")
    if args.frames not in (None, "scene"):
        match = _FRAME_RANGE.match(args.frames)
        if match is None:
            parser.error(f"--frames must be START-END or N, got {args.frames!r}")
        start = int(match.group(1))
        end = int(match.group(2)) if match.group(2) is not None else start
        for frame in (start, end):
            if not MIN_FRAME <= frame <= MAX_FRAME:
                parser.error(f"--frames {args.frames}: frame {frame} is outside Blender's "
                             f"frame range {MIN_FRAME} to {MAX_FRAME}")
        if end < start:
            parser.error(f"--frames {args.frames}: the end frame comes before the start")
        args.frame_range = (start, end)
    if args.format is not None:
        if args.output is None:
            parser.error(f"--format {args.format} needs --output (without it, the .blend's "
                         f"own output format is written)")
        if not args.output.lower().endswith(FORMATS[args.format]):
            parser.error(f"--format {args.format} writes {FORMATS[args.format]} files, but "
                         f"--output is {args.output!r}")


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
