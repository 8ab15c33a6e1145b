"""The shading points of a world program: rays escaping along their directions."""

from __future__ import annotations

from .points import ShadingPoints


def world_points(directions) -> ShadingPoints:
    """The shading points a world program runs on: rays escaping along unit ``directions``
    (3, n), seen as Cycles' background shader sees them (its P is the direction, its normal
    and incoming the direction reversed; Generated and Object coordinates the direction)."""
    towards = -directions
    direction = lambda: directions  # noqa: E731
    return ShadingPoints(directions, towards, towards, towards,
                         sources={"generated": direction, "object": direction})
