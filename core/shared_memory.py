"""Objects handed to other processes without a copy of their large arrays.

``pickle_out_of_band`` pickles with protocol 5 and leaves large buffers beside the pickle (a
render's context for worker processes, ``core.workers``, and for a Dask cluster,
``core.cluster``); ``_SharedPayload`` puts those buffers in one anonymous file that every
worker maps copy-on-write, and ``_shared_loads`` reads the object back over that mapping.  A
frame's image is such a file too (``_anonymous_file``, ``_frame_image``).
"""

from __future__ import annotations

import mmap
import os
import pickle
import tempfile

import numpy as np


#: A context's arrays of at least this many bytes reach the workers through shared memory
#: (``_SharedPayload``); smaller ones travel inside the pickle (a page per array and a slice
#: of the file would cost more than copying them).
SHARED_ARRAY_BYTES = 64 * 2 ** 10
#: Each shared array starts at a multiple of this within the file (a cache line).
SHARED_ALIGNMENT = 64


def _anonymous_file(size: int, label: str = "glint-frame") -> int:
    """A descriptor of ``size`` zero bytes that no name refers to, so nothing can leak when a
    process dies: a memfd on Linux, an unlinked temporary file elsewhere (label: what
    /proc shows of it)."""
    if hasattr(os, "memfd_create"):
        descriptor = os.memfd_create(label, os.MFD_CLOEXEC)
    else:
        descriptor, path = tempfile.mkstemp(prefix=label + "-")
        os.unlink(path)
    try:
        os.ftruncate(descriptor, size)
    except OSError:
        os.close(descriptor)
        raise
    return descriptor


def _map(descriptor: int, size: int, populate: bool = False) -> mmap.mmap:
    """The file ``descriptor`` mapped shared; populate: map every page at once (one system
    call instead of a page fault per 4 KiB page)."""
    flags = mmap.MAP_SHARED | (getattr(mmap, "MAP_POPULATE", 0) if populate else 0)
    return mmap.mmap(descriptor, size, flags=flags)


class _SharedPayload:
    """A pickled object whose large arrays live outside the pickle, in one anonymous file:
    ``payload`` the pickle (protocol 5), ``layout`` ((offset, bytes, read-only) of each
    out-of-band buffer in pickling order), ``size`` the file's, ``descriptor`` the file (None
    when nothing went out of band).  ``close()`` lets the parent's descriptor go (the
    workers' mappings keep the memory)."""

    def __init__(self, obj):
        self.payload, buffers = pickle_out_of_band(obj)
        self.layout, offset = [], 0
        for buffer in buffers:
            self.layout.append((offset, buffer.raw().nbytes, buffer.raw().readonly))
            offset += -(-buffer.raw().nbytes // SHARED_ALIGNMENT) * SHARED_ALIGNMENT
        self.size = offset
        self.descriptor = None
        if buffers:
            self.descriptor = _anonymous_file(self.size, "glint-scene")
            try:
                for (start, _, _), buffer in zip(self.layout, buffers):
                    _write_all(self.descriptor, buffer.raw(), start)
            except OSError:
                self.close()
                raise

    def close(self) -> None:
        if self.descriptor is not None:
            os.close(self.descriptor)
            self.descriptor = None


def pickle_out_of_band(obj, min_bytes: int = SHARED_ARRAY_BYTES
                       ) -> tuple[bytes, list[pickle.PickleBuffer]]:
    """(pickle, buffers): ``obj`` pickled with protocol 5, its buffers (arrays' data) of at
    least ``min_bytes`` left out of the pickle, to travel beside it without a copy into it;
    ``pickle.loads(pickle, buffers=...)`` takes them back in the same order."""
    buffers = []

    def in_band(buffer: pickle.PickleBuffer) -> bool:
        if buffer.raw().nbytes < min_bytes:
            return True
        buffers.append(buffer)
        return False

    return pickle.dumps(obj, protocol=5, buffer_callback=in_band), buffers


def _write_all(descriptor: int, data: memoryview, offset: int) -> None:
    while len(data):
        written = os.pwrite(descriptor, data, offset)
        data, offset = data[written:], offset + written


def _shared_loads(payload: bytes, mapping, layout) -> object:
    """The object a ``_SharedPayload`` pickled, its large arrays over ``mapping`` (the
    payload's file mapped copy-on-write: the worker may write to them, privately), read-only
    where the parent's were (a scene's frozen arrays stay frozen)."""
    view = memoryview(mapping) if mapping is not None else None
    return pickle.loads(payload, buffers=[
        view[start:start + size].toreadonly() if readonly else view[start:start + size]
        for start, size, readonly in layout])


def _frame_image(mapping, shape, dtype) -> np.ndarray:
    """The (H, W, 4) image of ``dtype`` at the start of ``mapping``."""
    return np.frombuffer(mapping, np.dtype(dtype), count=int(np.prod(shape))).reshape(shape)
