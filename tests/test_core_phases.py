"""Per-phase timers (RayStats.seconds_*): nested as the phases are, summed over tiles and
workers, left out of stats equality.  (What they measure is the benchmark's business.)"""

import numpy as np
import pytest

import core
from core import workers
from core.rays import RayStats


@pytest.mark.parametrize("semantics", ["article", "default"])
def test_phases_nest_and_add_up_to_the_tiles(semantics):
    stats = core.render(core.article_scene(96, 64),
                        core.RenderSettings(semantics=semantics, tile_size=32, threads=1)).stats
    phases = stats.phases()
    assert list(phases) == ["camera rays", "nearest hits", "shadow rays", "shading",
                            "rest of bounces", "tile overhead"]
    assert all(seconds >= 0 for seconds in phases.values()), phases
    assert sum(phases.values()) == pytest.approx(stats.seconds_tiles)
    # Every phase ran: the article's scene has hits, shadows and reflections.
    assert stats.seconds_nearest > 0 and stats.seconds_shadows > 0 and stats.seconds_camera > 0
    assert stats.seconds_shadows <= stats.seconds_shading
    assert stats.seconds_nearest + stats.seconds_shading <= stats.seconds_bounces
    assert stats.seconds_camera + stats.seconds_bounces <= stats.seconds_tiles


def test_worker_timers_are_summed_in_the_parent(monkeypatch):
    monkeypatch.setattr(workers, "MIN_PIXELS", 0)
    result = core.render(core.article_scene(96, 64), core.RenderSettings(
        tile_size=32, threads=2, parallelism="processes"))
    assert result.parallelism == "processes"
    assert result.stats.seconds_tiles > 0 and result.stats.seconds_nearest > 0


def test_timers_do_not_take_part_in_equality():
    assert RayStats(camera_rays=3, seconds_tiles=1.0) == RayStats(camera_rays=3, seconds_tiles=2.0)
    assert RayStats(camera_rays=3) != RayStats(camera_rays=4)
    total = RayStats(seconds_nearest=0.25)
    total.add(RayStats(seconds_nearest=0.5, tiles=1))
    assert total.seconds_nearest == 0.75 and total.tiles == 1
