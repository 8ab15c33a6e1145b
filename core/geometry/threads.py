"""Thread pools for the geometry's builds (the tree's, the bins'): NumPy releases the GIL in
most whole-array operations, so parts of a build run side by side."""

from __future__ import annotations

import threading
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager


@contextmanager
def thread_pool(threads: int):
    """A pool of ``threads`` threads for the duration of a build, or None for one thread."""
    if threads <= 1:
        yield None
        return
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="glint-build") as pool:
        yield pool


def run_on(pool, function, *args) -> Future:
    """function(*args) on ``pool``, or now where there is none: its Future."""
    if pool is not None:
        return pool.submit(function, *args)
    done = Future()
    done.set_result(function(*args))
    return done


def map_on(pool, function, items) -> list:
    """[function(item) for item in items], on ``pool`` where there is one (in order)."""
    if pool is None:
        return [function(item) for item in items]
    return list(pool.map(function, items))


class PicklesWithoutLock:
    """A holder of a ``_lock`` (threading.Lock, which cannot be pickled) that pickles for
    worker processes without it and gets a new one when unpickled."""

    def __getstate__(self):
        state = dict(self.__dict__)
        del state["_lock"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()
