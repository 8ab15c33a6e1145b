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
    """The article's (smaller, larger, valid) from b = 2 d.f and c = |f|^2 - r^2."""
    delta = b * b - 4.0 * c
    valid = delta > 0
    root = np.sqrt(np.where(valid, delta, 0))
    return (-b - root) / 2, (-b + root) / 2, valid


def offset_roots(f, rays, radii, *, article=False):
    """Roots for rays with their own origins, any broadcast shape: f = origins - centres and
    rays (unit directions) are (3, ...) arrays, radii (...).  Returns arrays of the broadcast
    shape (...)."""
    if article:
        return _textbook_roots(2.0 * dot(f, rays), dot(f, f) - radii ** 2)
    b = dot(f, rays)
    perp = f - b * rays
    disc = radii ** 2 - dot(perp, perp)
    f_len = length(f)
    t_near, t_far = _press_roots(b, (f_len - radii) * (f_len + radii), disc)
    return t_near, t_far, disc > 0


@dataclass(frozen=True)
class OriginTerms:
    """Per-sphere terms for rays leaving one origin, float64, each indexed by sphere.

    f: origin - centers (N, 3); c_prime: |f|^2 - r^2 (N,);
    article_c: the article's own ``norm(f) ** 2 - r ** 2`` (N,), with its rounding.
    """

    f: np.ndarray
    c_prime: np.ndarray
    article_c: np.ndarray

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
    f = f.astype(dtype)
    if article:
        return _textbook_roots(2.0 * dot(f, rays), article_c.astype(dtype))
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
