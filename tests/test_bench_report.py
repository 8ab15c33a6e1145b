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
