"""Timing, memory and error measurements, and what the machine is.

Every contender is timed the same way: one warm-up run (which also measures memory, under
tracemalloc, for Python/NumPy contenders), then the median of up to ``repeats`` timed runs;
a contender whose warm-up took long gets fewer timed runs so that it spends about ``budget``
seconds, and always at least one.
"""

from __future__ import annotations

import gc
import os
import platform
import statistics
import sys
import time
import tracemalloc
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np


@dataclass
class Timing:
    """Seconds of each timed run, and the peak memory in bytes (None: not measured)."""

    runs: list[float] = field(default_factory=list)
    peak_bytes: Optional[int] = None

    @property
    def median(self) -> float:
        return statistics.median(self.runs)


def traced_peak(work: Callable[[], object]):
    """(result, peak bytes allocated through Python's allocators, NumPy's included)."""
    gc.collect()
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        start, _ = tracemalloc.get_traced_memory()
        result = work()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak - start


def timed_runs(work: Callable[[], object], count: int) -> list[float]:
    runs = []
    for _ in range(count):
        gc.collect()
        start = time.perf_counter()
        work()
        runs.append(time.perf_counter() - start)
    return runs


def run_count(repeats: int, warm_up_seconds: float, budget: float) -> int:
    """How many timed runs fit in ``budget`` seconds, between 1 and ``repeats``."""
    return max(1, min(repeats, int(budget // max(warm_up_seconds, 1e-9))))


def measure(work: Callable[[], object], repeats: int, budget: float, trace_memory: bool = True):
    """(result of the warm-up run, Timing): see the module docstring."""
    start = time.perf_counter()
    if trace_memory:
        result, peak = traced_peak(work)
    else:
        gc.collect()
        result, peak = work(), None
    warm_up = time.perf_counter() - start
    return result, Timing(timed_runs(work, run_count(repeats, warm_up, budget)), peak)


# --------------------------------------------------------------------------------------------
# Errors, in 8-bit steps (1 = one step of an 8-bit image, 1/255).

STEPS = 255.0


def rgb_error(image: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """(max, RMS) of |image - reference| over every pixel's R, G and B, in 8-bit steps."""
    if image.shape[:2] != reference.shape[:2]:
        raise ValueError(f"image {image.shape[:2]} and reference {reference.shape[:2]} differ "
                         f"in size")
    difference = np.abs(image[..., :3].astype(np.float64) - reference[..., :3])
    return (float(difference.max()) * STEPS,
            float(np.sqrt(np.mean(difference ** 2))) * STEPS)


def silhouette_mismatches(alpha: np.ndarray, reference_alpha: np.ndarray) -> int:
    """Pixels covered (alpha > 0.5) in one mask but not in the other."""
    if alpha.shape != reference_alpha.shape:
        raise ValueError(f"masks {alpha.shape} and {reference_alpha.shape} differ in size")
    return int(np.count_nonzero((alpha > 0.5) != (reference_alpha > 0.5)))


# --------------------------------------------------------------------------------------------

def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def load_average() -> str:
    try:
        return " ".join(f"{value:.2f}" for value in os.getloadavg())
    except OSError:
        return "unknown"


def machine_lines() -> list[str]:
    return [
        f"CPU: {cpu_model()}, {os.cpu_count()} cores",
        f"Python {platform.python_version()}, NumPy {np.__version__}, {platform.platform()}",
        f"Load average at start (1, 5, 15 min): {load_average()}",
        f"Command: python -m bench {' '.join(sys.argv[1:])}".rstrip(),
    ]


def cpu_seconds(pids=()) -> Optional[float]:
    """User + system CPU seconds of this process and of the processes ``pids`` (Linux's
    /proc; None where it cannot be read)."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    total = usage.ru_utime + usage.ru_stime
    tick = os.sysconf("SC_CLK_TCK")
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
        except OSError:
            return None
        total += (int(fields[11]) + int(fields[12])) / tick
    return total
