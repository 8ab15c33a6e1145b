"""render.py's options, checked before Blender is loaded (this module imports no Blender
module): every mistake is one line and exit status 2, before anything is read or written."""

from __future__ import annotations

import argparse
import os
import re
import sys

from ...core import choices
from ...core.png import write_protected
from ...core.scene import MAX_DEPTH, MAX_SAMPLES
from .report import EXIT_USAGE, PROGRAM, fail

#: Blender's resolution_x/y hard limits (checked here, where Blender would silently clamp).
MIN_RESOLUTION, MAX_RESOLUTION = 4, 65536

OUTPUT_EXTENSIONS = (".png", ".exr")
#: --format: PNG (the core's 8-bit values), single-layer EXR (Combined, float) or multilayer
#: EXR (every view layer with its passes).
FORMATS = {"png": ".png", "exr": ".exr", "multilayer-exr": ".exr"}
_FRAME_RANGE = re.compile(r"^(-?\d+)(?:-(-?\d+))?$")

DESCRIPTION = "Render a .blend (or the article's scene) with Glint to an 8-bit RGBA PNG or " \
              "an OpenEXR."


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        raise SystemExit(fail(message, EXIT_USAGE))


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


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = _OneLineParser(prog=PROGRAM, description=DESCRIPTION)
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
    parser.add_argument("--semantics", choices=choices.SEMANTICS)
    parser.add_argument("--precision", choices=choices.PRECISIONS)
    parser.add_argument("--parallelism", choices=choices.PARALLELISM,
                        help=choices.help_text(choices.PARALLELISM_CHOICES) +
                             " (default: the scene's Glint > Performance > Parallelism)")
    add_animation_arguments(parser)
    args = parser.parse_args(argv)

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
