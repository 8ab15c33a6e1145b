"""8-bit RGBA PNG writing with the standard library only (zlib), so the core needs no imaging
package and Blender's bundled Python can use it as is."""

from __future__ import annotations

import os
import struct
import tempfile
import zlib

import numpy as np


def to_rgba8(image: np.ndarray) -> np.ndarray:
    """(H, W, 4) floats in [0, 1] (row 0 = top) -> (H, W, 4) uint8, rounded to nearest."""
    return np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def encode_png(rgba8: np.ndarray) -> bytes:
    """PNG bytes of an (H, W, 4) uint8 array, row 0 = top."""
    height, width, channels = rgba8.shape
    if channels != 4 or rgba8.dtype != np.uint8:
        raise ValueError(f"encode_png needs (H, W, 4) uint8, got {rgba8.shape} {rgba8.dtype}")
    rows = np.zeros((height, 1 + 4 * width), np.uint8)   # filter byte 0 (None) per row
    rows[:, 1:] = rgba8.reshape(height, 4 * width)
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header)
            + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _chunk(b"IEND", b""))


def decode_png(data: bytes) -> np.ndarray:
    """(H, W, 4) uint8 from PNG bytes written by ``encode_png`` (8-bit RGBA, filter 0 only:
    enough for tests and round trips, not a general decoder)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
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


def write_atomically(path: str, data: bytes) -> None:
    """Write data to path through a temporary file in the same folder and a rename, so a
    failure never leaves a partial file (and never destroys an existing one)."""
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix=".glint-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.unlink(temporary)
        raise


def write_png(path: str, image: np.ndarray) -> None:
    """Write an (H, W, 4) float image (row 0 = top) as an 8-bit RGBA PNG, atomically."""
    write_atomically(path, encode_png(to_rgba8(image)))
