"""bench.rays counts every ray the geometry traces under its kind (camera, bounce, shadow),
as the render's own stats count them, and leaves the geometry as it found it."""

from __future__ import annotations

import core
from bench import rays
from bench.scenes import mesh_and_spheres_scene
from core.geometry import Aggregate


def test_rays_are_counted_by_kind_as_the_render_counts_them():
    scene = mesh_and_spheres_scene(spheres=60, grid=6, subdivisions=1, width=24, height=16)
    settings = core.RenderSettings(samples=2, threads=1)
    nearest, occluded = Aggregate.nearest, Aggregate.occluded
    best = rays.measure(scene, settings, repeats=1)
    assert (Aggregate.nearest, Aggregate.occluded) == (nearest, occluded)
    stats = core.render(scene, settings).stats
    assert best["camera"][0] == stats.camera_rays == 24 * 16 * 2
    assert best["bounce"][0] == stats.reflection_rays > 0
    assert best["shadow"][0] == stats.shadow_rays > 0
    assert sum(best[kind][2] for kind in rays.KINDS) == stats.node_tests > 0
    assert "us/ray" in rays.report("scene", best)
