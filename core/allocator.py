"""glibc malloc settings for processes Glint owns, so that tile-sized temporaries stop faulting.

A tile's arrays are 128 KiB to a few MiB (a 128 x 128 tile's float64 (n,) array is 128 KiB,
exactly glibc's default ``M_MMAP_THRESHOLD``).  glibc serves such blocks with ``mmap`` and
returns them with ``munmap`` on free, so every temporary costs fresh zeroed pages from the
kernel: ~180 thousand minor page faults and ~0.3 s of system time per 1080p article frame.
Raising the mmap threshold keeps those blocks in malloc's heap, and raising the trim
threshold keeps the heap from being handed back to the kernel between tiles, so the same
pages are reused tile after tile.  The memory this holds is the render's own working set
(tens of MiB, bounded by the tile; ``core.render``), kept until the process exits.

``configure()`` applies both with ``mallopt`` through ctypes, on Linux with glibc only; on any
other platform or C library it does nothing and says so by returning False.  It is process
wide: it changes how malloc behaves for every library in the process.  So Glint applies it only
where it owns the process: ``python -m core``, ``render.py`` run as a program with pip ``bpy``,
the benchmark, and its render worker processes (``core.workers``).  It is NOT applied inside
Blender's own process, where it would change the allocator of Blender and of every other
add-on; a user who wants it there opts in by setting ``GLINT_MALLOC_TUNING=1`` in Blender's
environment (``configure_if_opted_in``).  Renders in worker processes get it either way.
"""

from __future__ import annotations

import ctypes
import os
import sys

#: glibc's mallopt parameters (malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: Blocks below this come from malloc's heap, not from mmap: 32 MiB, glibc's largest allowed
#: value on 64-bit (DEFAULT_MMAP_THRESHOLD_MAX); larger requests fail mallopt.  A tile's
#: largest temporaries (candidate pairs of a packet, 8-wide BVH fronts) stay well below it.
MMAP_THRESHOLD = 32 * 1024 * 1024
#: Free memory at the top of the heap is returned to the kernel only beyond this.
TRIM_THRESHOLD = 512 * 1024 * 1024
#: Environment variable by which a user opts in inside a process Glint does not own.
OPT_IN_VARIABLE = "GLINT_MALLOC_TUNING"

_applied: bool | None = None


def _glibc():
    """The process's C library through ctypes if it is glibc on Linux, else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        version = libc.gnu_get_libc_version   # glibc only (not musl, not bionic)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return None
    version.restype = ctypes.c_char_p
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return libc


def configure() -> bool:
    """Raise glibc's mmap and trim thresholds for this process (once; later calls return the
    first answer).  True when both settings were applied, False where nothing was done (not
    Linux with glibc, or mallopt refused)."""
    global _applied
    if _applied is None:
        libc = _glibc()
        _applied = bool(libc is not None
                        and libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
                        and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1)
    return _applied


def opted_in(environ=None) -> bool:
    """Whether the user asked for the malloc settings in a process Glint does not own."""
    value = (os.environ if environ is None else environ).get(OPT_IN_VARIABLE, "")
    return value.strip().lower() in ("1", "true", "yes", "on")


def configure_if_opted_in() -> bool:
    """``configure()`` only if ``GLINT_MALLOC_TUNING`` asks for it (inside Blender)."""
    return configure() if opted_in() else False
