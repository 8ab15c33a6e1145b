"""A reader for the uncompressed scanline OpenEXR files the tests make Blender write
(``exr_codec = 'NONE'``): enough to look at each layer of a multilayer EXR, nothing more."""

from __future__ import annotations

import struct

import numpy as np

MAGIC = b"\x76\x2f\x31\x01"
_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def _string(data: bytes, pos: int) -> tuple[str, int]:
    end = data.index(b"\0", pos)
    return data[pos:end].decode(), end + 1


def _header(data: bytes, pos: int) -> tuple[dict, int]:
    header = {}
    while data[pos] != 0:
        name, pos = _string(data, pos)
        kind, pos = _string(data, pos)
        (size,) = struct.unpack_from("<i", data, pos)
        header[name] = (kind, data[pos + 4:pos + 4 + size])
        pos += 4 + size
    return header, pos + 1


def _channels(raw: bytes) -> list:
    channels, at = [], 0
    while raw[at] != 0:
        name, at = _string(raw, at)
        (pixel_type,) = struct.unpack_from("<i", raw, at)
        channels.append((name, _TYPES[pixel_type]))
        at += 16
    return channels


def read_exr(path) -> dict[str, np.ndarray]:
    """{channel name: (H, W) float32, row 0 = top} of an uncompressed scanline EXR, single
    or multi-part (Blender 5 writes multilayer files as multi-part)."""
    data = open(path, "rb").read()
    if data[:4] != MAGIC:
        raise ValueError(f"{path} is not an OpenEXR file")
    (version,) = struct.unpack_from("<i", data, 4)
    multipart = bool(version & 0x1000)
    pos, headers = 8, []
    while True:
        header, pos = _header(data, pos)
        headers.append(header)
        if not multipart:
            break
        if data[pos] == 0:
            pos += 1
            break
    parts = []
    for header in headers:
        if header["compression"][1] != b"\0":
            raise ValueError(f"{path} is compressed; the tests write exr_codec 'NONE'")
        x0, y0, x1, y1 = struct.unpack("<4i", header["dataWindow"][1])
        parts.append((x1 - x0 + 1, y1 - y0 + 1, y0, _channels(header["channels"][1])))
    pos += 8 * sum(height for _, height, _, _ in parts)  # offset tables: a line per chunk
    planes = {name: np.empty((height, width), np.float32)
              for width, height, _, channels in parts for name, _ in channels}
    for _ in range(sum(height for _, height, _, _ in parts)):
        part = 0
        if multipart:
            (part,) = struct.unpack_from("<i", data, pos)
            pos += 4
        width, height, y0, channels = parts[part]
        y, _size = struct.unpack_from("<ii", data, pos)
        pos += 8
        for name, dtype in channels:
            planes[name][y - y0] = np.frombuffer(data, dtype, width, pos)
            pos += width * dtype.itemsize
    return planes


def write_exr(path, rgba: np.ndarray) -> None:
    """Write (H, W, C) float32 (row 0 = top, C = 3 or 4: RGB or RGBA) as an uncompressed
    single-part scanline OpenEXR of 32-bit float channels: test images made in the test."""
    rgba = np.asarray(rgba, np.float32)
    height, width, count = rgba.shape
    names = "RGBA"[:count]
    order = sorted(range(count), key=lambda c: names[c])   # channels stored A, B, G, R

    def attribute(name: str, kind: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    channels = b"".join(names[c].encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1)
                        for c in order) + b"\0"
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    header = (MAGIC + struct.pack("<i", 2)
              + attribute("channels", "chlist", channels)
              + attribute("compression", "compression", b"\0")
              + attribute("dataWindow", "box2i", window)
              + attribute("displayWindow", "box2i", window)
              + attribute("lineOrder", "lineOrder", b"\0")
              + attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attribute("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
              + attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    line = 8 + 4 * width * count
    start = len(header) + 8 * height
    offsets = struct.pack(f"<{height}Q", *(start + y * line for y in range(height)))
    planar = np.ascontiguousarray(rgba[..., order].transpose(0, 2, 1))   # (H, C, W)
    with open(path, "wb") as file:
        file.write(header + offsets)
        for y in range(height):
            file.write(struct.pack("<ii", y, 4 * width * count) + planar[y].tobytes())
