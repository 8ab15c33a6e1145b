"""What a render worker process runs: ``worker_loop`` serves its parent's renders
(``core.workers``), tile by tile, straight into the frame's image they share.

``core._worker_boot`` starts it; the messages it answers are ``worker_loop``'s docstring.
"""

from __future__ import annotations

import mmap
import os
import pickle
import traceback
from multiprocessing.reduction import recv_handle

import numpy as np

from .shared_memory import _frame_image, _map, _shared_loads



class _StopFlag:
    """threading.Event's ``is_set`` over one byte of shared memory (what render_tile polls)."""

    def __init__(self, buffer):
        self._buffer = buffer

    def is_set(self) -> bool:
        return self._buffer[0] != 0


class _Job:
    """One render as a worker sees it: its context, camera and the frame's image."""

    def __init__(self, mapping, shape, dtype_name: str, payload: bytes, shared, layout):
        self.image = _frame_image(mapping, tuple(shape), dtype_name)
        self.shared = shared          # the context's large arrays (or None)
        self.ctx, self.camera = _shared_loads(payload, shared, layout)

    def close(self) -> None:
        self.image = self.ctx = self.camera = None
        if self.shared is not None:
            try:
                self.shared.close()
            except BufferError:       # an array still refers to it: freed with the array
                pass
            self.shared = None


def worker_loop(connection, setup: dict) -> None:
    """Run in a worker: serve renders until the parent sends None or goes away.

    First the control page's descriptor (its byte 0 is the stop byte).  Messages in:
    ('render', frame id, frame bytes, shape, dtype, whether the frame's descriptor follows,
    shared bytes, shared layout), [the frame's descriptor,] [the shared arrays' descriptor
    (when shared bytes > 0),] then the pickled (context, camera) as bytes
    (``_SharedPayload``); a tile (y0, y1, x0, x1);
    ('end', ids of the frames to keep mapped); None.  Answers: ('ready',), ('done', tile,
    stats, whether every value is finite), ('cancelled', tile), ('error', tile, exception,
    traceback text), ('ended',)."""
    from . import allocator

    allocator.configure()
    with allocator.small_pages():     # for good: the process is Glint's (core.allocator)
        _serve(connection)


def _serve(connection) -> None:
    """``worker_loop``'s renders, one after the other."""
    from .failures import RenderCancelled
    from .tiles import render_tile

    try:
        control = _received_mapping(connection, mmap.PAGESIZE)
    except (EOFError, OSError):
        return
    stop = _StopFlag(control)
    frames: dict[int, mmap.mmap] = {}      # frame id -> its mapping, kept between renders
    job = None
    try:
        while True:
            try:
                message = connection.recv()
            except (EOFError, OSError):
                return                      # the parent is gone
            if message is None:
                return
            if message[0] == "render":
                _, frame, size, shape, dtype_name, sent, shared_size, layout = message
                try:
                    if sent:
                        frames[frame] = _received_mapping(connection, size)
                    shared = _received_mapping(connection, shared_size, private=True) \
                        if shared_size else None
                    payload = connection.recv_bytes()
                    if job is not None:       # a render whose end never came
                        job.close()
                    job = _Job(frames[frame], shape, dtype_name, payload, shared, layout)
                except Exception as error:
                    job = None
                    _send_error(connection, None, error)
                    continue
                connection.send(("ready",))
            elif message[0] == "end":
                if job is not None:
                    job.close()
                    job = None
                for frame in set(frames) - set(message[1]):
                    frames.pop(frame).close()  # the parent let this frame go
                connection.send(("ended",))
            elif job is None or stop.is_set():
                connection.send(("cancelled", message))
            else:
                tile = message
                try:
                    rgba, stats = render_tile(job.ctx, job.camera, tile, stop)
                    y0, y1, x0, x1 = tile[:4]
                    job.image[y0:y1, x0:x1] = rgba     # straight into the caller's image
                    connection.send(("done", tile, stats, bool(np.isfinite(rgba).all())))
                except RenderCancelled:
                    connection.send(("cancelled", tile))
                except Exception as error:
                    _send_error(connection, tile, error)
    finally:
        if job is not None:
            job.close()
        for mapping in frames.values():
            mapping.close()


def _received_mapping(connection, size: int, private: bool = False) -> mmap.mmap:
    """The descriptor the parent sends next over ``connection``, mapped (and closed: the
    mapping keeps the memory); private: copy-on-write (writes stay in this process)."""
    descriptor = recv_handle(connection)
    try:
        if private:
            return mmap.mmap(descriptor, size, flags=mmap.MAP_PRIVATE,
                             prot=mmap.PROT_READ | mmap.PROT_WRITE)
        return _map(descriptor, size)
    finally:
        os.close(descriptor)


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
