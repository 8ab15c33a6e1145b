"""Tiles rendered in worker processes, so that both cores work past the GIL: the parent's
side, its pool of workers and a frame's run on them (``render_tiles``).  A worker's own side
is ``core.worker_process``; what they share without a copy, ``core.shared_memory``.

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
  every worker it uses the prepared ``TraceContext`` and camera once, dropped when the render
  ends: pickled (a few kB for the article's scene), except that arrays of SHARED_ARRAY_BYTES
  or more (a big scene's spheres, triangles and tree, and the tables the render built for
  the frame: ``Aggregate.build_frame_tables``) go out of band (pickle protocol 5)
  into one anonymous file that every worker maps copy-on-write (``core.shared_memory``), so a
  million-sphere scene is written once, not serialized into every worker's socket, and its
  pages exist once in memory however many workers read them.
* the parent sends tile rectangles, at most two in flight per worker; a worker renders a
  tile with the same ``core.tiles.render_tile`` as a thread would and writes its pixels
  straight into the render's image, then answers with the tile's RayStats and whether its
  values are all finite.  The image is a frame's memory (``_Frame``: a memfd, or an unlinked
  temporary file, mapped by the parent and every worker; its descriptor goes to each worker
  once over its socket), and the parent's mapping of it is the image the render returns, so
  no tile is copied: a copy into a fresh image was most of the parent's CPU (measured at
  1080p, float64: 0.034 of 0.059 s a frame, page faults included), which on two cores is
  taken from the workers.  Frames whose image the caller has dropped are used again (at
  most ``KEPT_FRAMES``, each up to ``KEEP_SHARED_BYTES``), so their pages are mapped
  everywhere already.  The parent lands every tile itself (a tile with NaN is the same
  RenderError as with threads; on_tile, progress), in the order they land, as the thread
  pool does: the image does not depend on the number of workers or on how they are run.
* while a worker is still starting (its first render), the parent renders tiles itself
  from the same queue, so a cold start does not idle the frame; if the workers then fail
  to start, the parent renders the rest and the render says so (``render_tiles``'s
  fallback).  A worker still starting when the frame is done answers that render later;
  its next render reads the answers first (``owes_end``).  Where a process renders only
  once, 'auto' avoids a cold start that would not pay (``one_render``).
* the parent polls ``should_cancel`` at least every ``CANCEL_POLL_SECONDS``; a cancel (or any
  exception in the parent, KeyboardInterrupt included) sets a stop byte that running tiles
  check at every bundle of rays (byte 0 of a control page every worker maps), and the
  workers are then stopped.
* an exception in a worker is sent back pickled and raised in the parent as the same type
  with the same message (the worker's traceback text is attached as a note); a worker that
  dies is a RenderError naming its exit code.  Workers ignore SIGINT (the terminal sends
  Ctrl-C to the whole process group; the parent decides) and end when the parent's pipe
  closes, so they never outlive it.
"""

from __future__ import annotations

import atexit
import itertools
import mmap
import os
import socket
import subprocess
import sys
import threading
import time
import weakref
from collections import deque
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_for
from multiprocessing.reduction import send_handle

import numpy as np

from .failures import CANCEL_POLL_SECONDS, RenderCancelled, RenderError
from .shared_memory import _SharedPayload, _anonymous_file, _frame_image, _map

#: A worker must be ready (imported, context loaded) within this, else processes are
#: declared unavailable and the render falls back to threads.
START_TIMEOUT_SECONDS = 60.0
#: How long a worker may take to acknowledge the end of a render (its running tile stops at
#: its next bundle of rays) before it is killed and replaced.
END_TIMEOUT_SECONDS = 5.0
#: Tiles in flight per worker: one rendering, one queued, so no worker waits for the parent.
TILES_IN_FLIGHT = 2
#: Renders of less work than this many of the article scene's camera samples (pixels x
#: samples per pixel x TREE_SAMPLE_WEIGHT for scenes with a tree) stay in the calling
#: process: starting a worker (a Python and NumPy import, 0.1-0.3 s, once per process) costs
#: more than a small render gains.
MIN_PIXELS = 300_000
#: A camera sample of a scene that needs a tree (``GeometryPolicy.builds_tree``) counts as this
#: many of the article scene's: at 640 x 360 (230,400 pixels, under MIN_PIXELS) 1,000 spheres
#: took 14x the article scene's time (2 threads, same run), a million point-cloud spheres and
#: 100,000 instanced ones about 100x and 70x, and there processes took 0.71x and 0.57x of
#: threads' wall time (5.2 vs 7.3 s, 2.9 vs 5.1 s, two free cores): two threads in one
#: process gain little over one (the GIL).
TREE_SAMPLE_WEIGHT = 10
#: Frame memory is kept for later renders up to this size each (a 1920 x 1080 float64 image
#: is 63 MiB); a larger frame's memory lives only as long as its image.
KEEP_SHARED_BYTES = 256 * 2 ** 20
#: Frames kept for later renders: two, so that a caller still holding the previous image
#: while the next renders (``result = render(...)`` in a loop) never makes a new one.
KEPT_FRAMES = 2

#: Resident memory of a worker besides its tracing (Python, NumPy, core, its kept heap):
#: measured 62-64 MB after an 800 x 400 render, which includes its share of the tracing
#: memory that ``core.memory`` already counts; rounded up.
WORKER_PROCESS_BYTES = 80 * 2 ** 20

_BOOT_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_worker_boot.py")
_CORE_PACKAGE = __name__.rpartition(".")[0]
_CORE_FOLDER = os.path.dirname(os.path.abspath(__file__))

#: Why worker processes could not be used in this process (None: not known to fail).
unavailable_reason: str | None = None
#: How many tiles the last render on workers rendered in this process while they started.
last_render_here = 0
#: Set by ``expect_one_render``: this process renders once and exits (``python -m core``,
#: render.py for one frame), so a cold start is paid for one render only.
one_render = False
#: With ``one_render`` and no warm workers, 'auto' takes processes only for renders of at
#: least this many camera samples (pixels x samples per pixel), where their start-up pays:
#: booting two workers costs about 0.6 s of CPU (measured at load 5-7), and two workers
#: save 0.1 s a Mpixel of the article's scene on 2 free cores (README).
COLD_MIN_SAMPLES = 8_000_000


def expect_one_render() -> None:
    """Say that this process renders once and exits (see ``one_render``)."""
    global one_render
    one_render = True


def warm(count: int) -> bool:
    """Whether ``count`` workers of this process are running and have served a render."""
    return (_pool.owner == os.getpid() and len(_pool.workers) >= count
            and all(worker.served for worker in _pool.workers[:count]))


class ProcessesUnavailable(Exception):
    """Worker processes cannot be used for this render; the caller renders on threads."""


class WorkersBusy(ProcessesUnavailable):
    """Another render (a viewport's, say) is using the workers: threads this time, and no
    reason to tell the user."""


def _python_executable() -> str | None:
    """The Python that workers run: sys.executable if it is a Python program, else None."""
    executable = sys.executable
    if not executable or not os.path.isfile(executable):
        return None
    if not os.path.basename(executable).lower().startswith("python"):
        return None   # e.g. an embedding program that left sys.executable as itself
    return executable


class _Worker:
    def __init__(self, process, connection):
        self.process = process
        self.connection = connection
        self.in_flight: list = []
        self.frames: set[int] = set()   # ids of the frames this worker has mapped
        self.served = False              # has been ready for a render (is warm)
        self.owes_end = False            # its last render's 'ready' and 'ended' are unread

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


class _Frame:
    """Memory for one frame's image that the parent and the workers map (``_anonymous_file``):
    the workers write their tiles into it and the caller gets the parent's mapping as the
    render's image, so no tile is copied.  A frame whose image the caller has dropped is
    used again by a later render (its pages are already mapped everywhere)."""

    _ids = itertools.count(1)

    def __init__(self, size: int):
        self.id = next(self._ids)
        self.size = size
        self.descriptor = _anonymous_file(size)
        self._handed_out = None   # weakref to the mapping behind the image last handed out

    def busy(self) -> bool:
        """Whether an image of this frame (or a view of one) is still alive."""
        return self._handed_out is not None and self._handed_out() is not None

    def image(self, shape, dtype) -> np.ndarray:
        """A new (H, W, 4) image over this frame; its mapping lives as long as the image.
        A frame used before has its pages already: they are mapped at once (one system
        call, not a fault per page).  A new one's pages are allocated where they are first
        written, by the workers in parallel, not all here before the first tile."""
        mapping = _map(self.descriptor, self.size, populate=self._handed_out is not None)
        self._handed_out = weakref.ref(mapping)
        return _frame_image(mapping, shape, dtype)

    def close(self) -> None:
        """Let the memory go once every mapping is gone (an image still alive keeps it)."""
        os.close(self.descriptor)


class _Pool:
    """The live worker processes of this process, reused from render to render."""

    def __init__(self):
        self.lock = threading.Lock()      # one render at a time uses the workers
        self.workers: list[_Worker] = []
        self.owner = os.getpid()
        self.control = None               # one page every worker maps: byte 0 stops tiles
        self.control_descriptor = None
        self.frames: list[_Frame] = []    # most recently used last

    def frame(self, size: int) -> _Frame:
        """A kept frame of at least ``size`` bytes that no live image uses, else a new one."""
        for frame in self.frames:
            if frame.size >= size and not frame.busy():
                self.frames.remove(frame)
                break
        else:
            frame = _Frame(size)
        self.frames.append(frame)
        return frame

    def kept_frames(self) -> list[int]:
        """Let go of all but the KEPT_FRAMES most recent frames of at most KEEP_SHARED_BYTES;
        the ids of those kept."""
        kept = [f for f in self.frames if f.size <= KEEP_SHARED_BYTES][-KEPT_FRAMES:]
        for frame in self.frames:
            if frame not in kept:
                frame.close()
        self.frames = kept
        return [frame.id for frame in kept]

    def free_memory(self) -> None:
        for frame in self.frames:
            frame.close()
        self.frames = []
        if self.control is not None:
            self.control.close()
            os.close(self.control_descriptor)
            self.control = self.control_descriptor = None

    def grow(self, count: int) -> None:
        """Start workers until there are ``count`` (raises ProcessesUnavailable)."""
        global unavailable_reason
        if self.owner != os.getpid():     # a fork of the process that started them
            self._forget()
        executable = _python_executable()
        if executable is None:
            unavailable_reason = f"sys.executable ({sys.executable!r}) is not a Python"
        elif os.name != "posix":
            unavailable_reason = "worker processes need POSIX descriptor passing"
        if unavailable_reason is not None:
            raise ProcessesUnavailable(unavailable_reason)
        if self.control is None:
            self.control_descriptor = _anonymous_file(mmap.PAGESIZE)
            self.control = _map(self.control_descriptor, mmap.PAGESIZE)
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
                send_handle(worker.connection, self.control_descriptor, process.pid)
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

    def _forget(self) -> None:
        """In a fork of the process that started the workers: they are its parent's."""
        self.workers, self.frames, self.owner = [], [], os.getpid()
        self.control = self.control_descriptor = None

    def shutdown(self, timeout: float) -> None:
        if self.owner != os.getpid():
            self._forget()
            return
        idle = self.lock.acquire(timeout=timeout)
        try:
            # A render still running after ``timeout`` (a viewport's, as the add-on is
            # disabled) loses its workers and fails with a RenderError; the memory it uses
            # is let go when it ends.
            self.drop_all()
            if idle:
                self.free_memory()
        finally:
            if idle:
                self.lock.release()


_pool = _Pool()
atexit.register(_pool.shutdown, END_TIMEOUT_SECONDS)


def worker_pids() -> list[int]:
    """Process ids of the live workers (for measurements: the benchmark's CPU time)."""
    return [worker.process.pid for worker in _pool.workers]


def shutdown(timeout: float = END_TIMEOUT_SECONDS) -> None:
    """End the worker processes and free the kept shared image (the next render with
    processes starts new ones).  Waits up to ``timeout`` seconds for a running render to
    finish first, then ends the workers anyway."""
    _pool.shutdown(timeout)


class _Render:
    """One render on ``count`` of the pool's workers, into a frame's image (``_Frame``)."""

    def __init__(self, ctx, camera, shape, dtype, count: int):
        self.ctx, self.camera = ctx, camera
        self.dtype = np.dtype(dtype)
        self.shape = tuple(shape)
        self.frame = _pool.frame(int(np.prod(self.shape)) * self.dtype.itemsize)
        self.image = self.frame.image(self.shape, self.dtype)
        self.stop = _pool.control
        self.stop[0] = 0
        self.payload = _SharedPayload((ctx, camera))
        self.workers = _pool.workers[:count]
        self.pending = None          # tiles not yet sent (a deque, from ``run``)
        self.starting = set()        # connections of the workers not yet ready
        self.done = 0                # tiles landed
        self.here = 0                # of those, rendered in this process

    def start(self) -> None:
        """Hand every worker this render (each answers 'ready' once it has loaded it)."""
        frame = self.frame
        for worker in list(self.workers):
            if worker.owes_end:           # the last render ended before it was ready
                worker.owes_end = False
                if not _wait_for_end(worker, time.monotonic() + START_TIMEOUT_SECONDS):
                    self.workers.remove(worker)
                    _pool._failed_to_start(worker)
                worker.served = True
            sent = frame.id not in worker.frames
            shared = self.payload
            try:
                worker.connection.send(("render", frame.id, frame.size, self.shape,
                                        self.dtype.name, sent, shared.size, shared.layout))
                if sent:
                    send_handle(worker.connection, frame.descriptor, worker.process.pid)
                    worker.frames.add(frame.id)
                if shared.size:
                    send_handle(worker.connection, shared.descriptor, worker.process.pid)
                worker.connection.send_bytes(shared.payload)
            except OSError:
                self.workers.remove(worker)
                _pool._failed_to_start(worker)
        # (Each worker holds the shared file from its message on: this process's descriptor
        # is no longer needed.)
        self.payload.close()

    def run(self, tiles, finish, should_cancel) -> None:
        """Render ``tiles``; finish(tile, pixels, stats, done, finite) is called in this
        process for each as it lands, pixels its view of the image, finite whether all its
        values are finite.  A worker gets tiles once it is ready.  While a worker is still
        starting (its first render: a Python, NumPy and core import, 0.25-0.5 s here), this
        process renders tiles itself, so a cold start costs the frame nothing but the tiles
        it did not help with."""
        global unavailable_reason

        self.pending = tiles if hasattr(tiles, "popleft") else deque(tiles)
        by_connection = {w.connection: w for w in self.workers}
        self.starting = starting = {w.connection for w in self.workers}
        helping = not all(w.served for w in self.workers)   # warm ones are ready at once
        deadline = time.monotonic() + START_TIMEOUT_SECONDS
        while self.pending or any(w.in_flight for w in self.workers):
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")
            if starting and time.monotonic() > deadline:
                unavailable_reason = (f"worker processes did not start within "
                                      f"{START_TIMEOUT_SECONDS:g} s")
                raise ProcessesUnavailable(unavailable_reason)
            help_now = helping and bool(starting) and bool(self.pending)
            listen = list(starting) + [w.connection for w in self.workers if w.in_flight]
            ready = wait_for(listen, timeout=0 if help_now else CANCEL_POLL_SECONDS)
            for connection in ready:
                worker = by_connection[connection]
                try:
                    message = connection.recv()
                except (EOFError, OSError):
                    if connection in starting:
                        self.workers.remove(worker)
                        _pool._failed_to_start(worker)
                    self._died(worker)
                if connection in starting:       # ('ready',) or ('error', None, ...)
                    starting.discard(connection)
                    if message[0] == "error":
                        _raise_worker_error(message)
                    worker.served = True
                    self._feed(worker, self.pending)
                    continue
                kind, tile = message[0], message[1]
                worker.in_flight.remove(tile)
                if kind == "error":
                    _raise_worker_error(message)
                if kind == "cancelled":
                    raise RenderCancelled("render cancelled")
                self.done += 1
                y0, y1, x0, x1 = tile[:4]
                finish(tile, self.image[y0:y1, x0:x1], message[2], self.done, message[3])
                self._feed(worker, self.pending)
                for other in self.workers:     # (a new pass may have begun)
                    if other is not worker and other.connection not in starting:
                        self._feed(other, self.pending)
            if help_now and not ready:
                self.render_here(self.pending.popleft(), finish)

    def render_here(self, tile, finish) -> None:
        """One tile rendered in this process, as a thread would, into the image."""
        from .tiles import render_tile

        rgba, stats = render_tile(self.ctx, self.camera, tile)
        y0, y1, x0, x1 = tile[:4]
        finite = bool(np.isfinite(rgba).all())
        if finite:
            self.image[y0:y1, x0:x1] = rgba
        self.done += 1
        self.here += 1
        finish(tile, self.image[y0:y1, x0:x1], stats, self.done, finite)

    def finish_here(self, finish, should_cancel) -> None:
        """The workers are gone after some tiles landed: the tiles they had and those never
        sent, rendered in this process (as one thread would; two threads gain nothing)."""

        for worker in self.workers:
            self.pending.extendleft(reversed(worker.in_flight))
            worker.in_flight.clear()
        _pool.drop_all()    # the others started the same way: none is trusted
        while self.pending:
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")
            self.render_here(self.pending.popleft(), finish)

    def _feed(self, worker: _Worker, pending: deque) -> None:
        while len(worker.in_flight) < TILES_IN_FLIGHT and pending:
            tile = pending.popleft()
            try:
                worker.connection.send(tile)
            except OSError:         # it died after its last answer (a broken pipe)
                self._died(worker)
            worker.in_flight.append(tile)

    def _died(self, worker: _Worker):
        """A worker went away during the render: a RenderError naming its exit code."""

        _pool.drop(worker)
        self.workers.remove(worker)
        raise RenderError(f"a render worker process died (exit code "
                          f"{worker.process.returncode})") from None

    def end(self) -> None:
        """Stop running tiles at their next bundle, let every worker drop this render and
        the frames the pool let go (a worker that does not answer is replaced next time)."""
        self.stop[0] = 1
        self.payload.close()
        kept = _pool.kept_frames()
        self.workers = [w for w in self.workers if w in _pool.workers]   # not dropped
        for worker in list(self.workers):
            worker.frames &= set(kept)
            try:
                worker.connection.send(("end", kept))
            except (OSError, ValueError):
                _pool.drop(worker)
                self.workers.remove(worker)
        deadline = time.monotonic() + END_TIMEOUT_SECONDS
        for worker in self.workers:
            if worker.connection in self.starting:
                # Still starting when the frame was done: it answers 'ready' and then
                # 'ended' once up, read at its next render's start (not waited for here).
                worker.owes_end = True
            elif not _wait_for_end(worker, deadline):
                _pool.drop(worker)
            worker.in_flight.clear()
        self.stop = None


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


def planned_bytes(count: int, scene_bytes: int) -> int:
    """What rendering in ``count`` workers holds beyond a threaded render (``core.memory``):
    per worker its interpreter, and one more copy of the scene's arrays, the shared file all
    workers map (``_SharedPayload``, with the frame's tables the parent built:
    ``Aggregate.build_frame_tables``; what a worker still builds on first use is small).  The
    tracing memory only moves into the workers, and the image is the frame they share."""
    return count * WORKER_PROCESS_BYTES + scene_bytes


def render_tiles(ctx, camera, tiles, shape, dtype, count: int, finish,
                 should_cancel=None):
    """(image, fallback): the (H, W, 4) image of ``shape`` and ``dtype`` with ``tiles``
    rendered into it on ``count`` worker processes (and in this process while they start,
    ``_Render.run``); finish(tile, pixels, stats, done, finite) is called in this process as
    each tile lands, pixels the tile's view of the image.  fallback: None, or why this
    process rendered the tiles left after the workers failed to start.  Raises
    ProcessesUnavailable, before any tile is finished, where they cannot be used (cannot
    start here; WorkersBusy: another render is using them)."""
    global last_render_here
    if not _pool.lock.acquire(blocking=False):
        raise WorkersBusy("another render is using the worker processes")
    try:
        try:
            _pool.grow(count)
        except ProcessesUnavailable:
            _pool.drop_all()
            raise
        render = _Render(ctx, camera, shape, dtype, count)
        fallback = None
        try:
            try:
                render.start()
                render.run(tiles, finish, should_cancel)
            except ProcessesUnavailable as error:
                if render.done == 0:
                    raise
                fallback = str(error)       # tiles landed: this process does the rest
                render.finish_here(finish, should_cancel)
            return render.image, fallback
        except ProcessesUnavailable:
            _pool.drop_all()    # the others started the same way: none is trusted
            raise
        finally:
            last_render_here = render.here
            render.end()
            render.image = None   # the caller's now, or gone (its frame is free again)
    finally:
        _pool.lock.release()
