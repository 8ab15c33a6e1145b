"""Progressive path-traced frames: samples added pass by pass over the whole frame.

A path-traced frame is rendered in passes: the first gives every pixel a sample, each next
one adds as many samples as the frame has so far (1, 1, 2, 4, ...), up to the samples asked
for, so the picture is whole early and sharpens as it goes, as Cycles' progressive render
does.  A pass is one ``TileJob`` per tile: the tile, the range of sample indices it adds,
and (with a noise threshold) which of its pixels still take samples.  Tiles render their
pass's *sums* (``SUM_CHANNELS``: radiance, twice the odd samples' radiance, alpha, the
sample count, and the denoising guides' sums) wherever they run, threads or worker
processes; ``ProgressiveFrame`` adds them into the frame's totals as they land and hands
the frame's current mean of that tile on.  A cancelled frame keeps what landed; a time
limit ends the frame after the pass during which it ran out.

With a noise threshold a pixel stops once ``converged`` says so, judged after each pass
from its own samples: the image does not depend on tiles or on how they ran.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import NamedTuple

import numpy as np

#: Channels of a pass's per-pixel sums: RGB, RGB of the odd samples (twice), alpha, count.
SUM_CHANNELS = 8
#: ... and the guides' (albedo, normal) sums after them when the frame has guides.
GUIDE_SUM_CHANNELS = 6


class TileJob(NamedTuple):
    """One tile's share of a pass: rows y0..y1, columns x0..x1, sample indices
    first..last, and live: which of its pixels take them (a packed bit per pixel in row
    order, bytes), or None for all; passes: the frame has passes, which the job's sums
    carry (``core.tiles.render_path_tile``)."""

    y0: int
    y1: int
    x0: int
    x1: int
    first: int
    last: int
    live: bytes | None = None
    passes: bool = False

    def live_pixels(self) -> np.ndarray | None:
        """(h, w) bool of the pixels taking samples, or None for all."""
        if self.live is None:
            return None
        h, w = self.y1 - self.y0, self.x1 - self.x0
        bits = np.unpackbits(np.frombuffer(self.live, np.uint8), count=h * w)
        return bits.reshape(h, w).astype(bool)


def pass_sizes(samples: int, first: int = 1) -> list[int]:
    """The samples each pass adds: ``first``, then as many as there are so far, up to
    ``samples`` in all."""
    sizes, done = [], 0
    size = max(1, min(first, samples))
    while done < samples:
        size = min(size, samples - done)
        sizes.append(size)
        done += size
        size = done
    return sizes


def min_samples(settings) -> int:
    """The samples every pixel gets before adaptive sampling may stop it: the setting, or
    for 0 Cycles' automatic choice from the noise threshold."""
    if settings.min_samples > 0:
        return min(settings.min_samples, settings.samples)
    threshold = max(settings.noise_threshold, 1e-6)
    return min(settings.samples, max(4, math.ceil(16.0 / threshold ** 0.3)))


def converged(total, half, count, threshold: float):
    """(k,) whether pixels whose sample sums are ``total`` (3, k) and twice the sums of
    their odd samples ``half`` (3, k) after ``count`` (k,) samples are converged: Cycles'
    ``film_adaptive_sampling_convergence_check`` (the two halves' estimates differ by less
    than ``threshold`` relative to the square root of the pixel's brightness)."""
    difference = np.abs(total - half).sum(axis=0) / count
    normalise = np.sqrt(np.maximum(total.sum(axis=0), 0) / count)
    return difference / (1e-4 + normalise) < threshold


class WorkQueue:
    """The passes' tile jobs in order, made one pass at a time: a deque of the jobs ready to
    run (what the schedulers pop), which ``refill`` extends with the next pass once the
    frame has every tile of the last one."""

    def __init__(self, frame: "ProgressiveFrame"):
        self.frame = frame
        self.jobs = deque(frame.next_pass())

    def __bool__(self) -> bool:
        return bool(self.jobs)

    def __len__(self) -> int:
        return len(self.jobs)

    def popleft(self):
        return self.jobs.popleft()

    def extendleft(self, items) -> None:
        self.jobs.extendleft(items)

    def refill(self) -> None:
        """After a job landed: the next pass's jobs, if the last pass is complete."""
        if not self.jobs and self.frame.pass_complete():
            self.jobs.extend(self.frame.next_pass())


class ProgressiveFrame:
    """The totals of a frame being path traced (module docstring) and its visible image.

    image: (H, W, 4 [+ 6]) of the image dtype, the current mean of every pixel (and its
    guides), what ``on_tile`` sees.  tiles: the frame's tiles (y0, y1, x0, x1)."""

    def __init__(self, settings, tiles, image: np.ndarray, guides: bool,
                 passes: bool = False):
        self.settings = settings
        self.passes = passes
        self.tiles = list(tiles)
        self.image = image
        height, width = image.shape[:2]
        channels = SUM_CHANNELS + (GUIDE_SUM_CHANNELS if guides else 0)
        # float32: a pixel's sums of up to thousands of samples keep 6-7 digits, far more
        # than the 8-bit or half-float outputs they become.
        self.totals = np.zeros((height, width, channels), np.float32)
        self.live = np.ones((height, width), bool)
        self.adaptive = settings.noise_threshold > 0
        first = min_samples(settings) if self.adaptive else 1
        self.sizes = pass_sizes(settings.samples, first)
        self.started = time.monotonic()
        self.done_samples = 0
        self.passes_made = 0
        self.outstanding = 0      # jobs of the current pass not yet landed

    @property
    def channels(self) -> int:
        return self.totals.shape[2]

    def pass_complete(self) -> bool:
        return self.outstanding == 0

    def out_of_time(self) -> bool:
        limit = self.settings.time_limit
        return limit > 0 and time.monotonic() - self.started >= limit

    def next_pass(self) -> list:
        """The next pass's jobs ([] when the frame is done: every sample taken, every pixel
        converged, or the time limit reached)."""
        if self.passes_made:
            self._settle()
        if self.passes_made >= len(self.sizes) or (self.passes_made and self.out_of_time()):
            return []
        first = self.done_samples
        last = first + self.sizes[self.passes_made]
        self.passes_made += 1
        self.done_samples = last
        jobs = []
        for y0, y1, x0, x1 in self.tiles:
            live = self.live[y0:y1, x0:x1]
            if not live.any():
                continue
            packed = None if live.all() else np.packbits(live.ravel()).tobytes()
            jobs.append(TileJob(y0, y1, x0, x1, first, last, packed, self.passes))
        self.outstanding = len(jobs)
        if not jobs:
            return self.next_pass() if self.passes_made < len(self.sizes) else []
        return jobs

    def _settle(self) -> None:
        """After a pass: the pixels that converged take no more samples."""
        if not self.adaptive:
            return
        totals = self.totals[self.live]
        count = totals[:, 7]
        settled = converged(totals[:, 0:3].T, totals[:, 3:6].T, np.maximum(count, 1),
                            self.settings.noise_threshold)
        rows = np.flatnonzero(self.live.ravel())
        flat = self.live.reshape(-1)
        flat[rows[settled]] = False

    def land(self, job: TileJob, sums: np.ndarray) -> np.ndarray:
        """Add a job's sums (h, w, channels) into the totals; the tile's view of the image,
        refreshed with its pixels' new means.  The sums are rounded to float32 first, as
        they travel from worker processes and clusters, so that the image does not depend
        on where a tile ran (rounding twice is not rounding once)."""
        self.outstanding -= 1
        y0, y1, x0, x1 = job[:4]
        totals = self.totals[y0:y1, x0:x1]
        totals += np.asarray(sums, np.float32).astype(np.float64)
        count = np.maximum(totals[..., 7:8], 1)
        view = self.image[y0:y1, x0:x1]
        view[..., 0:3] = totals[..., 0:3] / count
        view[..., 3:4] = totals[..., 6:7] / count
        if self.channels > SUM_CHANNELS:
            view[..., 4:] = totals[..., SUM_CHANNELS:] / count
        return view

    @property
    def samples_taken(self) -> int:
        return self.done_samples
