"""Spheres: the ray/sphere kernels, shape-generic, and the scene's spheres as a shape that
answers its own batch tests (``Spheres``).

Vectors are (3, ...) arrays (``core.vectors``): a kernel broadcasts rays against spheres in
whatever layout the caller gives, (3, k, n) for k spheres by n rays or (3, E) for E explicit
pairs, and returns the pair roots ``(t_near, t_far, valid)`` in the broadcast shape: the two
distances along the (unit) ray where it crosses the sphere, and whether it crosses at all
(discriminant > 0, strictly, so tangent rays miss as in the article).  Callers pick what
they need through the hit rules (``rules``): the nearest hit, or whether a segment is blocked.

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

``textbook=True`` computes the article's textbook form instead (b = 2 d.(o - c),
c = |o - c|^2 - r^2, delta = b^2 - 4c), so that its rounding, and the reference image, are
reproduced; a test shows the stable kernels give the same reference image within 1e-9.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..arrays import SphereArrays
from ..vectors import dot, length, take

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


def offset_roots(f, rays, radii, *, textbook=False):
    """Roots for rays with their own origins, any broadcast shape: f = origins - centres and
    rays (unit directions) are (3, ...) arrays, radii (...).  Returns arrays of the broadcast
    shape (...)."""
    if textbook:
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


def origin_roots(f, c_prime, article_c, radii, rays, *, textbook=False):
    """Roots for rays from one origin, any broadcast shape: f = origin - centres (3, ...) and
    c_prime, article_c, radii (...) as ``OriginTerms`` gives them (float64), rays (3, ...) unit
    directions in the render precision."""
    dtype = rays.dtype
    f = f.astype(dtype, copy=False)     # (read, never written)
    if textbook:
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


class FewSpheres:
    """Every ray of a batch against each of k candidate spheres in turn, one (n,) row at a
    time: the flat culling's path for batches culled to a few spheres
    (``GeometryPolicy.dense_candidates``).

    The same roots as ``origin_roots`` / ``offset_roots`` (every product and sum in the same
    order, so the same values), without their (k, n) temporaries: a sphere's terms are
    scalars, so each step is one pass over a row, written into reused buffers, and the
    nearest hit is kept as a running minimum (no ``argmin`` over a strided axis).  Only what
    the caller asks for is formed: the article's nearest hit needs only the near root (it
    needs both roots > 0, and the far root is never below the near one), its shadow test
    only the far root.

    origins: (3, 1) with ``terms`` (``OriginTerms``) when every ray leaves one point, else
    (3, n); directions (3, n) unit, in the render precision; centers (N, 3) and radii (N,)
    float64.  textbook: the article's root formula, else the stable one; rules: the hit rules
    (``rules``), which read the rows' terms.
    """

    def __init__(self, centers, radii, origins, directions, terms=None, *, textbook: bool,
                 rules):
        self.dtype = directions.dtype
        self.directions = directions
        self.textbook = textbook
        self.rules = rules
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

    def roots(self, b, disc, c):
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
        t, better = self.rules.few_nearest(self, b, disc, c, t_min)
        if bounded:
            better &= t < t_max
        better &= t < best_t
        if exclude is not None:
            better &= exclude != gid
        np.copyto(best_t, t, where=better)
        np.copyto(best, gid, where=better)

    def blocked(self, spheres, low, high, exclude, ids, blocked):
        """blocked (n,) |= whether a candidate sphere blocks each segment (low, high) under
        the hit rules; ``exclude`` as in ``nearest``."""
        with np.errstate(invalid="ignore", divide="ignore"):
            for sphere in spheres:
                self._blocked_one(sphere, low, high, exclude, ids, blocked)

    def _blocked_one(self, sphere, low, high, exclude, ids, blocked):
        gid = sphere if ids is None else ids[sphere]
        b, disc, c = self._terms(sphere)
        hit = self.rules.few_blocked(self, b, disc, c, low, high)
        hit &= disc > 0
        if exclude is not None:
            hit &= exclude != gid
        blocked |= hit


class Spheres:
    """The scene's spheres as a shape: their arrays (``core.arrays.SphereArrays``, float64)
    and their centres and radii in the render precision ``dtype``, answering the batch tests
    of (ray, sphere) pairs that the accelerators hand them: by global id (``pair_roots``,
    ``pairs_nearest``, ``pairs_blocked``), or by slot of a table of spheres laid out in an
    accelerator's order (``by_slot``: a tree's leaves), whose pairs read short stretches of
    the table instead of scattered elements of scene-long arrays.  textbook: the article's
    root formula (``ROOT_FORMULAS``), else the stable one."""

    def __init__(self, arrays: SphereArrays, dtype, textbook: bool):
        self.arrays = arrays
        self.dtype = np.dtype(dtype)
        self.textbook = textbook
        self.count = len(arrays)
        self.centers_t = np.ascontiguousarray(arrays.centers.T, self.dtype)
        self.radii = np.ascontiguousarray(arrays.radii, self.dtype)
        self.material = arrays.material

    def boxes(self, ids):
        """(low, high) (3, k) float64 bounding boxes of spheres ``ids`` (k,) (None: all)."""
        c = self.arrays.centers.T if ids is None else self.arrays.centers[ids].T
        r = self.arrays.radii if ids is None else self.arrays.radii[ids]
        return np.subtract(c, r, out=np.empty(c.shape)), np.add(c, r, out=np.empty(c.shape))

    def pair_roots(self, rays, r, sphere):
        """(t_near, t_far, valid) (E,) of pairs (ray r, sphere) of a batch (``RayBatch``),
        with the batch's shared terms when it has them for every sphere."""
        directions = take(rays.directions, r)
        terms = rays.shared.tree_terms if rays.shared is not None else None
        if terms is not None:
            return origin_roots(take(terms.rows, sphere), terms.c_prime.take(sphere),
                                terms.article_c.take(sphere), self.arrays.radii.take(sphere),
                                directions, textbook=self.textbook)
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        return offset_roots(origins - take(self.centers_t, sphere), directions,
                            self.radii[sphere], textbook=self.textbook)

    def pairs_nearest(self, rays, r, sphere, t_min, limit, rules):
        """(E,) the hit distance (inf: none) of pairs (ray r, sphere) under the hit rules,
        beyond the rays' t_min (E,) and nearer than ``limit`` (E,)."""
        d = rules.first_hit(*self.pair_roots(rays, r, sphere), t_min)
        return np.where(d < limit, d, np.inf)

    def pairs_blocked(self, rays, r, sphere, low, high, rules):
        """(E,) whether pairs (ray r, sphere) are blocked: a root within (low, high) (n,) of
        the ray (``HitRules.blocks``).  With the stable roots and no shared terms, the roots
        are computed only for the pairs whose ray meets the sphere (most of a leaf's miss):
        the same flags, 4-5 % faster on the occlusion rays of dense sphere fields."""
        terms = rays.shared.tree_terms if rays.shared is not None else None
        if terms is not None or self.textbook:
            t_near, t_far, valid = self.pair_roots(rays, r, sphere)
            return valid & rules.blocks(t_near, t_far, low[r], high[r])
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        f = origins - take(self.centers_t, sphere)
        radii = self.radii.take(sphere)
        b, disc = offset_discriminants(f, take(rays.directions, r), radii)
        blocked = disc > 0
        meet = np.flatnonzero(blocked)
        t_near, t_far = offset_press_roots(take(f, meet), radii.take(meet), b.take(meet),
                                           disc.take(meet))
        rows = r.take(meet)
        blocked[meet] = rules.blocks(t_near, t_far, low.take(rows), high.take(rows))
        return blocked

    # ---- by slot ------------------------------------------------------------------------

    def by_slot(self, ids):
        """(x, y, z, radii) (S,) the spheres of slots ``ids`` (S,) (global ids, -1: an empty
        slot) in the render precision, NaN in an empty slot: a table for the slot kernels
        (about 40 bytes a sphere in float64, 24 in float32)."""
        pad = ids < 0
        safe = np.where(pad, 0, ids)
        columns = [self.centers_t[k].take(safe) for k in range(3)]
        columns.append(self.radii.take(safe))
        for column in columns:
            column[pad] = np.nan
        return tuple(columns)

    def _slot_offsets(self, rays, r, slots, table, stats):
        """(3, k) each pair's ray origin less its sphere's centre, for pairs (ray ``r``, slot
        ``slots``) (k,) of a table (``by_slot``: (x, y, z, radii, ids)); counts the k sphere
        tests."""
        if stats is not None:
            stats.sphere_tests += len(slots)
        origins = rays.origins if rays.origins.shape[1] == 1 else take(rays.origins, r)
        f = np.empty((3, len(slots)), np.result_type(origins.dtype, self.dtype))
        for k, column in enumerate(table[:3]):
            np.subtract(origins[k], column.take(slots), out=f[k])
        return f

    def slots_nearest(self, rays, r, slots, table, t_min, limit, rules, stats):
        """(E,) ``pairs_nearest`` of pairs (ray r, slot) of a table (``_slot_offsets``):
        the same operations on the same values, so the same distances; t_min, limit (E,)."""
        f = self._slot_offsets(rays, r, slots, table, stats)
        roots = offset_roots(f, take(rays.directions, r), table[3].take(slots),
                             textbook=self.textbook)
        d = rules.first_hit(*roots, t_min)
        return np.where(d < limit.astype(self.dtype), d, np.inf).astype(self.dtype, copy=False)

    def slots_blocked(self, rays, r, slots, table, low, high, rules, stats):
        """The rays (k,) of pairs (ray r, slot) (E,) of a table (``_slot_offsets``; ids None:
        the slots are the sphere ids themselves) whose sphere blocks them, with the stable
        roots and no shared terms (``pairs_blocked``: the same flags), less the pairs of the
        sphere each ray excludes (``RayBatch.exclude``), which are dropped before their
        roots (its own slot's box holds the ray's origin: 22 % of the pairs in dense
        fields)."""
        ids = table[4]
        if rays.exclude is not None:
            other = np.flatnonzero((slots if ids is None else ids.take(slots))
                                   != rays.exclude.take(r))
            r, slots = r.take(other), slots.take(other)
        f = self._slot_offsets(rays, r, slots, table, stats)
        radius = table[3].take(slots)
        b, disc = offset_discriminants(f, take(rays.directions, r), radius)
        meet = np.flatnonzero(disc > 0)
        t_near, t_far = offset_press_roots(take(f, meet), radius.take(meet), b.take(meet),
                                           disc.take(meet))
        met = r.take(meet)
        blocked = rules.blocks(t_near, t_far, low.take(met), high.take(met))
        return met[blocked]
