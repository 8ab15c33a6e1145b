"""The shading points of a world program: rays escaping along their directions."""

from __future__ import annotations

import numpy as np

from .points import ShadingPoints


def world_points(directions, ray=None) -> ShadingPoints:
    """The shading points a world program runs on: rays escaping along unit ``directions``
    (3, n), seen as Cycles' background shader sees them (its P is the direction, its normal
    and incoming the direction reversed; Generated and Object coordinates the direction).
    ray: the Light Path node's coordinates of those rays ({'ray_type': (n,) codes, depths},
    ``core.shader.input_nodes``), or None for camera rays."""
    towards = -directions
    direction = lambda: directions  # noqa: E731
    sources = {"generated": direction, "object": direction}
    sources.update(light_path_sources(ray))
    return ShadingPoints(directions, towards, towards, towards, sources=sources)


def light_path_sources(ray) -> dict:
    """Shading point sources for the Light Path node from ``ray`` ({coordinate name: (n,)
    values or a number}, or None)."""
    if not ray:
        return {}
    return {name: (lambda values=values: np.atleast_1d(values)[None, :])
            for name, values in ray.items()}
