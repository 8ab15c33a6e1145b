"""Ctrl-C (SIGINT) and SIGTERM during render.py: they cancel the render within about a tile's
time instead of raising inside Blender's or NumPy's code, and the program exits 128 + the
signal's number (130, 143) with one line."""

from __future__ import annotations

import signal

from .report import RenderScriptError

#: Exit status after a signal cancelled the run: the shell's convention, 128 + its number.
EXIT_SIGNAL_BASE = 128


class Interruption:
    """SIGINT and SIGTERM, caught so that they cancel the render: the handler only records the
    signal; the engine polls ``requested`` between tiles (through its FrameRequest), and
    ``run`` between steps.  A second signal gets the default action (ends the process at
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


class Interrupted(RenderScriptError):
    """The run was cancelled by a signal; ``outcome`` says what was written (a frame: nothing;
    an animation: the frames finished before it)."""

    def __init__(self, signal_number: int, outcome: str = "nothing written"):
        name = signal.Signals(signal_number).name
        how = " (Ctrl-C)" if signal_number == signal.SIGINT else ""
        super().__init__(f"cancelled by {name}{how}; {outcome}",
                         EXIT_SIGNAL_BASE + signal_number)
        self.signal_number = signal_number
