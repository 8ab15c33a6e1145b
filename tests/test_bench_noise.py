"""bench.noise: noise against a reference in 8-bit steps, the time at equal noise, and one tiny
run of both engines through F12."""

import math
import os

import numpy as np
import pytest

from bench import noise, scale

pytestmark = pytest.mark.slow  # every test here takes seconds (child processes)


def test_noise_is_the_rms_of_the_display_difference_in_8_bit_steps():
    rng = np.random.default_rng(1)
    reference = np.zeros((32, 48, 4))
    image = reference.copy()
    # Grain of +-2 steps in a checkerboard: 2 steps RMS per pixel, nothing left in 8 x 8 boxes.
    grain = np.where((np.indices((32, 48)).sum(axis=0) % 2) == 0, 2.0, -2.0) / 255
    image[..., :3] = grain[..., None]
    image[..., 3] = rng.uniform(size=(32, 48))         # alpha is not compared
    measured = noise.noise(image, reference)
    assert measured["rms"] == pytest.approx(2.0)
    assert measured["box_rms"] == pytest.approx(0.0, abs=1e-9)
    # An offset of 3 steps in the green channel alone: sqrt(3^2 / 3) per pixel and per box.
    image[..., :3] = 0
    image[..., 1] = 3 / 255
    measured = noise.noise(image, reference)
    assert measured["rms"] == pytest.approx(math.sqrt(3)) == measured["box_rms"]


def test_equal_noise_interpolates_in_log_log_and_flags_extrapolation():
    # A path tracer's noise ~ 1/sqrt(samples), its time ~ samples: exact in log-log.
    points = [(n, 0.5 * n, 40 / math.sqrt(n)) for n in (1, 4, 16)]
    inside = noise.equal_noise(40 / math.sqrt(8), points)
    assert inside["samples"] == pytest.approx(8) and inside["seconds"] == pytest.approx(4)
    assert not inside["extrapolated"]
    beyond = noise.equal_noise(40 / math.sqrt(64), points)
    assert beyond["samples"] == pytest.approx(64) and beyond["seconds"] == pytest.approx(32)
    assert beyond["extrapolated"]
    with pytest.raises(ValueError):
        noise.equal_noise(10.0, points[:1])


def test_a_tiny_case_renders_both_engines_at_every_count(tmp_path):
    # Dense enough that the spheres hide parts of each other's world (300 hardly did: the
    # RMS of either count was a few hundredths of a step, and which was larger was chance).
    case = scale.Case.parse("instances:3000:64x36")
    result = noise.run(case, (1, 4), 16, (1, 4), 64, repeats=1, budget=0.0, out=str(tmp_path))
    assert [e["samples"] for e in result["glint"]] == [1, 4]
    assert [e["samples"] for e in result["cycles"]] == [1, 4]
    for engine in ("glint", "cycles"):
        noisy, less = result[engine]
        # More samples, less noise: each engine's own convergence, which a count that did
        # not reach the render (the same image twice) would not show.
        assert noisy["rms"] > less["rms"] > 0, engine
        assert result[engine + "_reference"]["samples"] in (16, 64)
    assert [m["world_samples"] for m in result["equal_noise"]] == [1, 4]
    assert all(m["seconds"] > 0 for m in result["equal_noise"])
    assert len(noise.summary(result)) == 4
    assert os.path.exists(result["picture"])

    # The bench's rows (one per count) and its report's line for the workload.
    from bench import report
    from bench.suite import QUICK, Bench, noise_rows

    bench = Bench(QUICK, str(tmp_path))
    bench.scale_results.append(dict(result, kind="noise"))
    rows = noise_rows("scale-noise", result)
    assert [(row.kind, row.seconds) for row in rows] == (
        [("glint", e["median_s"]) for e in result["glint"]]
        + [("cycles", e["median_s"]) for e in result["cycles"]])
    assert all("Cycles at the same noise" in row.notes[-1] for row in rows[:2])
    (target,) = [t for t in report.scale_targets(bench) if t.name.startswith("(scale 5)")]
    assert target.status == "MEASURED" and "4 world samples" in target.details


def test_without_blender_the_workload_is_left_out_with_a_note(tmp_path):
    from bench.suite import QUICK, Bench

    bench = Bench(QUICK, str(tmp_path), use_blender=False)
    bench.noise_workload("scale-noise")
    bench.scale_workload("scale-points")
    assert not bench.rows and not bench.scale_results
    assert [note.split(":")[0] for note in bench.notes] == ["scale-noise", "scale-points"]
