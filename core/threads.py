"""Tiles rendered in this process: on the calling thread alone, or on a thread pool.

The thread scheduler, with the shape of the worker processes' (``core.workers``) and the
cluster's (``core.cluster``): ``render_tiles(ctx, camera, tiles, shape, dtype, count, finish,
should_cancel)`` renders every tile with ``core.tiles.render_tile`` into an image and hands
each to ``finish`` on the calling thread as it lands.  A pool keeps a few tiles in flight,
so that a cancel is honoured promptly.  (The geometry's builds have pools of their own:
``core.geometry.threads``.)
"""

from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

import numpy as np

from .failures import CANCEL_POLL_SECONDS, RenderCancelled
from .tiles import render_tile



class _Asked:
    """A tile's ``stop`` on the render's own thread: ``is_set`` asks ``should_cancel``, as a
    threading.Event set by the thread loop would answer."""

    def __init__(self, should_cancel):
        self.should_cancel = should_cancel

    def is_set(self) -> bool:
        return self.should_cancel is not None and bool(self.should_cancel())


def render_tiles(ctx, camera, tiles, shape, dtype, count: int, finish, should_cancel=None,
                 beside=None) -> np.ndarray | None:
    """The (H, W, C) image of ``shape`` and ``dtype`` with ``tiles`` rendered into it on
    ``count`` threads; finish(tile, pixels, stats, done, finite) is called on this thread as
    each tile lands, as ``core.workers.render_tiles`` calls it: pixels the tile's view of
    the image, finite whether the values it was made from are all finite (a tile that is
    not is left out of the image).  shape None: no image, pixels the tile's own values
    (for a caller that adds them into its own totals, where an image would be one more
    frame of memory).  tiles: a list, or a deque-like queue that ``finish`` may extend (a
    progressive frame's ``WorkQueue``).  beside(tile, stats): more of a tile's work, done
    on the thread that rendered it before it lands (a frame's passes).  Raises
    RenderCancelled when ``should_cancel()`` answers True."""
    image = None if shape is None else np.zeros(shape, dtype)
    pending = tiles if hasattr(tiles, "popleft") else deque(tiles)
    done = 0

    def next_tile():
        return pending.popleft() if pending else None

    def run(tile, stop):
        rgba, stats = render_tile(ctx, camera, tile, stop)
        if beside is not None:
            beside(tile, stats)
        return rgba, stats

    def land(tile, result):
        nonlocal done
        rgba, stats = result
        y0, y1, x0, x1 = tile[:4]
        finite = bool(np.isfinite(rgba).all())
        done += 1
        if image is None:
            finish(tile, rgba, stats, done, finite)
            return
        if finite:
            image[y0:y1, x0:x1] = rgba
        finish(tile, image[y0:y1, x0:x1], stats, done, finite)

    _run_on_threads(next_tile, run, land, count, should_cancel)
    return image


def _run_on_threads(next_job, run, land, threads: int, should_cancel) -> None:
    """Run every job ``next_job()`` hands out (None: none now; landing one may make more)
    as ``run(job, stop)`` and give its result to ``land(job, result)`` on this thread as it
    finishes: on this thread alone for one thread, else on a pool of ``threads`` with a few
    jobs in flight, so that a cancel (``should_cancel()``) is honoured promptly.  ``stop``
    tells a running job to raise RenderCancelled at its next bundle of rays."""
    def cancelled():
        return should_cancel is not None and should_cancel()

    if threads == 1:
        asked = _Asked(should_cancel)   # (a deep tile polls it between bounces)
        while True:
            if cancelled():
                raise RenderCancelled("render cancelled")
            job = next_job()
            if job is None:
                return
            land(job, run(job, asked))
    stop = threading.Event()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        pending = {}
        try:
            while True:
                while len(pending) < 2 * threads:
                    job = next_job()
                    if job is None:
                        break
                    pending[pool.submit(run, job, stop)] = job
                if not pending:
                    return
                # Wake up regularly to poll should_cancel while long tiles run.
                finished, _ = wait(pending, timeout=CANCEL_POLL_SECONDS,
                                   return_when=FIRST_COMPLETED)
                for future in finished:
                    land(pending.pop(future), future.result())
                if cancelled():
                    raise RenderCancelled("render cancelled")
        except BaseException:
            # Cancelled, a tile failed, or an exception (KeyboardInterrupt) arrived: stop
            # the other tiles at their next bundle instead of finishing them.
            stop.set()
            for future in pending:
                future.cancel()
            raise
