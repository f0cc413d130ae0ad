import subprocess
import sys

import numpy as np
from scipy import stats

from scenarios.streams import PURPOSE_ACTION, PURPOSE_START, RunStreams


def test_draws_depend_on_seed_and_index_only():
    a = RunStreams.of(7, np.arange(1000)).uniform(3, PURPOSE_ACTION, 2)
    b = RunStreams.of(7, np.arange(500, 1000)).uniform(3, PURPOSE_ACTION, 2)
    np.testing.assert_array_equal(a[500:], b)
    assert not np.array_equal(a, RunStreams.of(8, np.arange(1000)).uniform(3, PURPOSE_ACTION, 2))


def test_draws_are_uniform_and_uncorrelated_across_counters_purposes_and_indices():
    s = RunStreams.of(0, np.arange(200_000))
    u = s.uniform(0, PURPOSE_START, 2)
    assert stats.kstest(u[:, 0], "uniform").pvalue > 1e-3
    assert stats.kstest(u[:, 1], "uniform").pvalue > 1e-3
    v = s.uniform(1, PURPOSE_START, 1)[:, 0]
    w = s.uniform(0, PURPOSE_ACTION, 1)[:, 0]
    for x, y in [(u[:, 0], u[:, 1]), (u[:, 0], v), (u[:, 0], w), (u[:-1, 0], u[1:, 0])]:
        assert abs(np.corrcoef(x, y)[0, 1]) < 0.01


def test_same_stream_in_a_fresh_process():
    code = ("import numpy as np; from scenarios.streams import RunStreams; "
            "print(repr(RunStreams.of(123, [5, 2**40]).uniform(9, 2, 3).tolist()))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert eval(out) == RunStreams.of(123, [5, 2**40]).uniform(9, 2, 3).tolist()


def test_draws_follow_the_documented_formula():
    """draw(counter, lane) = top 53 bits of mix(base + (counter * LANES + lane + 1) * G),
    whatever in-place arithmetic computes it."""
    from scenarios.streams import _G, LANES, mix64

    s = RunStreams.of(11, np.array([0, 3, 2**33, 2**63 + 5], dtype=np.uint64))
    u = s.uniform(7, PURPOSE_ACTION, 3)
    base = s._base(PURPOSE_ACTION)
    with np.errstate(over="ignore"):
        for lane in range(3):
            z = mix64(base + np.uint64(7 * LANES + lane + 1) * _G)
            np.testing.assert_array_equal(u[:, lane], (z >> np.uint64(11)).astype(np.float64) / 2.0**53)


def test_uniform_at_on_rows_is_the_subsets_draw():
    """``rows`` (repeats allowed) asks the same numbers as a subset of those rows."""
    streams = RunStreams.of(5, np.arange(100, 140))
    streams.uniform(1, 7)  # the sub-streams derived before the subset, as the sampler does
    rows = np.repeat(np.array([3, 0, 39, 3]), 4)
    counters = np.tile(np.arange(1, 5, dtype=np.uint64), 4)
    for lane in (0, 1):
        expected = streams.subset(rows).uniform_at(counters, 7, lane)
        assert np.array_equal(streams.uniform_at(counters, 7, lane, rows=rows), expected)
