"""The bench report's fitted curve exponents (``bench.report.curve_exponents``)."""

from types import SimpleNamespace

from bench.report import curve_exponents
from bench.suite import CurvePoint


def _points(contender, counts, seconds, tiles):
    return [CurvePoint("cost-sphere-sets", contender, 640, 360, count, s, 3, None, 1, t)
            for count, s, t in zip(counts, seconds, tiles)]


def test_exponents_of_the_whole_render_and_of_the_tiles_alone():
    counts = [10 ** k for k in range(7)]
    # Whole renders growing as count^0.3 (a linear build on top of the tracing), tiles as
    # count^0.05: each fit must recover its own exponent, over all points and the last decade.
    glint = _points("glint", counts, [0.1 * c ** 0.3 for c in counts],
                    [0.2 * c ** 0.05 for c in counts])
    baseline = _points("baseline", counts, [0.01 * c for c in counts], [None] * len(counts))
    lines = curve_exponents(SimpleNamespace(curve_points=glint + baseline), "cost-sphere-sets")
    assert ("- glint at 640x360: time ~ spheres^k with k = 0.30 over 1 to 1,000,000, "
            "0.30 from 100,000") in lines
    assert ("- glint at 640x360 (tiles alone): time ~ spheres^k with k = 0.05 over 1 to "
            "1,000,000, 0.05 from 100,000") in lines
    # The baseline has no tiles: one line, of its whole render.
    assert [line for line in lines if line.startswith("- baseline")] == [
        "- baseline at 640x360: time ~ spheres^k with k = 1.00 over 1 to 1,000,000, "
        "1.00 from 100,000"]


def test_the_time_splits_into_rays_and_the_cost_of_each():
    """More spheres cover more of the frame (rays a pixel 1 -> 3) while each ray's cost grows
    as count^0.1: the per-ray line must recover 0.1 from the render's time (not the time's
    own exponent, nor the tiles' thread-summed seconds), and list the tests a ray at each
    point."""
    counts = [10 ** k for k in range(4)]
    rays = [640 * 360 * (1 + 2 * k / 3) for k in range(4)]
    seconds = [r * 1e-6 * c ** 0.1 for r, c in zip(rays, counts)]
    glint = [CurvePoint("cost-sphere-sets", "glint", 640, 360, c, s, 3, None, 1, 3 * s,
                        rays=int(r), tests=int(r * (5 + 10 * k)))
             for k, (c, r, s) in enumerate(zip(counts, rays, seconds))]
    lines = curve_exponents(SimpleNamespace(curve_points=glint), "cost-sphere-sets")
    [line] = [line for line in lines if "per traced ray" in line]
    assert line.startswith("- glint at 640x360, per traced ray (1.00-3.00 rays a pixel): the "
                           "render's time a ray ~ spheres^k with k = 0.10 over 1 to 1,000 "
                           "(1.00 to 2.00 us)")
    assert line.endswith("tests a ray: 5.0 at 1, 15.0 at 10, 25.0 at 100, 35.0 at 1,000")
