"""Runs: consecutive stretches of a flat array, described by their lengths.

Culling and traversal lay out variable-length lists (a packet's rays, a ray's candidate
spheres, a ray's BVH nodes) one after another in flat arrays; these helpers turn the lengths
of those runs into where each starts and each element's position within its run.
"""

from __future__ import annotations

import numpy as np


def run_starts(lengths: np.ndarray) -> np.ndarray:
    """(R,) index of the first element of each of R runs laid end to end (an exclusive
    cumulative sum of lengths (R,))."""
    return np.cumsum(lengths) - lengths


def value_run_starts(values: np.ndarray) -> np.ndarray:
    """(R,) index of the first element of each run of equal consecutive values (n,) (the
    runs of a flat array grouped by key, e.g. pairs grouped by ray)."""
    first = np.empty(len(values), bool)
    first[:1] = True
    np.not_equal(values[1:], values[:-1], out=first[1:])
    return np.flatnonzero(first)


def rank_within_runs(lengths: np.ndarray) -> np.ndarray:
    """(lengths.sum(),) each element's position within its run: 0, 1, ..., lengths[0] - 1,
    0, 1, ..., lengths[1] - 1, ... for runs of lengths (R,) laid end to end."""
    return np.arange(int(np.sum(lengths))) - np.repeat(run_starts(lengths), lengths)
