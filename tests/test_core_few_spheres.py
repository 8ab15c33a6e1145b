"""The few-sphere kernels (core.geometry.spheres.FewSpheres, the flat culling's path for bundles
culled to a handful of spheres) against the (k, n) broadcast kernels they replace: the same roots
in the same order, so the same nearest hits and the same blocked segments, bit for bit, for
every root formula and hit rule, shared and own origins, float64 and float32."""

from __future__ import annotations

import numpy as np
import pytest

from core.geometry.rules import ARTICLE_RULES, HIT_RULES
from core.geometry.spheres import FewSpheres, OriginTerms, offset_roots, origin_roots


def _scene(dtype, shared):
    rng = np.random.default_rng(7)
    centers = np.vstack([rng.uniform(-2, 2, (5, 3)), [[0.0, -9000.0, 0.0]],
                         [[40.0, 0.0, -300.0]]])     # a floor; a far, small sphere
    radii = np.r_[rng.uniform(0.1, 0.8, 5), 8999.3, 0.05]
    n = 4000
    directions = rng.normal(size=(3, n))
    directions[:, :200] = (centers[6] - [0.1, 0.2, 0.3])[:, None] + rng.normal(0, 0.02, (3, 200))
    directions /= np.linalg.norm(directions, axis=0)
    if shared:
        origins = np.array([[0.1], [0.2], [0.3]])
    else:
        origins = rng.uniform(-1.5, 1.5, (3, n))
        origins[:, :100] = (centers[0] + radii[0] * 1.0000001 * directions[:, :100].T).T
    terms = OriginTerms.at(origins[:, 0], centers, radii) if shared else None
    return centers, radii, origins.astype(dtype), directions.astype(dtype), terms, rng


def _broadcast_roots(centers, radii, origins, directions, terms, textbook, spheres):
    if terms is not None:
        return origin_roots(terms.f[spheres].T[:, :, None], terms.c_prime[spheres][:, None],
                            terms.article_c[spheres][:, None], radii[spheres][:, None],
                            directions[:, None, :], textbook=textbook)
    dtype = directions.dtype
    return offset_roots(origins[:, None, :] - centers[spheres].T.astype(dtype)[:, :, None],
                        directions[:, None, :], radii[spheres].astype(dtype)[:, None],
                        textbook=textbook)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shared", [True, False])
@pytest.mark.parametrize("textbook, article", [(True, True), (False, True), (True, False),
                                               (False, False)])
def test_few_spheres_match_the_broadcast_kernels(dtype, shared, textbook, article):
    centers, radii, origins, directions, terms, rng = _scene(dtype, shared)
    n = directions.shape[1]
    spheres = np.array([0, 2, 3, 5, 6])
    ids = np.arange(10, 17)   # global ids of the local spheres
    t_min = 0.0 if article else rng.uniform(0, 0.5, n).astype(dtype)
    t_max = rng.uniform(1, 50, n)
    t_max[::3] = np.inf
    exclude = None if article else rng.choice(np.r_[-1, ids], n)

    t_near, t_far, valid = _broadcast_roots(centers, radii, origins, directions, terms,
                                            textbook, spheres)
    rules = ARTICLE_RULES if article else HIT_RULES
    with np.errstate(invalid="ignore"):
        distances = rules.first_hit(t_near, t_far, valid, t_min)
    distances[~(distances < t_max)] = np.inf
    if exclude is not None:
        distances[ids[spheres][:, None] == exclude[None, :]] = np.inf
    row = np.argmin(distances, axis=0)
    expected_t = distances[row, np.arange(n)]
    expected = np.where(np.isfinite(expected_t), ids[spheres][row], -1)

    few = FewSpheres(centers, radii, origins, directions, terms, textbook=textbook,
                     rules=rules)
    best_t, best = np.full(n, np.inf, dtype), np.full(n, -1, np.intp)
    few.nearest(spheres, t_min, t_max, exclude, ids, best_t, best)
    assert (best >= 0).sum() > n // 10        # the case hits something
    np.testing.assert_array_equal(best, expected)
    np.testing.assert_array_equal(best_t, expected_t)

    low = rng.uniform(0, 2, n).astype(dtype)
    high = (low + rng.uniform(0, 30, n)).astype(dtype)
    with np.errstate(invalid="ignore"):
        if article:
            hit = valid & (t_far < high) & (t_far > low)
        else:
            hit = valid & (((t_near > low) & (t_near < high)) | ((t_far > low) & (t_far < high)))
    if exclude is not None:
        hit &= ids[spheres][:, None] != exclude[None, :]
    blocked = np.zeros(n, bool)
    few.blocked(spheres, low, high, exclude, ids, blocked)
    assert 0 < blocked.sum() < n
    np.testing.assert_array_equal(blocked, hit.any(axis=0))
