"""Helpers for tests that start, signal and watch child processes (Linux ``/proc``)."""

from __future__ import annotations

import signal
import time


def sigint_disposition(ignored: bool = False):
    """A ``preexec_fn`` that sets the child's SIGINT action explicitly: the default (Ctrl-C
    ends or cancels it) or, with ``ignored``, ignored, as a shell does for ``command &``.
    A child otherwise inherits this process's: the suite started with SIGINT ignored
    (``nohup``, ``trap '' INT``) would hand that on, and the child would rightly keep it."""
    action = signal.SIG_IGN if ignored else signal.SIG_DFL
    return lambda: signal.signal(signal.SIGINT, action)


def running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def all_ended(pids, seconds: float = 10.0) -> bool:
    """Wait up to ``seconds`` for every process of ``pids`` to end; whether they all did."""
    deadline = time.monotonic() + seconds
    while any(running(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return not any(running(pid) for pid in pids)
