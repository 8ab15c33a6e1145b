"""Ray/sphere intersection kernels, shape-generic.

Vectors are (3, ...) arrays (``core.vectors``): a kernel broadcasts rays against spheres in
whatever layout the caller gives, (3, k, n) for k spheres by n rays or (3, E) for E explicit
pairs, and returns the pair roots ``(t_near, t_far, valid)`` in the broadcast shape: the two
distances along the (unit) ray where it crosses the sphere, and whether it crosses at all
(discriminant > 0, strictly, so tangent rays miss as in the article).  Callers pick what
they need: the nearest hit (``core.trace``) or whether a segment is blocked (``core.shading``).

Numerics (docs/article.md, "Numerics worth knowing").  With f = o - c and b' = f.d:

* the discriminant as ``r^2 - |f - b' d|^2`` (Haines et al., Ray Tracing Gems ch. 7): the
  squared distance from the centre to the ray's line, computed as a vector, does not cancel
  for a small sphere far away;
* the roots as ``q = -(b' + sign(b') sqrt(disc))``, then ``q`` and ``c'/q`` (Press et al.), so
  the near root of a huge sphere (the article's floor) is not a difference of nearly equal
  numbers;
* ``c' = |f|^2 - r^2`` as ``(|f| - r)(|f| + r)``.

When rays share an origin (camera rays of a perspective camera; shadow rays, which Glint
traces from the light towards the shaded points), f and c' are per sphere (``OriginTerms``),
computed once, c' in extended precision.  The discriminant is then ``b'^2 - c'``, whose error
is about eps * c' against a scale of r^2: accurate while c' <= CHEAP_DISCRIMINANT_RATIO * r^2
(spheres near the origin, or large); the rest (small and far) take the vector form.

``article=True`` computes the article's textbook form instead (b = 2 d.(o - c),
c = |o - c|^2 - r^2, delta = b^2 - 4c), so that its rounding, and the reference image, are
reproduced; a test shows the stable kernels give the same reference image within 1e-9.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .vectors import dot, length

#: Largest c' / r^2 for which ``b'^2 - c'`` is used (relative discriminant error ~ eps * ratio).
CHEAP_DISCRIMINANT_RATIO = {np.dtype(np.float64): 1e4, np.dtype(np.float32): 1e1}


def _press_roots(b, c_prime, disc):
    """(smaller, larger) roots of t^2 + 2 b t + c' = 0, given disc = b^2 - c'."""
    root = np.sqrt(np.maximum(disc, 0))
    q = -(b + np.copysign(root, b))
    with np.errstate(divide="ignore", invalid="ignore"):
        other = c_prime / q
    return np.minimum(q, other), np.maximum(q, other)


def _textbook_roots(b, c):
    """The article's (smaller, larger, valid) from b = 2 d.f and c = |f|^2 - r^2.
    (Halved by products with 0.5, which round as the article's division by 2 does, and
    with fewer temporaries.)"""
    delta = b * b
    delta -= 4.0 * c
    valid = delta > 0
    root = np.where(valid, delta, 0)
    np.sqrt(root, out=root)
    low = np.negative(b)
    high = low + root
    low -= root
    low *= 0.5
    high *= 0.5
    return low, high, valid


def offset_roots(f, rays, radii, *, article=False):
    """Roots for rays with their own origins, any broadcast shape: f = origins - centres and
    rays (unit directions) are (3, ...) arrays, radii (...).  Returns arrays of the broadcast
    shape (...)."""
    if article:
        return _textbook_roots(2.0 * dot(f, rays), dot(f, f) - radii ** 2)
    b, disc = offset_discriminants(f, rays, radii)
    t_near, t_far = offset_press_roots(f, radii, b, disc)
    return t_near, t_far, disc > 0


def offset_discriminants(f, rays, radii):
    """(b', disc) of ``offset_roots`` (its first half): a ray meets its sphere where
    disc > 0 (then offset_press_roots gives the roots)."""
    b = dot(f, rays)
    perp = f - b * rays
    return b, radii ** 2 - dot(perp, perp)


def offset_press_roots(f, radii, b, disc):
    """(t_near, t_far) of ``offset_roots`` from ``offset_discriminants``' b', disc, for pairs
    f, radii of the same shape (the second half: callers may keep only the pairs that meet)."""
    f_len = length(f)
    return _press_roots(b, (f_len - radii) * (f_len + radii), disc)


@dataclass(frozen=True)
class OriginTerms:
    """Per-sphere terms for rays leaving one origin, float64, each indexed by sphere.

    f: origin - centers (N, 3); c_prime: |f|^2 - r^2 (N,);
    article_c: the article's own ``norm(f) ** 2 - r ** 2`` (N,), with its rounding.
    """

    f: np.ndarray
    c_prime: np.ndarray
    article_c: np.ndarray

    @functools.cached_property
    def rows(self) -> np.ndarray:
        """(3, N) f as contiguous rows, for gathering pairs' columns (``vectors.take``)."""
        return np.ascontiguousarray(self.f.T)

    @classmethod
    def at(cls, origin, centers, radii) -> "OriginTerms":
        """Terms at ``origin`` (3,) for spheres (N, 3), (N,).  c' is formed in extended
        precision (np.longdouble, 64-bit mantissa on x86): it is per sphere, so this costs
        nothing per ray, and it keeps the floor's c' (|f|^2 ~ 8e7, c' ~ 3e4) exact to ~1e-16."""
        origin = np.asarray(origin, np.float64)
        f_wide = origin.astype(np.longdouble)[None, :] - centers.astype(np.longdouble)
        c_wide = (f_wide * f_wide).sum(axis=1) - radii.astype(np.longdouble) ** 2
        f = origin[None, :] - centers
        return cls(f, c_wide.astype(np.float64), np.linalg.norm(f, axis=1) ** 2 - radii ** 2)


def origin_roots(f, c_prime, article_c, radii, rays, *, article=False):
    """Roots for rays from one origin, any broadcast shape: f = origin - centres (3, ...) and
    c_prime, article_c, radii (...) as ``OriginTerms`` gives them (float64), rays (3, ...) unit
    directions in the render precision."""
    dtype = rays.dtype
    f = f.astype(dtype, copy=False)     # (read, never written)
    if article:
        return _textbook_roots(2.0 * dot(f, rays), article_c.astype(dtype, copy=False))
    b = dot(f, rays)
    c_cast = c_prime.astype(dtype)
    cheap = c_prime <= CHEAP_DISCRIMINANT_RATIO[np.dtype(dtype)] * radii * radii
    if cheap.all():
        disc = b * b - c_cast
    else:
        perp = f - b * rays
        disc = np.where(cheap, b * b - c_cast, (radii * radii).astype(dtype) - dot(perp, perp))
    t_near, t_far = _press_roots(b, c_cast, disc)
    return t_near, t_far, disc > 0


def first_hit_distance(t_near, t_far, valid, t_min, *, article=False):
    """Distance (k, n) of the hit each pair counts, inf where none.

    Article: a hit needs both roots > 0, and is the nearer one (a ray never hits a sphere it
    starts inside).  Default: the nearest root beyond t_min (so from inside, the far side).
    t_min: scalar or (n,).
    """
    if article:
        return np.where(valid & (t_near > 0) & (t_far > 0), t_near, np.inf)
    return np.where(valid & (t_near > t_min), t_near,
                    np.where(valid & (t_far > t_min), t_far, np.inf))


class FewSpheres:
    """Every ray of a batch against each of k candidate spheres in turn, one (n,) row at a
    time: the aggregate's path for bundles culled to a few spheres (``core.cull``'s
    ``DENSE_CANDIDATES``).

    The same roots as ``origin_roots`` / ``offset_roots`` (every product and sum in the same
    order, so the same values), without their (k, n) temporaries: a sphere's terms are
    scalars, so each step is one pass over a row, written into reused buffers, and the
    nearest hit is kept as a running minimum (no ``argmin`` over a strided axis).  Only what
    the caller asks for is formed: the article's nearest hit needs only the near root (it
    needs both roots > 0, and the far root is never below the near one), its shadow test
    only the far root.

    origins: (3, 1) with ``terms`` (``OriginTerms``) when every ray leaves one point, else
    (3, n); directions (3, n) unit, in the render precision; centers (N, 3) and radii (N,)
    float64.  textbook: the article's root formula, else the stable one; article: the
    article's hit rules (``first_hit_distance``), else the nearest root beyond t_min and
    any root inside a segment.
    """

    def __init__(self, centers, radii, origins, directions, terms=None, *, textbook: bool,
                 article: bool):
        self.dtype = directions.dtype
        self.directions = directions
        self.textbook = textbook
        self.article = article
        self.centers = centers
        self.radii = radii
        self.terms = terms
        self.origins = origins
        n = directions.shape[1]
        self.b = np.empty(n, self.dtype)
        self.scratch = np.empty(n, self.dtype)
        self.disc = np.empty(n, self.dtype)
        self.root = np.empty(n, self.dtype)
        self.f = None if terms is not None else np.empty((3, n), self.dtype)

    def _dot_f(self, f, out):
        """out = f . directions, f three scalars or (3, n) rows (the order of ``dot``)."""
        d, scratch = self.directions, self.scratch
        np.multiply(f[0], d[0], out=out)
        np.multiply(f[1], d[1], out=scratch)
        out += scratch
        np.multiply(f[2], d[2], out=scratch)
        out += scratch
        return out

    def _terms(self, sphere):
        """(b, disc, c) of one sphere in the article's textbook form (b = 2 f.d,
        disc = b^2 - 4c), or in the stable form (b = f.d, disc as ``origin_roots`` /
        ``offset_roots``, c = c'), where disc > 0 means the ray crosses the sphere."""
        cast = self.dtype.type
        b, disc, scratch = self.b, self.disc, self.scratch
        radius = cast(self.radii[sphere])
        if self.terms is not None:
            f = self.terms.f[sphere].astype(self.dtype)
            self._dot_f(f, b)
            if self.textbook:
                c = cast(self.terms.article_c[sphere])
                b *= cast(2.0)
                np.multiply(b, b, out=disc)
                disc -= cast(4.0) * c
                return b, disc, c
            c_prime, r = self.terms.c_prime[sphere], self.radii[sphere]
            c = cast(c_prime)
            if c_prime <= CHEAP_DISCRIMINANT_RATIO[self.dtype] * r * r:
                np.multiply(b, b, out=disc)
                disc -= c
                return b, disc, c
            fx = np.broadcast_to(f[:, None], (3, len(b)))
            squared = cast(r * r)     # origin_roots squares in float64
        else:
            fx = self.f
            center = self.centers[sphere].astype(self.dtype)
            for row in range(3):
                np.subtract(self.origins[row], center[row], out=fx[row])
            self._dot_f(fx, b)
            if self.textbook:
                c = dot(fx, fx)
                c -= radius * radius
                b *= cast(2.0)
                np.multiply(b, b, out=disc)
                disc -= cast(4.0) * c
                return b, disc, c
            # c' = (|f| - r)(|f| + r)
            size = dot(fx, fx)
            np.sqrt(size, out=size)
            c = size - radius
            size += radius
            c *= size
            squared = radius * radius   # offset_roots squares in the render precision
        # disc = r^2 - |f - b d|^2, the perpendicular squared distance as a vector.
        d = self.directions
        disc.fill(squared)
        for row in range(3):
            np.multiply(b, d[row], out=scratch)
            np.subtract(fx[row], scratch, out=scratch)
            scratch *= scratch
            if row == 0:
                perp = scratch.copy()
            else:
                perp += scratch
        disc -= perp
        return b, disc, c

    def _roots(self, b, disc, c):
        """(t_near, t_far) (n,) new arrays: Press et al.'s roots (``_press_roots``), or the
        textbook ones (``_textbook_roots``), from ``_terms``."""
        # NaN where disc < 0 (the callers run under errstate): no root is read where
        # disc <= 0, and every test of a NaN root fails.
        root = np.sqrt(disc, out=self.root)
        if self.textbook:
            t_near = np.subtract(-b, root)
            t_near *= self.dtype.type(0.5)
            t_far = np.subtract(root, b)
            t_far *= self.dtype.type(0.5)
            return t_near, t_far
        q = np.copysign(root, b)
        q += b
        np.negative(q, out=q)
        other = np.divide(c, q)   # (the callers ignore division by zero)
        return np.minimum(q, other), np.maximum(q, other, out=other)

    def nearest(self, spheres, t_min, t_max, exclude, ids, best_t, best):
        """Improve best_t, best (n,) in place with the candidate ``spheres`` (k,) (indices into
        centers; ``ids`` maps them to global ids, None: the same), hits in (t_min, t_max)
        (scalars or (n,)), a ray ignoring its ``exclude`` (n,) (-1: none; or None).  A hit
        must be strictly nearer: on ties the earlier sphere keeps it (scene order)."""
        bounded = np.ndim(t_max) or np.isfinite(t_max)
        with np.errstate(invalid="ignore", divide="ignore"):   # once: it costs a few us
            for sphere in spheres:
                self._nearest_one(sphere, t_min, t_max, bounded, exclude, ids, best_t, best)

    def _nearest_one(self, sphere, t_min, t_max, bounded, exclude, ids, best_t, best):
        gid = sphere if ids is None else ids[sphere]
        b, disc, c = self._terms(sphere)
        if self.article and self.textbook:
            # t_near = (-b - sqrt(disc)) / 2: NaN where disc < 0, which no test passes.
            t = np.sqrt(disc, out=self.root)
            t += b
            t *= self.dtype.type(-0.5)
            better = t > 0
            better &= disc > 0
        elif self.article:
            t, t_far = self._roots(b, disc, c)
            better = t > 0
            better &= t_far > 0
            better &= disc > 0
        else:
            # The near root if beyond t_min, else the far one (never below the near one).
            t_near, t_far = self._roots(b, disc, c)
            better = t_far > t_min
            better &= disc > 0
            t = np.where(t_near > t_min, t_near, t_far)
        if bounded:
            better &= t < t_max
        better &= t < best_t
        if exclude is not None:
            better &= exclude != gid
        np.copyto(best_t, t, where=better)
        np.copyto(best, gid, where=better)

    def blocked(self, spheres, low, high, exclude, ids, blocked):
        """blocked (n,) |= whether a candidate sphere blocks each segment: the article's far
        root in (low, high), else either root there; ``exclude`` as in ``nearest``."""
        with np.errstate(invalid="ignore", divide="ignore"):
            for sphere in spheres:
                self._blocked_one(sphere, low, high, exclude, ids, blocked)

    def _blocked_one(self, sphere, low, high, exclude, ids, blocked):
        gid = sphere if ids is None else ids[sphere]
        b, disc, c = self._terms(sphere)
        if self.article:
            if self.textbook:   # t_far = (-b + sqrt(disc)) / 2
                t = np.sqrt(disc, out=self.root)
                t -= b
                t *= self.dtype.type(0.5)
            else:
                t = self._roots(b, disc, c)[1]
            hit = t < high
            hit &= t > low
        else:
            t_near, t_far = self._roots(b, disc, c)
            hit = t_near > low
            hit &= t_near < high
            far = t_far > low
            far &= t_far < high
            hit |= far
        hit &= disc > 0
        if exclude is not None:
            hit &= exclude != gid
        blocked |= hit
