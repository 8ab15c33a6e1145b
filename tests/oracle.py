"""An independent ray/sphere oracle in 60-digit decimal arithmetic (not the code under test).

``exact_hit(origin, direction, center, radius)`` returns the distance to the first crossing
in front of the origin (t > 0) as a Decimal, or None for a miss or a tangent ray.  The
direction is used as given (normalised here in 60 digits), so the oracle answers for the
exact float inputs the tracer saw.
"""

from __future__ import annotations

from decimal import Decimal, getcontext

getcontext().prec = 60


def _dec(values):
    return [Decimal(float(v)) for v in values]


def exact_roots(origin, direction, center, radius):
    """(t_near, t_far) as Decimals along the normalised direction, or None if disc <= 0."""
    o, d, c = _dec(origin), _dec(direction), _dec(center)
    r = Decimal(float(radius))
    norm = sum(x * x for x in d).sqrt()
    d = [x / norm for x in d]
    f = [a - b for a, b in zip(o, c)]
    b = sum(x * y for x, y in zip(f, d))
    disc = b * b - (sum(x * x for x in f) - r * r)
    if disc <= 0:
        return None
    root = disc.sqrt()
    return -b - root, -b + root


def exact_hit(origin, direction, center, radius, *, from_inside=True):
    """First crossing with t > 0 (the far one if the origin is inside and from_inside)."""
    roots = exact_roots(origin, direction, center, radius)
    if roots is None:
        return None
    near, far = roots
    if near > 0:
        return near
    if far > 0 and from_inside:
        return far
    return None
