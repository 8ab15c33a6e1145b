"""The Whitted integrator at glass: reflected and refracted rays are both followed while a
bounce stays within ``core.trace.BRANCH_BUDGET`` rays a camera ray, and one of them, chosen
by weight and reweighted, beyond it; so nested glass costs time and memory in proportion to
the depth, not 2^depth, and a deep render cancels between bounces."""

from __future__ import annotations

import threading
import time
import tracemalloc

import numpy as np
import pytest

import core
from core import trace
from core.settings import RenderSettings

from bench.nested_glass import nested_glass_scene


def whitted(depth: int, samples: int = 1, threads: int = 1) -> RenderSettings:
    return RenderSettings(integrator="whitted", max_depth=depth, samples=samples,
                          anti_aliasing="fixed" if samples > 1 else "off", threads=threads)


def test_a_glass_ball_at_the_default_depth_splits_exactly_as_before(monkeypatch):
    scene = nested_glass_scene(32, 18, layers=1)
    budgeted = core.render(scene, whitted(3)).image
    monkeypatch.setattr(trace, "BRANCH_BUDGET", np.inf)
    assert np.array_equal(budgeted, core.render(scene, whitted(3)).image)


def test_nested_glass_grows_with_the_depth_not_its_power_of_two():
    scene = nested_glass_scene(24, 14, layers=5)
    rays, peaks = {}, {}
    for depth in (16, 64):
        tracemalloc.start()
        try:
            rays[depth] = core.render(scene, whitted(depth)).stats.reflection_rays
            peaks[depth] = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    pixels = 24 * 14
    # At most BRANCH_BUDGET rays a camera ray each bounce (2^16 a pixel without it).
    assert rays[64] <= trace.BRANCH_BUDGET * pixels * 64
    assert rays[64] < 5 * rays[16]
    assert peaks[64] < 1.5 * peaks[16]


def test_choosing_one_branch_keeps_the_image_splitting_gives(monkeypatch):
    # Depth 8 splits up to 2^7 rays a camera ray; the budget's choice is unbiased, so the
    # frame's mean and its glass's mean agree within the choice's noise (16 samples a pixel).
    scene = nested_glass_scene(32, 18, layers=3)
    chosen = core.render(scene, whitted(8, samples=16)).image[..., :3]
    monkeypatch.setattr(trace, "BRANCH_BUDGET", np.inf)
    split = core.render(scene, whitted(8, samples=16)).image[..., :3]
    assert not np.array_equal(chosen, split)     # the budget was reached
    glass = (slice(3, 15), slice(10, 22))
    assert chosen.mean() == pytest.approx(split.mean(), rel=0.01)
    assert chosen[glass].mean() == pytest.approx(split[glass].mean(), rel=0.03)
    # Per pixel, the difference is noise around zero, not a bias.
    assert abs((chosen - split)[glass].mean()) < 0.25 * np.abs(chosen - split)[glass].mean()


@pytest.mark.parametrize("threads", [1, 2])
def test_a_deep_whitted_render_cancels_between_bounces(threads):
    scene = nested_glass_scene(64, 36, layers=5)
    asked_at = []
    timer = threading.Timer(0.5, lambda: asked_at.append(time.perf_counter()))
    timer.start()
    try:
        with pytest.raises(core.RenderCancelled):
            core.render(scene, whitted(256, samples=64, threads=threads),
                        should_cancel=lambda: bool(asked_at))
        # A generous bound (the machine may be shared); a bounce of this tile takes ~0.05 s.
        assert time.perf_counter() - asked_at[0] < 5.0
    finally:
        timer.cancel()
