"""Cells of directions and of space, one layout each: the cube-map cells that direction bins
(``bins``) and packets of rays (``cull``) cut directions into, and the Morton codes that
order points along a space-filling curve (the tree's clusters, the flat culling's)."""

from __future__ import annotations

import numpy as np

#: Points whose Morton codes are made at a time: their float64 temporaries stay in cache.
CHUNK = 16384


def face_cells(directions, cells: int):
    """(face, u, v) (n,) each: the cube-map cell of each unit direction (3, n), with
    ``cells`` x ``cells`` cells on each of the six faces: face 2 axis + (negative), u along
    the next axis, v along the one after, each in [0, cells).  The major axis is picked by
    comparisons, ties to the lower axis (a tie between two axes may pick either face: bins
    list the boxes seen on their shared edge on both).  Whole-array selections rather than
    an argmax and a fancy gather: half the time."""
    d = directions
    size = np.abs(d)
    x = (size[0] >= size[1]) & (size[0] >= size[2])
    y = ~x & (size[1] >= size[2])
    along = np.where(x, d[0], np.where(y, d[1], d[2]))
    first = np.where(x, d[1], np.where(y, d[2], d[0]))
    second = np.where(x, d[2], np.where(y, d[0], d[1]))
    half = d.dtype.type(cells / 2)
    scale = np.abs(along)
    np.divide(half, scale, out=scale)
    face = np.where(x, 0, np.where(y, 2, 4)) + (along < 0)
    first *= scale
    first += half
    second *= scale
    second += half
    u = np.minimum(first.astype(np.intp), cells - 1)
    v = np.minimum(second.astype(np.intp), cells - 1)
    return face, u, v


def direction_cells(directions, cells: int) -> np.ndarray:
    """(n,) the cube-map cell of each unit direction (3, n) as one number, (face * cells +
    u) * cells + v (``face_cells``): rays sharing a cell point within about 90 / cells
    degrees of each other."""
    face, u, v = face_cells(directions, cells)
    return (face * cells + u) * cells + v


def _spread_table():
    """(2048,) uint64: each 11-bit value with two zero bits inserted after each bit."""
    v = np.arange(2048, dtype=np.uint64)
    spread = np.zeros(2048, np.uint64)
    for bit in range(11):
        spread |= ((v >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit)
    return spread


#: ``_spread_table()``, shifted for the x, y and z bits of a Morton code.
_SPREAD = tuple(_spread_table() << np.uint64(axis) for axis in range(3))


def morton_codes(points: np.ndarray) -> np.ndarray:
    """(N,) uint64 63-bit Morton codes of points (3, N) over their bounding box (a cube of
    its largest side, so that a code prefix is a cubic cell): each coordinate's 21 bits,
    spread by table 11 bits at a time."""
    low = points.min(axis=1)
    extent = (points.max(axis=1) - low).max()
    codes = np.zeros(points.shape[1], np.uint64)
    for first in range(0, points.shape[1], CHUNK):
        part = slice(first, first + CHUNK)
        for axis in range(3):
            cells = ((points[axis, part] - low[axis]) / (extent if extent > 0 else 1)
                     * (2 ** 21 - 1)).astype(np.intp)
            codes[part] |= _SPREAD[axis].take(cells & 2047)
            codes[part] |= _SPREAD[axis].take((cells >> 11) & 1023) << np.uint64(33)
    return codes


def morton_cells(sorted_codes: np.ndarray, per_cell: int) -> np.ndarray:
    """(N,) bool: where a new cell starts in sorted Morton codes, for the finest cells
    (code prefixes, 3 bits a level) that hold on average at least per_cell points.  (A cell
    of prefix shift s starts where consecutive codes differ in a bit at s or above; the
    number of cells falls with s, so the shift is found by bisection.)"""
    differ = sorted_codes[1:] ^ sorted_codes[:-1]

    def cells(shift):
        return 1 + np.count_nonzero(differ >= np.uint64(1 << shift))

    shifts = list(range(0, 64, 3))
    low, high = 0, len(shifts) - 1         # the answer: the first that fits, else the last
    while low < high:
        middle = (low + high) // 2
        if cells(shifts[middle]) * per_cell <= len(sorted_codes):
            high = middle
        else:
            low = middle + 1
    return np.r_[True, differ >= np.uint64(1 << shifts[low])]
