"""Tiles rendered in worker processes, so that both cores work past the GIL.

A thread pool gains little (the render holds the GIL in about half of its ~750 NumPy calls a
tile), so large renders run their tiles in ``count`` worker processes instead:

* started as ``python -P core/_worker_boot.py FD`` with ``subprocess`` and one socket pair
  (multiprocessing's Connection over it), never a plain fork: forking Blender (or any
  process with threads, GPU drivers and open files) is unsafe.  multiprocessing's 'spawn'
  and 'forkserver' are not used either: both re-run the parent's ``__main__`` in every worker,
  so a user's script without an ``if __name__ == "__main__"`` guard would render itself again
  in each worker, and ``blender --python render.py`` would re-run render.py there.  The
  executable is ``sys.executable``, a Python in every place Glint runs (the venv's Python with
  pip ``bpy``; Blender's bundled Python inside Blender, which sets ``sys.executable`` to it,
  not to the Blender binary).  Where it is not a Python, on Windows (no descriptor passing),
  or where a worker cannot start, the render falls back to threads (``ProcessesUnavailable``),
  and the reason is kept in ``unavailable_reason`` so later renders do not try again.
* each worker takes the parent's ``sys.path``, imports ``core`` under the parent's own package
  name (``core._worker_boot``) and applies Glint's malloc settings (``core.allocator``: the
  process is Glint's own, even inside Blender).  Workers stay alive between renders (an
  animation, the benchmark's repeats, F12 after F12 pay their start-up, a Python and NumPy
  import, once); ``shutdown()`` ends them, as does the parent's exit.  Each render sends
  every worker it uses the prepared ``TraceContext`` and camera once (pickled: a few kB for
  the article's scene, the arrays themselves for big ones), dropped when the render ends.
* the parent sends tile rectangles, at most two in flight per worker; a worker renders a
  tile with the same ``core.render.render_tile`` as a thread would and writes its pixels into
  one shared-memory image (``multiprocessing.shared_memory``, kept for the next render of
  the same or smaller size up to ``KEEP_SHARED_BYTES``, so its pages fault once), then
  answers with the tile's RayStats and whether its values are all finite.  The parent
  finishes every tile itself (a tile with NaN is the same RenderError as with threads; copy
  into the result, on_tile, progress), in the order they land, exactly as the thread pool
  does: the image does not depend on the number of workers or on how they are run.
* the parent polls ``should_cancel`` at least every ``CANCEL_POLL_SECONDS``; a cancel (or any
  exception in the parent, KeyboardInterrupt included) sets a shared stop byte that running
  tiles check at every bundle of rays (the first byte of the shared memory), and the
  workers are then stopped.
* an exception in a worker is sent back pickled and raised in the parent as the same type
  with the same message (the worker's traceback text is attached as a note); a worker that
  dies is a RenderError naming its exit code.  Workers ignore SIGINT (the terminal sends
  Ctrl-C to the whole process group; the parent decides) and end when the parent's pipe
  closes, so they never outlive it.
"""

from __future__ import annotations

import atexit
import os
import pickle
import socket
import subprocess
import sys
import threading
import time
import traceback
from multiprocessing import resource_tracker, shared_memory
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_for

import numpy as np

#: How often the parent polls should_cancel while workers run (seconds).
CANCEL_POLL_SECONDS = 0.1
#: A worker must be ready (imported, context loaded) within this, else processes are
#: declared unavailable and the render falls back to threads.
START_TIMEOUT_SECONDS = 60.0
#: How long a worker may take to acknowledge the end of a render (its running tile stops at
#: its next bundle of rays) before it is killed and replaced.
END_TIMEOUT_SECONDS = 5.0
#: Tiles in flight per worker: one rendering, one queued, so no worker waits for the parent.
TILES_IN_FLIGHT = 2
#: Renders below this many pixels stay in the calling process: starting a worker (a Python
#: and NumPy import, 0.1-0.3 s, once per process) costs more than a small render gains.
MIN_PIXELS = 300_000
#: The shared image is kept between renders up to this size (a 1920 x 1080 float64 image is
#: 63 MiB); larger ones are freed when their render ends.
KEEP_SHARED_BYTES = 256 * 2 ** 20
#: The shared memory holds the stop byte at 0 and the image from this offset (aligned).
IMAGE_OFFSET = 64

#: Resident memory of a worker besides its tracing (Python, NumPy, core, its kept heap):
#: measured 62-64 MB after an 800 x 400 render, which includes its share of the tracing
#: memory that ``core.memory`` already counts; rounded up.
WORKER_PROCESS_BYTES = 80 * 2 ** 20

_BOOT_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_worker_boot.py")
_CORE_PACKAGE = __name__.rpartition(".")[0]
_CORE_FOLDER = os.path.dirname(os.path.abspath(__file__))

#: Why worker processes could not be used in this process (None: not known to fail).
unavailable_reason: str | None = None


class ProcessesUnavailable(Exception):
    """Worker processes cannot be used for this render; the caller renders on threads."""


class _StopFlag:
    """threading.Event's ``is_set`` over one byte of shared memory (what render_tile polls)."""

    def __init__(self, buffer):
        self._buffer = buffer

    def is_set(self) -> bool:
        return self._buffer[0] != 0


def _python_executable() -> str | None:
    """The Python that workers run: sys.executable if it is a Python program, else None."""
    executable = sys.executable
    if not executable or not os.path.isfile(executable):
        return None
    if not os.path.basename(executable).lower().startswith("python"):
        return None   # e.g. an embedding program that left sys.executable as itself
    return executable


# ------------------------------------------------------------------------------------------
# The worker side

class _Job:
    """One render as a worker sees it: its context, camera and the shared image."""

    def __init__(self, memory, shape, dtype_name: str, payload: bytes):
        self.image = np.ndarray(tuple(shape), np.dtype(dtype_name), buffer=memory.buf,
                                offset=IMAGE_OFFSET)
        self.stop = _StopFlag(memory.buf[:1])
        self.ctx, self.camera = pickle.loads(payload)

    def close(self) -> None:
        self.image = self.stop = self.ctx = self.camera = None


def worker_loop(connection, setup: dict) -> None:
    """Run in a worker: serve renders until the parent sends None or goes away.

    Messages in: ('render', shared name, shape, dtype) followed by the pickled (context,
    camera) as bytes; a tile (y0, y1, x0, x1); ('end',); None.  Answers: ('ready',),
    ('done', tile, stats, whether every value is finite), ('cancelled', tile),
    ('error', tile, exception, traceback text), ('ended',)."""
    from . import allocator
    from .render import RenderCancelled, render_tile

    allocator.configure()
    job = memory = None
    try:
        while True:
            try:
                message = connection.recv()
            except (EOFError, OSError):
                return                      # the parent is gone
            if message is None:
                return
            if message[0] == "render":
                payload = connection.recv_bytes()
                try:
                    if job is not None:       # a render whose end never came
                        job.close()
                        job = None
                    if memory is None or memory.name != message[1]:
                        if memory is not None:
                            memory.close()
                        memory = None
                        memory = _attach(message[1])
                    job = _Job(memory, *message[2:], payload)
                except Exception as error:
                    _send_error(connection, None, error)
                    continue
                connection.send(("ready",))
            elif message[0] == "end":
                if job is not None:
                    job.close()
                    job = None
                connection.send(("ended",))
            elif job is None or job.stop.is_set():
                connection.send(("cancelled", message))
            else:
                tile = message
                try:
                    rgba, stats = render_tile(job.ctx, job.camera, tile, job.stop)
                    y0, y1, x0, x1 = tile
                    job.image[y0:y1, x0:x1] = rgba
                    connection.send(("done", tile, stats, bool(np.isfinite(rgba).all())))
                except RenderCancelled:
                    connection.send(("cancelled", tile))
                except Exception as error:
                    _send_error(connection, tile, error)
    finally:
        if job is not None:
            job.close()
        if memory is not None:
            memory.close()


def _attach(name: str):
    """The parent's shared memory, not registered with a resource tracker: Python < 3.13
    registers every attached segment, which would start a tracker process in each worker and
    unlink the parent's image when the worker exits.  Only the parent owns it."""
    register = resource_tracker.register
    resource_tracker.register = lambda *args: None
    try:
        return shared_memory.SharedMemory(name=name)
    finally:
        resource_tracker.register = register


def _send_error(connection, tile, error: BaseException) -> None:
    text = "".join(traceback.format_exception(type(error), error, error.__traceback__))
    try:
        pickle.loads(pickle.dumps(error))      # survives the trip as itself?
        payload = error
    except Exception:
        payload = RuntimeError(f"{type(error).__name__}: {error}")
    try:
        connection.send(("error", tile, payload, text))
    except (OSError, ValueError):
        pass


# ------------------------------------------------------------------------------------------
# The parent side

class _Worker:
    def __init__(self, process, connection):
        self.process = process
        self.connection = connection
        self.in_flight: list = []

    def end(self) -> None:
        """Stop the worker for good: ask, then kill if it does not go."""
        try:
            self.connection.send(None)
        except (OSError, ValueError):
            pass
        try:
            self.process.wait(1.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.connection.close()


class _Pool:
    """The live worker processes of this process, reused from render to render."""

    def __init__(self):
        self.lock = threading.Lock()      # one render at a time uses the workers
        self.workers: list[_Worker] = []
        self.owner = os.getpid()
        self.memory = None                # the shared image, kept between renders

    def shared_memory(self, size: int):
        """Shared memory of at least ``size`` bytes: the kept one if it is large enough."""
        if self.memory is not None and self.memory.size < size:
            self.free_memory()
        if self.memory is None:
            self.memory = shared_memory.SharedMemory(create=True, size=size)
        return self.memory

    def free_memory(self) -> None:
        if self.memory is not None:
            self.memory.close()
            self.memory.unlink()
            self.memory = None

    def grow(self, count: int) -> None:
        """Start workers until there are ``count`` (raises ProcessesUnavailable)."""
        global unavailable_reason
        if self.owner != os.getpid():     # a fork of the process that started them
            self.workers, self.memory, self.owner = [], None, os.getpid()
        executable = _python_executable()
        if executable is None:
            unavailable_reason = f"sys.executable ({sys.executable!r}) is not a Python"
        elif os.name != "posix":
            unavailable_reason = "worker processes need POSIX descriptor passing"
        if unavailable_reason is not None:
            raise ProcessesUnavailable(unavailable_reason)
        setup = {"sys_path": list(sys.path), "core_name": _CORE_PACKAGE,
                 "core_folder": _CORE_FOLDER}
        flags = ["-P"] if sys.version_info >= (3, 11) else []   # not core/ on sys.path
        while len(self.workers) < count:
            mine, theirs = socket.socketpair()
            try:
                process = subprocess.Popen(
                    [executable, *flags, _BOOT_FILE, str(theirs.fileno())],
                    pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL)
            except OSError as error:
                mine.close()
                unavailable_reason = f"cannot start a worker process: {error}"
                raise ProcessesUnavailable(unavailable_reason) from error
            finally:
                theirs.close()
            worker = _Worker(process, Connection(mine.detach()))
            self.workers.append(worker)
            try:
                worker.connection.send(setup)
            except OSError:
                self._failed_to_start(worker)

    def _failed_to_start(self, worker: _Worker):
        """A worker that went away before it was ready: processes do not work here."""
        global unavailable_reason
        self.drop(worker)
        unavailable_reason = (f"a worker process exited while starting (exit code "
                              f"{worker.process.returncode})")
        raise ProcessesUnavailable(unavailable_reason) from None

    def drop(self, worker: _Worker) -> None:
        if worker in self.workers:
            self.workers.remove(worker)
            worker.end()

    def drop_all(self) -> None:
        for worker in list(self.workers):
            self.drop(worker)

    def shutdown(self) -> None:
        if self.owner != os.getpid():     # a fork: the workers are its parent's, not ours
            self.workers, self.memory = [], None
            return
        with self.lock:
            self.drop_all()
            self.free_memory()


_pool = _Pool()
atexit.register(_pool.shutdown)


def worker_pids() -> list[int]:
    """Process ids of the live workers (for measurements: the benchmark's CPU time)."""
    return [worker.process.pid for worker in _pool.workers]


def shutdown() -> None:
    """End the worker processes (the next render with processes starts new ones)."""
    _pool.shutdown()


class _Render:
    """One render on ``count`` of the pool's workers, into a shared-memory image."""

    def __init__(self, ctx, camera, shape, count: int):
        self.dtype = np.dtype(ctx.dtype)
        self.shape = tuple(shape)
        image_bytes = int(np.prod(self.shape)) * self.dtype.itemsize
        self.memory = _pool.shared_memory(IMAGE_OFFSET + image_bytes)
        self.image = np.ndarray(self.shape, self.dtype, buffer=self.memory.buf,
                                offset=IMAGE_OFFSET)
        self.stop = self.memory.buf[:1]
        self.stop[0] = 0
        self.payload = pickle.dumps((ctx, camera), protocol=5)
        self.workers = _pool.workers[:count]

    def start(self, should_cancel) -> None:
        """Hand every worker this render and wait until all are ready."""
        global unavailable_reason
        from .render import RenderCancelled

        header = ("render", self.memory.name, self.shape, self.dtype.name)
        for worker in list(self.workers):
            try:
                worker.connection.send(header)
                worker.connection.send_bytes(self.payload)
            except OSError:
                self.workers.remove(worker)
                _pool._failed_to_start(worker)
        deadline = time.monotonic() + START_TIMEOUT_SECONDS
        waiting = {w.connection: w for w in self.workers}
        while waiting:
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")
            if time.monotonic() > deadline:
                unavailable_reason = (f"worker processes did not start within "
                                      f"{START_TIMEOUT_SECONDS:g} s")
                raise ProcessesUnavailable(unavailable_reason)
            for connection in wait_for(list(waiting), timeout=CANCEL_POLL_SECONDS):
                worker = waiting.pop(connection)
                try:
                    message = connection.recv()
                except (EOFError, OSError):
                    self.workers.remove(worker)
                    _pool._failed_to_start(worker)
                if message[0] == "error":
                    _raise_worker_error(message)

    def run(self, tiles, finish, should_cancel) -> None:
        """Render ``tiles``; finish(tile, rgba, stats, done, finite) is called in this
        process for each as it lands, rgba a view of the shared image, finite whether all
        its values are finite (checked by the worker)."""
        from .render import RenderCancelled, RenderError

        queue = iter(tiles)
        done = 0
        by_connection = {w.connection: w for w in self.workers}
        for worker in self.workers:
            self._feed(worker, queue)
        while any(w.in_flight for w in self.workers):
            ready = wait_for([w.connection for w in self.workers if w.in_flight],
                             timeout=CANCEL_POLL_SECONDS)
            for connection in ready:
                worker = by_connection[connection]
                try:
                    message = connection.recv()
                except (EOFError, OSError):
                    _pool.drop(worker)
                    self.workers.remove(worker)
                    raise RenderError(f"a render worker process died (exit code "
                                      f"{worker.process.returncode})") from None
                kind, tile = message[0], message[1]
                worker.in_flight.remove(tile)
                if kind == "error":
                    _raise_worker_error(message)
                if kind == "cancelled":
                    raise RenderCancelled("render cancelled")
                done += 1
                y0, y1, x0, x1 = tile
                finish(tile, self.image[y0:y1, x0:x1], message[2], done, message[3])
                self._feed(worker, queue)
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")

    @staticmethod
    def _feed(worker: _Worker, queue) -> None:
        while len(worker.in_flight) < TILES_IN_FLIGHT:
            tile = next(queue, None)
            if tile is None:
                return
            worker.connection.send(tile)
            worker.in_flight.append(tile)

    def end(self) -> None:
        """Stop running tiles at their next bundle, let every worker drop this render (a
        worker that does not answer is replaced next time), free the image."""
        self.stop[0] = 1
        self.workers = [w for w in self.workers if w in _pool.workers]   # not dropped
        for worker in list(self.workers):
            try:
                worker.connection.send(("end",))
            except (OSError, ValueError):
                _pool.drop(worker)
                self.workers.remove(worker)
        deadline = time.monotonic() + END_TIMEOUT_SECONDS
        for worker in self.workers:
            if not _wait_for_end(worker, deadline):
                _pool.drop(worker)
            worker.in_flight.clear()
        self.image = None
        self.stop.release()
        self.stop = None
        if self.memory.size > KEEP_SHARED_BYTES:
            _pool.free_memory()


def _wait_for_end(worker: _Worker, deadline: float) -> bool:
    """Read a worker's answers until it acknowledges the end of the render."""
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not worker.connection.poll(remaining):
            return False
        try:
            if worker.connection.recv()[0] == "ended":
                return True
        except (EOFError, OSError):
            return False


def _raise_worker_error(message):
    _, _, error, text = message
    if isinstance(error, BaseException):
        if hasattr(error, "add_note"):
            error.add_note("in a render worker process:\n" + text.rstrip())
        raise error
    raise RuntimeError(str(error))


def prestart(count: int) -> None:
    """Start ``count`` workers now without waiting for them, so that their start-up (a Python
    and NumPy import) overlaps the caller's preparation (the render's context, a BVH); a
    failure is left for ``render_tiles`` to find."""
    if unavailable_reason is not None or not _pool.lock.acquire(blocking=False):
        return
    try:
        _pool.grow(count)
    except ProcessesUnavailable:
        _pool.drop_all()
    finally:
        _pool.lock.release()


def planned_bytes(shape, dtype, count: int, scene_bytes: int) -> int:
    """What rendering in ``count`` workers holds beyond a threaded render (``core.memory``):
    the shared image of ``shape`` in the render's ``dtype``, and per worker its interpreter
    and its own copy of the scene; the tracing memory only moves into the workers."""
    image = IMAGE_OFFSET + int(np.prod(shape)) * np.dtype(dtype).itemsize
    return image + count * (WORKER_PROCESS_BYTES + scene_bytes)


def render_tiles(ctx, camera, tiles, shape, count: int, finish, should_cancel=None) -> None:
    """Render ``tiles`` of an image of ``shape`` (H, W, 4) on ``count`` worker processes.
    Raises ProcessesUnavailable, before any tile is finished, where they cannot be used
    (cannot start here, or another render is using them)."""
    if not _pool.lock.acquire(blocking=False):
        raise ProcessesUnavailable("another render is using the worker processes")
    try:
        try:
            _pool.grow(count)
        except ProcessesUnavailable:
            _pool.drop_all()
            raise
        render = _Render(ctx, camera, shape, count)
        try:
            render.start(should_cancel)
            render.run(tiles, finish, should_cancel)
        except ProcessesUnavailable:
            _pool.drop_all()    # the others started the same way: none is trusted
            raise
        finally:
            render.end()
    finally:
        _pool.lock.release()
