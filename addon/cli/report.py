"""What render.py tells the user: one line per error (``fail``, ``RenderScriptError``) with
its exit status, and the progress line (``ProgressLine``)."""

from __future__ import annotations

import math
import sys
import time

PROGRAM = "render.py"

EXIT_USAGE = 2   # bad option (argparse's convention)
EXIT_FAILURE = 1  # the render could not be made


class RenderScriptError(Exception):
    """A problem reported to the user as one line, and the exit status it ends the program
    with."""

    def __init__(self, message: str, exit_code: int = EXIT_FAILURE):
        super().__init__(message)
        self.exit_code = exit_code


def fail(message: str, code: int = EXIT_FAILURE) -> int:
    print(f"{PROGRAM}: error: {message}", file=sys.stderr)
    return code


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
