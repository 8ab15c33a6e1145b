"""core.runs: positions within runs laid end to end, checked against a plain Python loop."""

import numpy as np

from core.runs import rank_within_runs, run_starts


def test_rank_within_runs_matches_a_loop_including_empty_runs():
    lengths = np.array([3, 0, 1, 4, 0, 2])
    expected = [i for n in lengths for i in range(n)]
    assert rank_within_runs(lengths).tolist() == expected
    assert run_starts(lengths).tolist() == [0, 3, 3, 4, 8, 8]


def test_no_runs():
    assert rank_within_runs(np.zeros(0, np.intp)).tolist() == []
    assert run_starts(np.zeros(0, np.intp)).tolist() == []
