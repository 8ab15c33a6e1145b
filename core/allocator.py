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

``small_pages()`` is a narrower, temporary setting that is safe anywhere: while it is held,
NumPy does not ask the kernel for transparent huge pages for its large arrays (NumPy calls
``madvise(MADV_HUGEPAGE)`` on every array of 4 MiB or more; with the common
``defrag=madvise`` kernel setting each fault in such an array may then compact memory
synchronously).  A render holds it for all of its work (``core.render``; the worker
processes for good), the BVH build included, whose temporaries are a few hundred large
arrays made and dropped at once: the 10^6-point cloud's ``make_context`` took 1.3 s of user and
0.1-2.3 s of system time per call with huge pages (1.9 s on a process's first call even
with ``configure()``), 0.15 s of system time without.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import sys
import threading

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


def _huge_page_switch():
    """NumPy's ``_set_madvise_hugepage(enabled) -> previous`` (numpy 2.x: ``numpy._core``,
    1.x: ``numpy.core``), or None where this NumPy has none."""
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        switch = getattr(module, "_set_madvise_hugepage", None)
        if switch is not None:
            return switch
    return None


_switch = _huge_page_switch()
_small_pages_lock = threading.Lock()
_small_pages_holders = 0
_huge_pages_before = None


@contextlib.contextmanager
def small_pages():
    """NumPy allocates without asking for transparent huge pages while this is held (by any
    thread; the setting is NumPy's, process wide, and is restored when the last holder
    leaves).  Arrays keep whatever pages they got after it is released."""
    global _small_pages_holders, _huge_pages_before
    if _switch is None:
        yield
        return
    with _small_pages_lock:
        if _small_pages_holders == 0:
            _huge_pages_before = _switch(False)
        _small_pages_holders += 1
    try:
        yield
    finally:
        with _small_pages_lock:
            _small_pages_holders -= 1
            if _small_pages_holders == 0:
                _switch(_huge_pages_before)
