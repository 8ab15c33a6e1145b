"""Tiles rendered on a Dask cluster (``RenderSettings.cluster``), a third way to run a frame's
tiles beside threads and local worker processes (``core.workers``), with the same shape:
``render_tiles(address, ctx, camera, tiles, shape, dtype, finish, should_cancel)``.

* The submitting process builds the frame's ``TraceContext`` as for any render; it is
  pickled once (protocol 5, its large arrays beside the pickle without a copy) and scattered
  to every worker once per frame (``Client.scatter(..., broadcast=True)``), never once per
  tile.  The tiles (plain (y0, y1, x0, x1) or ``core.progressive.TileJob``s) are dealt into
  a few tasks per worker (``task_groups``: a tile is too small a task), whose arguments are
  the scattered frame and the tiles' numbers; a worker unpickles a frame once
  (``_worker_frame``) and keeps it for the frame's other tasks.  Results (each tile's pixels
  in the image's dtype, its RayStats as numbers) come back as tasks finish and are handed to
  ``finish`` in this process tile by tile, exactly as ``core.workers`` hands its tiles over:
  the image, the progress and Blender's tiles do not know where a tile ran, and a
  progressive frame's ``WorkQueue`` is read again after every landed task so that its next
  pass is submitted as soon as it exists.
* A worker needs only NumPy and Glint's core, installed with pip from the repository under
  the package name ``WORKER_PACKAGE`` (``pyproject.toml``); so does the scheduler, which
  unpickles the tasks it is given (Dask's own rule: one environment everywhere).  The
  submitter imports the core
  under another name (``core`` in a checkout, ``glint.core`` in render.py, ``bl_ext....core``
  in Blender), so nothing crosses by the submitter's module names: the worker's functions
  are called by their name in ``WORKER_PACKAGE`` (``_WorkerFunction``), a frame's pickle is
  read with the submitter's module names mapped to the worker's (``_CoreUnpickler``), and
  results are plain arrays, numbers and strings.
* A worker must run the submitter's Glint: the same version and the same core source
  (``identity``); one that does not is refused with one line, before the frame's scene is
  sent (``_check_workers``) and again by each task (a worker that joined later).
* A worker that dies mid-frame loses nothing: the scheduler runs its tasks again on the
  others, which have the frame already, and every tile's pixels depend only on the tile,
  so the image is the same.
* Ctrl-C, a cancel, or any exception here cancels the frame's tasks on the cluster and tells
  every worker to stop its running tile at its next bundle of rays (``stop_frame``).
* ``distributed`` is imported only here, lazily: the core, the add-on and local renders do
  not need it.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import os
import pickle
import queue
import threading
import time
import traceback
import uuid
from collections import OrderedDict, deque

import numpy as np

from .failures import CANCEL_POLL_SECONDS, RenderCancelled, RenderError
from .validation import SceneError
from .version import VERSION

#: The name pip installs the core under on a worker (``pyproject.toml``): not a top-level
#: ``core``, which any project may have.
WORKER_PACKAGE = "glint_raytracer_core"
#: The pip distribution that installs it.
WORKER_DISTRIBUTION = "glint-raytracer-core"
#: How long to wait for the scheduler to answer, and for it to have a worker (seconds);
#: the environment variable GLINT_CLUSTER_TIMEOUT sets another.
DEFAULT_TIMEOUT_SECONDS = 30.0
TIMEOUT_VARIABLE = "GLINT_CLUSTER_TIMEOUT"
#: Arrays of at least this many bytes travel beside the frame's pickle, not inside it.
OUT_OF_BAND_BYTES = 64 * 2 ** 10
#: Tasks a pass's tiles are dealt into per worker (``task_groups``): enough for the
#: scheduler to balance tiles of unequal cost, few enough that a task's cost is small
#: beside its tiles'.
TASKS_PER_WORKER = 4
#: Frames a worker keeps unpickled (the current one, and the last, whose forgetting may
#: arrive after the next frame's first tile).
KEPT_FRAMES = 2
#: What Dask's distributed scheduler is installed as, for the line that says it is missing.
INSTALL_HINT = 'pip install "dask[distributed]"'

_CORE_PACKAGE = __name__.rpartition(".")[0]
_CORE_FOLDER = os.path.dirname(os.path.abspath(__file__))


class ClusterError(SceneError):
    """The cluster cannot render this frame (no Dask, an unreachable scheduler, no workers,
    a worker running another Glint, a tile that failed there); the message is one line,
    reported as the front ends report a setting they cannot use."""


def timeout_seconds() -> float:
    """DEFAULT_TIMEOUT_SECONDS, or GLINT_CLUSTER_TIMEOUT's value."""
    text = os.environ.get(TIMEOUT_VARIABLE, "").strip()
    if not text:
        return DEFAULT_TIMEOUT_SECONDS
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value < float("inf"):
        raise ClusterError(f"{TIMEOUT_VARIABLE} must be a positive number of seconds, got "
                           f"{text!r}")
    return value


# ------------------------------------------------------------------------------------------
# What the submitter and the workers agree on

_identity = None


def identity() -> tuple[str, str]:
    """(version, source): this core's Glint version and a hash of its Python source (every
    .py file under the core's folder, by relative path), which two installs of one commit
    share and a changed file does not."""
    global _identity
    if _identity is None:
        digest = hashlib.sha256()
        for folder, folders, files in os.walk(_CORE_FOLDER):
            folders[:] = sorted(f for f in folders if f != "__pycache__")
            for name in sorted(f for f in files if f.endswith(".py")):
                path = os.path.join(folder, name)
                relative = os.path.relpath(path, _CORE_FOLDER).replace(os.sep, "/")
                with open(path, "rb") as stream:
                    digest.update(relative.encode() + b"\0" + stream.read() + b"\0")
        _identity = (VERSION, digest.hexdigest()[:16])
    return _identity


def skew_line(worker: str, theirs, ours) -> str | None:
    """The line refusing a worker whose identity ``theirs`` is not ``ours``, or None."""
    theirs, ours = tuple(theirs), tuple(ours)
    if theirs == ours:
        return None
    if theirs[0] != ours[0]:
        return (f"cluster worker {worker} runs Glint {theirs[0]}, this is Glint {ours[0]}: "
                f"install the same version on every worker ({WORKER_DISTRIBUTION})")
    return (f"cluster worker {worker} runs another build of Glint {ours[0]} (core source "
            f"{theirs[1]}, here {ours[1]}): install this checkout's core on every worker")


class _Module:
    """Pickles as ``importlib.import_module(name)``."""

    def __init__(self, name: str):
        self.name = name

    def __reduce__(self):
        return importlib.import_module, (self.name,)


class _WorkerFunction:
    """A function of this module called on a worker by its name in the worker's package
    (``WORKER_PACKAGE``): it pickles as ``getattr(import_module(...), name)``, whatever
    this process imported the core as."""

    def __init__(self, name: str):
        self.name = name
        self.__name__ = name

    def __reduce__(self):
        return getattr, (_Module(f"{WORKER_PACKAGE}.cluster"), self.name)

    def __call__(self, *args, **keywords):     # (only ever called on a worker)
        return getattr(importlib.import_module(f"{WORKER_PACKAGE}.cluster"),
                       self.name)(*args, **keywords)


# ------------------------------------------------------------------------------------------
# The worker side

_frames: "OrderedDict[str, tuple]" = OrderedDict()   # frame key -> (ctx, camera)
_frames_lock = threading.Lock()
_stopped: set[str] = set()


class _CoreUnpickler(pickle.Unpickler):
    """Reads a pickle made by a process that imported the core as ``sender``, with this
    process's core in its place."""

    def __init__(self, stream, sender: str, buffers):
        super().__init__(stream, buffers=buffers)
        self.sender = sender

    def find_class(self, module, name):
        if module == self.sender or module.startswith(self.sender + "."):
            module = _CORE_PACKAGE + module[len(self.sender):]
        return super().find_class(module, name)


def _load_frame(frame) -> tuple:
    sender, payload, buffers, read_only = frame
    views = [memoryview(np.ascontiguousarray(buffer)).cast("B") for buffer in buffers]
    views = [view.toreadonly() if locked else view for view, locked in zip(views, read_only)]
    return _CoreUnpickler(io.BytesIO(payload), sender, views).load()


def _worker_frame(key: str, frame) -> tuple:
    """(ctx, camera) of the frame ``key`` (``frame``: what ``_frame_data`` made), unpickled
    once per worker (two threads of one worker may both unpickle it: the lock is held only
    briefly, as ``forget_frame`` takes it on the worker's event loop); the oldest of more
    than KEPT_FRAMES is let go."""
    with _frames_lock:
        loaded = _frames.get(key)
    if loaded is None:
        loaded = _load_frame(frame)
        with _frames_lock:
            _frames[key] = loaded
            while len(_frames) > KEPT_FRAMES:
                _stopped.discard(_frames.popitem(last=False)[0])
    return loaded


class _FrameStop:
    """threading.Event's ``is_set`` for one frame: set by ``stop_frame``."""

    def __init__(self, key: str):
        self.key = key

    def is_set(self) -> bool:
        return self.key in _stopped


def worker_identity() -> tuple[str, str]:
    """Run on a worker by ``_check_workers``."""
    return identity()


async def stop_frame(key: str) -> None:
    """Run on every worker (on its event loop: ``Client.run`` without waiting takes
    coroutines only) when a frame is cancelled: its running tile stops at its next bundle of
    rays, and its tiles still to come return at once."""
    _stopped.add(key)
    await forget_frame(key)


async def forget_frame(key: str) -> None:
    """Run on every worker when a frame ends: its unpickled scene is let go."""
    with _frames_lock:
        _frames.pop(key, None)


def run_tiles(frame, key: str, tiles: bytes, dtype: str, sender_identity):
    """One task: the tiles ``tiles`` (a pickled list of each tile's or TileJob's numbers) of
    frame ``key``
    rendered on this worker, one after the other.  Returns ('done', [pixels in ``dtype``],
    [RayStats values], [whether every value is finite]), one of each per tile;
    ('cancelled',); ('skew', this worker's identity, its address); or ('error', exception
    type, message, traceback text).  Never raises, so that nothing of this package must be
    unpickled by the submitter."""
    from . import allocator
    from .progressive import TileJob
    from .tiles import render_tile

    if tuple(sender_identity) != identity():
        from distributed import get_worker
        return ("skew", identity(), get_worker().address)
    stop = _FrameStop(key)
    # A Dask worker is not Glint's own process: its malloc settings only where the user
    # asks (GLINT_MALLOC_TUNING=1 in the worker's environment, core.allocator).
    allocator.configure_if_opted_in()
    answer = ("done", [], [], [])
    try:
        with allocator.small_pages():
            ctx, camera = _worker_frame(key, frame)
            for tile in pickle.loads(tiles):
                job = TileJob(*tile) if len(tile) > 4 else tuple(tile)
                pixels, stats = render_tile(ctx, camera, job, stop)
                answer[1].append(np.ascontiguousarray(pixels, np.dtype(dtype)))
                answer[2].append(tuple(getattr(stats, name)
                                       for name in stats.__dataclass_fields__))
                answer[3].append(bool(np.isfinite(pixels).all()))
        return answer
    except RenderCancelled:
        return ("cancelled",)
    except Exception as error:
        text = "".join(traceback.format_exception(type(error), error, error.__traceback__))
        return ("error", type(error).__name__, str(error), text)


# ------------------------------------------------------------------------------------------
# The submitter side

_clients: dict = {}
_clients_lock = threading.Lock()


def _distributed():
    try:
        import distributed
    except ImportError:
        raise ClusterError(f"rendering on a cluster needs Dask's distributed scheduler, "
                           f"which is not installed: {INSTALL_HINT}") from None
    return distributed


def _reason(error: BaseException) -> str:
    lines = str(error).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def client(address: str):
    """A connected ``distributed.Client`` of the scheduler at ``address``, kept for later
    frames (an animation connects once).  Security (TLS certificates) comes from Dask's
    configuration (``distributed.comm.tls``: its YAML files or DASK_* variables)."""
    distributed = _distributed()
    with _clients_lock:
        kept = _clients.get(address)
        if kept is not None and kept.status == "running":
            return kept
        timeout = timeout_seconds()
        if address.startswith("tls://") and distributed.security.Security(
                ).get_connection_args("client").get("ssl_context") is None:
            # (Checked first: a Client that fails on it waits a minute to close.)
            raise ClusterError(f"{address} is a TLS scheduler, but Dask's configuration "
                               f"gives this process no TLS certificate "
                               f"(distributed.comm.tls: ca-file, client cert and key; "
                               f"docs/user-guide.md)")
        try:
            made = distributed.Client(address, timeout=f"{timeout}s", set_as_default=False)
        except (OSError, TimeoutError) as error:
            raise ClusterError(f"cannot reach the Dask scheduler at {address} within "
                               f"{timeout:g} s ({_reason(error)})") from None
        except (TypeError, ValueError) as error:   # (a configuration Dask cannot use)
            raise ClusterError(f"cannot connect to the Dask scheduler at {address}: "
                               f"{_reason(error)}") from None
        _clients[address] = made
        return made


def close_clients() -> None:
    """Disconnect from every scheduler (the workers keep running)."""
    with _clients_lock:
        for made in _clients.values():
            try:
                made.close()
            except Exception:   # a scheduler already gone: nothing left to close
                pass
        _clients.clear()


def _check_workers(connection, address: str) -> list[str]:
    """The workers' addresses, after waiting for at least one; every one must run this
    Glint (ClusterError otherwise)."""
    timeout = timeout_seconds()
    try:
        connection.wait_for_workers(1, timeout=timeout)
    except (TimeoutError, OSError) as error:
        if isinstance(error, OSError) and not isinstance(error, TimeoutError):
            raise ClusterError(f"lost the Dask scheduler at {address} "
                               f"({_reason(error)})") from None
        raise ClusterError(f"the Dask scheduler at {address} has no workers (waited "
                           f"{timeout:g} s): start some with 'dask worker {address} "
                           f"--nthreads 1 --nworkers N'") from None
    answers = connection.run(_WorkerFunction("worker_identity"), on_error="return")
    ours = identity()
    for worker, answer in sorted(answers.items()):
        if isinstance(answer, ImportError) or WORKER_PACKAGE in str(answer):
            # (Dask hands a worker's exception back as a plain Exception naming it.)
            raise ClusterError(f"cluster worker {worker} has no Glint core (no module "
                               f"{WORKER_PACKAGE}): install it there with pip install "
                               f"{WORKER_DISTRIBUTION} from Glint's repository "
                               f"(docs/user-guide.md)")
        if isinstance(answer, BaseException):
            raise ClusterError(f"cluster worker {worker} failed Glint's version check "
                               f"({type(answer).__name__}: {_reason(answer)})")
        line = skew_line(worker, answer, ours)
        if line is not None:
            raise ClusterError(line)
    return sorted(answers)


def frame_data(ctx, camera) -> tuple:
    """What is scattered once per frame: (the core's name here, the pickle of (ctx, camera),
    its large arrays' bytes as uint8 arrays (sent without a copy into the pickle), which of
    them are read-only)."""
    from .shared_memory import pickle_out_of_band

    payload, buffers = pickle_out_of_band((ctx, camera), OUT_OF_BAND_BYTES)
    arrays = [np.frombuffer(buffer.raw(), np.uint8) for buffer in buffers]
    return (_CORE_PACKAGE, payload, arrays, [buffer.raw().readonly for buffer in buffers])


def frame_bytes(data) -> int:
    """Bytes of a frame's scattered data (what each worker receives once per frame)."""
    return len(data[1]) + sum(array.nbytes for array in data[2])


#: What the last render on a cluster sent and received, for measurements (bench.cluster):
#: bytes of the scattered frame (per worker), workers it went to, tiles, bytes of the
#: results, seconds to pickle and scatter the frame, seconds from then to the last tile
#: landed, and each tile's seconds on its worker.
last_render = {"frame_bytes": 0, "workers": 0, "tiles": 0, "result_bytes": 0,
               "send_seconds": 0.0, "tiles_wall_seconds": 0.0, "tile_seconds": []}


def task_groups(jobs: list, workers: int) -> list[list]:
    """``jobs`` dealt into at most TASKS_PER_WORKER groups per worker, a task each, every
    group taking every n-th job so that the costly tiles of one region spread over the
    tasks.  A tile of the article's 1080p frame takes 2-3 ms, far below what a task costs
    the scheduler and the network (a few ms each, more on a loaded machine), so the tiles
    travel in groups; a frame of few tiles still gives every worker one."""
    count = min(len(jobs), TASKS_PER_WORKER * workers)
    return [jobs[k::count] for k in range(count)]


def render_tiles(address: str, ctx, camera, tiles, shape, dtype, finish, should_cancel=None):
    """The (H, W, C) image of ``shape`` and ``dtype`` with ``tiles`` rendered into it on the
    cluster at ``address``; finish(tile, pixels, stats, done, finite) is called in this
    process as each tile lands (``core.workers.render_tiles``' contract: pixels the tile's
    view of the image, finite whether the values it was made from are all finite).  tiles:
    a list, or a deque-like queue that ``finish`` may extend (a progressive frame's
    ``WorkQueue``).  Raises ClusterError (one line) where the cluster cannot render it,
    RenderCancelled when ``should_cancel()`` answers True."""
    from .rays import RayStats

    connection = client(address)
    workers = _check_workers(connection, address)
    dtype = np.dtype(dtype)
    image = np.zeros(shape, dtype)
    key = f"glint-frame-{uuid.uuid4().hex}"
    began = time.perf_counter()
    data = frame_data(ctx, camera)
    pending = tiles if hasattr(tiles, "popleft") else deque(tiles)
    ours = identity()
    run = _WorkerFunction("run_tiles")
    running: dict = {}         # future -> its jobs
    landed = queue.Queue()     # futures as they finish (their callbacks' thread puts them)
    counter = 0
    done = 0
    frame = None
    sent = {"frame_bytes": frame_bytes(data), "workers": len(workers), "tiles": 0,
            "result_bytes": 0, "send_seconds": 0.0, "tiles_wall_seconds": 0.0,
            "tile_seconds": []}
    try:
        try:
            [frame] = connection.scatter([data], broadcast=True, hash=False)
        except (OSError, TimeoutError) as error:
            raise ClusterError(f"cannot send the scene to the cluster at {address} "
                               f"({_reason(error)})") from None
        sent["send_seconds"] = time.perf_counter() - began

        def submit_ready():
            nonlocal counter
            jobs = [pending.popleft() for _ in range(len(pending))]
            for group in task_groups(jobs, len(workers)):
                counter += 1
                # Loosely bound to the workers known now: the scheduler then hands every
                # worker its share at once instead of one task per idle thread (its queuing
                # of tasks without restrictions), so that no worker waits a round trip
                # between tasks; any other worker may still take them (work stealing, a
                # worker that died).
                # (The tiles' numbers as one pickle of builtins: Dask reads lists and tuples
                # in a task's arguments as parts of its graph.)
                numbers = pickle.dumps([tuple(job) for job in group])
                future = connection.submit(run, frame, key, numbers,
                                           dtype.str, ours, pure=False,
                                           key=f"glint-tiles-{key[12:]}-{counter}",
                                           workers=workers, allow_other_workers=True)
                running[future] = group
                future.add_done_callback(landed.put)

        submit_ready()
        while running:
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")
            try:
                batch = [landed.get(timeout=CANCEL_POLL_SECONDS)]
            except queue.Empty:
                continue
            while not landed.empty():       # (one round trip for all that have finished)
                batch.append(landed.get_nowait())
            batch = [future for future in batch if future in running]
            for future, answer in zip(batch, _answers(connection, batch, running, address)):
                jobs = running.pop(future)
                future.release()        # (the worker may drop its copy now)
                if answer[0] == "skew":
                    raise ClusterError(skew_line(answer[2], answer[1], ours))
                if answer[0] == "cancelled":
                    raise RenderCancelled("render cancelled")
                if answer[0] == "error":
                    _, kind, message, text = answer
                    error = RenderError(f"a tile failed on the cluster ({kind}: {message})")
                    error.add_note("on a cluster worker:\n" + text.rstrip())
                    raise error
                for job, pixels, values, finite in zip(jobs, *answer[1:]):
                    y0, y1, x0, x1 = job[:4]
                    view = image[y0:y1, x0:x1]
                    if finite:
                        view[...] = pixels
                    done += 1
                    stats = RayStats(*values)
                    sent["tiles"] += 1
                    sent["result_bytes"] += pixels.nbytes
                    sent["tile_seconds"].append(stats.seconds_tiles)
                    finish(job, view, stats, done, finite)
            submit_ready()       # (a landed tile may have begun a new pass)
        sent["tiles_wall_seconds"] = time.perf_counter() - began - sent["send_seconds"]
    except BaseException:
        if running:
            _cancel(connection, list(running), key)
        raise
    finally:
        last_render.update(sent)
        if frame is not None:
            _release(connection, frame, key)
    return image


def _answers(connection, futures, running, address: str) -> list:
    """Finished tasks' answers, fetched together; the cluster's failures (a task that killed
    every worker it ran on, a lost dependency, a lost scheduler) as one line."""
    for future in futures:
        try:
            if future.status != "finished":
                future.result()             # (raises the task's failure)
        except (OSError, TimeoutError) as error:
            raise ClusterError(f"lost the Dask scheduler at {address} "
                               f"({_reason(error)})") from None
        except Exception as error:      # KilledWorker, a lost dependency, ...
            y0, y1, x0, x1 = running[future][0][:4]
            raise ClusterError(f"the cluster could not render {len(running[future])} tiles "
                               f"from pixels {x0}-{x1 - 1} x {y0}-{y1 - 1} "
                               f"({type(error).__name__}: {_reason(error)})") from None
    try:
        return connection.gather(futures)
    except (OSError, TimeoutError) as error:
        raise ClusterError(f"lost the Dask scheduler at {address} ({_reason(error)})") from None


def _cancel(connection, futures, key: str) -> None:
    """Cancel a frame's tasks on the cluster and stop its running tiles."""
    try:
        connection.cancel(futures, force=True)
        connection.run(_WorkerFunction("stop_frame"), key, wait=False)
    except Exception:   # the scheduler is gone: nothing of the frame runs any more
        pass


def _release(connection, frame, key: str) -> None:
    """Let the workers drop the frame's scattered data and its unpickled scene."""
    try:
        frame.release()
        connection.run(_WorkerFunction("forget_frame"), key, wait=False)
    except Exception:   # the scheduler is gone: so is the frame
        pass
