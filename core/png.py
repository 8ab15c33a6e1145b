"""8-bit RGBA PNG writing with the standard library only (zlib), so the core needs no imaging
package and Blender's bundled Python can use it as is.

Files are written the way a user's previous image must survive any failure
(``atomic_file``): into a new temporary file beside the target, renamed over it only once
complete.  The target is the file a symlink points to (the link stays a link), an existing
file keeps its permission bits, and a write-protected one is refused.  The PNG is encoded a
block of rows at a time straight into that file (several IDAT chunks, as the format allows),
so writing costs a few rows of memory, not a copy of the image.
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
import struct
import zlib
from contextlib import contextmanager
from typing import Callable, Optional

import numpy as np

#: Rows converted and compressed at a time.
ROW_BLOCK = 64
SIGNATURE = b"\x89PNG\r\n\x1a\n"


class WriteCancelled(Exception):
    """``should_cancel()`` answered True while writing; the previous file is intact."""


def to_rgba8(image: np.ndarray) -> np.ndarray:
    """(H, W, 4) floats in [0, 1] (row 0 = top) -> (H, W, 4) uint8, rounded to nearest."""
    return np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def _header(width: int, height: int) -> bytes:
    return SIGNATURE + _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))


def _filtered(rgba8: np.ndarray) -> bytes:
    """Rows of (h, W, 4) uint8 as PNG scanlines: filter byte 0 (None), then the pixels."""
    height, width = rgba8.shape[:2]
    rows = np.zeros((height, 1 + 4 * width), np.uint8)
    rows[:, 1:] = rgba8.reshape(height, 4 * width)
    return rows.tobytes()


def encode_png(rgba8: np.ndarray) -> bytes:
    """PNG bytes of an (H, W, 4) uint8 array, row 0 = top."""
    height, width, channels = rgba8.shape
    if channels != 4 or rgba8.dtype != np.uint8:
        raise ValueError(f"encode_png needs (H, W, 4) uint8, got {rgba8.shape} {rgba8.dtype}")
    return (_header(width, height) + _chunk(b"IDAT", zlib.compress(_filtered(rgba8), 6))
            + _chunk(b"IEND", b""))


def decode_png(data: bytes) -> np.ndarray:
    """(H, W, 4) uint8 from PNG bytes written by ``encode_png`` (8-bit RGBA, filter 0 only:
    enough for tests and round trips, not a general decoder)."""
    if data[:8] != SIGNATURE:
        raise ValueError("not a PNG file")
    pos, idat, size = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height = size
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, 1 + 4 * width)
    if rows[:, 0].any():
        raise ValueError("decode_png reads only unfiltered rows")
    return rows[:, 1:].reshape(height, width, 4).copy()


def write_protected(path: str) -> bool:
    """True if ``path`` exists and its permissions forbid writing it: no write bit at all
    (which root would otherwise ignore), or none for this process."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return False
    return not (mode & 0o222) or not os.access(path, os.W_OK)


@contextmanager
def atomic_path(path: str, suffix: str = ".tmp"):
    """``with atomic_path(path) as temporary: writer(temporary)``: for writers that take a
    file name (Blender's ``Image.save_render``).  ``temporary`` is a new, empty file beside
    the target (ending in ``suffix``) that replaces the file ``path`` names only if the block
    completes; on any exception it is removed and the previous file is untouched.

    A symlink is followed (the file it points to is replaced, the link is kept); an existing
    file keeps its permission bits; a new one gets what a plain ``open()`` would give it (the
    temporary is created with mode 0666 and the kernel applies the umask, so the process-wide
    umask is never changed).  Raises PermissionError for a write-protected file.
    """
    target = os.path.realpath(path)
    if write_protected(target):
        raise PermissionError(errno.EACCES, "the file is write-protected", path)
    try:
        previous_mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        previous_mode = None
    folder = os.path.dirname(target)
    temporary = os.path.join(folder, f".glint-{secrets.token_hex(8)}{suffix}")
    os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield temporary
        if previous_mode is not None:
            os.chmod(temporary, previous_mode)
        os.replace(temporary, target)
    except BaseException:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise


@contextmanager
def atomic_file(path: str):
    """``with atomic_file(path) as stream: stream.write(...)``: the bytes replace the file
    ``path`` names only if the block completes (``atomic_path``'s rules: the previous file
    is untouched on any exception, symlinks are written through, permissions kept,
    write-protected files refused); they reach the disk before the rename."""
    with atomic_path(path) as temporary:
        with open(temporary, "wb") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())


def write_png(path: str, image: np.ndarray, *,
              convert: Optional[Callable[[np.ndarray], np.ndarray]] = None,
              should_cancel: Optional[Callable[[], bool]] = None) -> None:
    """Write an (H, W, 4) float image (row 0 = top) as an 8-bit RGBA PNG, atomically.

    convert: applied to each block of rows (h, W, 4) before quantisation (e.g. unpremultiply),
    so no converted copy of the whole image exists.  should_cancel: polled between blocks; True
    raises WriteCancelled and leaves the previous file as it was."""
    height, width, channels = image.shape
    if channels != 4:
        raise ValueError(f"write_png needs (H, W, 4), got {image.shape}")
    with atomic_file(path) as stream:
        stream.write(_header(width, height))
        compressor = zlib.compressobj(6)
        for first in range(0, height, ROW_BLOCK):
            if should_cancel is not None and should_cancel():
                raise WriteCancelled(f"writing {path} cancelled")
            rows = image[first:first + ROW_BLOCK]
            packed = compressor.compress(_filtered(to_rgba8(
                rows if convert is None else convert(rows))))
            if packed:
                stream.write(_chunk(b"IDAT", packed))
        stream.write(_chunk(b"IDAT", compressor.flush()) + _chunk(b"IEND", b""))
