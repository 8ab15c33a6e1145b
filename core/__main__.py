"""``python -m core --scene article --width W --height H --output FILE`` (.png or .npy).

Every failure is one line on stderr and a non-zero exit (2 for bad input, 1 for anything
else); the output is written atomically (``core.png.atomic_file``), so the previous file
survives any failure.  Ctrl-C or SIGTERM stop the render between tiles, write nothing and exit
130 or 143 (128 + the signal's number).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time

import numpy as np

from . import allocator, workers
from .article import article_scene, article_settings
from .choices import (ANTI_ALIASING, PARALLELISM, PARALLELISM_CHOICES, PRECISIONS,
                      SEMANTICS, help_text)
from .png import atomic_file, write_png
from .render import render
from .settings import RenderSettings
from .validation import SceneError

SCENES = {"article": article_scene}


class _OneLineParser(argparse.ArgumentParser):
    """argparse's errors as one line (its default prints the usage first)."""

    def error(self, message):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def parse_args(argv):
    parser = _OneLineParser(prog="python -m core", description=__doc__)
    parser.add_argument("--scene", choices=sorted(SCENES), default="article")
    parser.add_argument("--width", type=int, default=300)
    parser.add_argument("--height", type=int, default=200)
    parser.add_argument("--output", required=True, help="FILE.png (8-bit RGBA) or FILE.npy")
    parser.add_argument("--semantics", choices=SEMANTICS, default="article")
    parser.add_argument("--precision", choices=PRECISIONS, default="float64")
    parser.add_argument("--max-depth", type=int, default=3)
    parser.add_argument("--anti-aliasing", choices=ANTI_ALIASING, default="off")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--threads", type=int, default=None,
                        help="tiles rendered at once (default: one per core)")
    parser.add_argument("--parallelism", choices=PARALLELISM,
                        default=RenderSettings.parallelism,
                        help=help_text(PARALLELISM_CHOICES))
    parser.add_argument("--no-malloc-tuning", action="store_true",
                        help="keep glibc's default malloc thresholds (core.allocator)")
    args = parser.parse_args(argv)
    if not args.output.endswith((".png", ".npy")):
        parser.error(f"--output must end in .png or .npy, got {args.output!r}")
    folder = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(folder):
        parser.error(f"--output folder does not exist: {folder}")
    return args


class Terminated(BaseException):
    """SIGTERM arrived (raised from its handler, like KeyboardInterrupt for SIGINT)."""


def _terminate(number, frame):
    raise Terminated()


def main(argv=None, own_process: bool = False) -> int:
    """own_process: run as the program (``python -m core``), so the process is Glint's and
    gets its malloc settings (``core.allocator``); not when called from other code."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if own_process and not args.no_malloc_tuning:
        allocator.configure()
    if own_process:  # one render, then exit: 'auto' weighs the workers' start-up
        workers.expect_one_render()
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_IGN:
        signal.signal(signal.SIGTERM, _terminate)
    try:
        scene = SCENES[args.scene](args.width, args.height)
        settings = article_settings(
            semantics=args.semantics, precision=args.precision, max_depth=args.max_depth,
            anti_aliasing=args.anti_aliasing, samples=args.samples, threads=args.threads,
            parallelism=args.parallelism)
        start = time.perf_counter()
        result = render(scene, settings)
        elapsed = time.perf_counter() - start
        if args.output.endswith(".npy"):
            with atomic_file(args.output) as stream:
                np.save(stream, result.image)  # streamed from the array, no copy
        else:
            write_png(args.output, result.display())
    except (SceneError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: cancelled by SIGINT (Ctrl-C); nothing written", file=sys.stderr)
        return 128 + signal.SIGINT
    except Terminated:
        print("error: cancelled by SIGTERM; nothing written", file=sys.stderr)
        return 128 + signal.SIGTERM
    except MemoryError:
        print("error: out of memory: lower --width, --height or --samples", file=sys.stderr)
        return 1
    except Exception as error:  # a bug: still one line, never a traceback
        detail = str(error).strip().splitlines()
        print(f"error: internal error ({type(error).__name__}"
              f"{': ' + detail[0] if detail else ''})", file=sys.stderr)
        return 1
    if result.fallback is not None:
        print(f"warning: {result.fallback}", file=sys.stderr)
    print(f"wrote {args.output} ({args.width}x{args.height}, {result.precision}, "
          f"{args.semantics} semantics) in {elapsed:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(own_process=True))
