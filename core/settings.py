"""How to render a scene: ``RenderSettings``, validated on construction as every part of a
scene is (``core.scene``; the choices each field takes: ``core.choices``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .choices import (ANTI_ALIASING, FILMS, INTEGRATORS, PARALLELISM, PIXEL_FILTERS,
                      PRECISIONS, SEMANTICS)
from .validation import (MAX_DEPTH, MAX_FILTER_WIDTH, MAX_LIGHT_SAMPLES, MAX_SAMPLES,
                         MAX_THREADS, MAX_TILE_SIZE, SceneError, check_address, value_text,
                         _choice, _count, _non_negative, _positive, _set)


@dataclass(frozen=True)
class RenderSettings:
    """How to render.

    semantics: 'article' keeps every quirk of the article; 'default' fixes them (see
        ``core.shading`` and the README for the list).
    precision: 'float64', 'float32', or 'auto' (``core.precision.choose_precision`` picks
        float32 only when the scene's ratio of size to smallest feature allows it).
    max_depth: number of bounces (the primary hit counts as the first).
    anti_aliasing: 'off' (one ray through each pixel centre), 'fixed' (``samples`` stratified
        rays in every pixel), 'adaptive' (one ray per pixel, then ``samples`` rays in the pixels
        whose neighbours hit a different sphere or differ in colour).
    samples: rays per supersampled pixel.
    light_samples: shadow rays per light with radius > 0 (soft shadows).
    world_samples: shadow rays per point towards the world (a k x k grid of at least this
        many; default semantics, scenes with several spheres and a world that shines): the
        share of the sky a point sees scales the world's diffuse light (contact shadows);
        0 treats the world as unoccluded.
    contribution_cutoff: a path stops once nothing it could still add exceeds this (a fraction
        of full white); 1e-6 keeps results float64-accurate to the 8-bit output many times over.
    tile_size: tiles are tile_size x tile_size pixels; memory per tile is bounded by it.
    threads: how many tiles render at once (None: one per core), on threads or worker
        processes as ``parallelism`` says.  Results never depend on it.
    parallelism: 'auto' (the default), 'threads' (a thread pool in this process) or
        'processes' (worker processes, ``core.workers``).  Processes render only renders of
        more than one tile and at least ``core.workers.MIN_PIXELS`` pixels (smaller ones
        stay in this process, where a worker's start-up would cost more than it gains), and
        fall back to threads where processes cannot start (``RenderResult.fallback`` says
        why).  'auto' takes processes where 'processes' would and ``threads`` is more than
        one (one worker only moves the work), except in a process that renders once
        (``python -m core``, render.py for one frame), where a cold start must pay:
        workers already running, or ``core.workers.COLD_MIN_SAMPLES`` camera samples.
        Measured on 2 cores, two threads render the article's 1080p frame 0.91x as fast as
        one (the GIL), two warm processes 1.75x (README: "Worker processes and malloc
        settings").  Results never depend on it.
    cluster: '' (render on this machine, as ``parallelism`` says), or the address of a Dask
        scheduler ('tcp://HOST:PORT' or 'tls://HOST:PORT') whose workers render the tiles
        (``core.cluster``; needs ``dask[distributed]`` here and Glint's core on the workers).
        The image is the same bit for bit.
    film: the image's alpha and background (default semantics; ``core.choices.FILM_CHOICES``):
        'coverage' (the core's own image): the background where camera rays escape, alpha =
        1 - transparency, the share of the pixel's samples that escaped (directly or straight
        through Transparent BSDFs, weighted by what passed) or met a holdout; 'opaque'
        (Blender's Film > Transparent off): the same colours, alpha = 1 - the holdouts' share
        only; 'transparent' (Film > Transparent on): escaped camera rays add no background,
        alpha as for 'coverage'.  Article semantics: alpha is the coverage ('opaque': 1).
    """

    semantics: Literal["default", "article"] = "default"
    precision: Literal["auto", "float64", "float32"] = "auto"
    max_depth: int = 3
    anti_aliasing: Literal["off", "fixed", "adaptive"] = "off"
    samples: int = 16
    light_samples: int = 16
    world_samples: int = 9
    contribution_cutoff: float = 1e-6
    tile_size: int = 128
    threads: int | None = None
    parallelism: Literal["auto", "threads", "processes"] = "auto"
    film: Literal["coverage", "opaque", "transparent"] = "coverage"
    integrator: Literal["path", "whitted"] = "path"
    max_bounces: int = 12
    diffuse_bounces: int = 4
    glossy_bounces: int = 4
    transmission_bounces: int = 12
    transparent_bounces: int = 8
    clamp_direct: float = 0.0
    clamp_indirect: float = 10.0
    caustics_reflective: bool = True
    caustics_refractive: bool = True
    filter_glossy: float = 1.0
    noise_threshold: float = 0.0
    min_samples: int = 0
    time_limit: float = 0.0
    filter_type: Literal["BOX", "GAUSSIAN", "BLACKMAN_HARRIS"] = "BLACKMAN_HARRIS"
    filter_width: float = 1.5
    seed: int = 0
    guides: bool = False
    cluster: str = ""

    def __post_init__(self):
        _choice("settings.semantics", self.semantics, SEMANTICS)
        _choice("settings.precision", self.precision, PRECISIONS)
        _choice("settings.anti_aliasing", self.anti_aliasing, ANTI_ALIASING)
        _choice("settings.parallelism", self.parallelism, PARALLELISM)
        _set(self, "cluster", check_address("settings.cluster", self.cluster))
        _choice("settings.film", self.film, FILMS)
        _count("settings.max_depth", self.max_depth, maximum=MAX_DEPTH)
        _count("settings.samples", self.samples, maximum=MAX_SAMPLES)
        _count("settings.light_samples", self.light_samples, maximum=MAX_LIGHT_SAMPLES)
        _count("settings.world_samples", self.world_samples, minimum=0,
               maximum=MAX_LIGHT_SAMPLES)
        _count("settings.tile_size", self.tile_size, minimum=8, maximum=MAX_TILE_SIZE)
        if self.threads is not None:
            _count("settings.threads", self.threads, maximum=MAX_THREADS)
        _set(self, "contribution_cutoff",
             _non_negative("settings.contribution_cutoff", self.contribution_cutoff))
        _choice("settings.integrator", self.integrator, INTEGRATORS)
        _choice("settings.filter_type", self.filter_type, PIXEL_FILTERS)
        for name in ("max_bounces", "diffuse_bounces", "glossy_bounces",
                     "transmission_bounces", "transparent_bounces"):
            _count(f"settings.{name}", getattr(self, name), minimum=0, maximum=MAX_DEPTH)
        _count("settings.min_samples", self.min_samples, minimum=0, maximum=MAX_SAMPLES)
        _count("settings.seed", self.seed, minimum=0, maximum=2 ** 31 - 1)
        for name in ("clamp_direct", "clamp_indirect", "filter_glossy", "noise_threshold",
                     "time_limit"):
            _set(self, name, _non_negative(f"settings.{name}", getattr(self, name)))
        _set(self, "filter_width", _positive("settings.filter_width", self.filter_width))
        if self.filter_width > MAX_FILTER_WIDTH:
            raise SceneError(f"settings.filter_width must be at most {MAX_FILTER_WIDTH:g} "
                             f"pixels, got {value_text(self.filter_width)}")
        for name in ("caustics_reflective", "caustics_refractive", "guides"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise SceneError(f"settings.{name} must be True or False, got "
                                 f"{value_text(getattr(self, name))}")
            _set(self, name, bool(getattr(self, name)))
