"""Helpers for tests that watch child processes (Linux ``/proc``)."""

from __future__ import annotations

import time


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
