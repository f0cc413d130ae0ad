"""The chunk-size rule (farm/execution/chunking.py) on measured times: chunks follow the simulator,
from one run (a slow one) to a whole batch (a fast vectorized one). The rule on real Ray
is tested in tests/farm/test_parallel_contract.py; that no cut changes a result, there too."""

import math

import numpy as np
import pytest

from farm.execution.chunking import DRIVER_SHARE, EXTRAPOLATE, LIMIT_FACTOR, LIMIT_FLOOR_S, REPLAY_FLOOR_S, FIRST_RUN_LIMIT_S, ChunkSizer


def measured(workers, chunk_cost, run_cost, call=1e-3, sizes=(1, 40, 60), timeout=0.0):
    """A sizer that saw chunks of ``sizes`` runs take chunk_cost + run_cost * runs."""
    sizer = ChunkSizer(workers, timeout)
    for _ in range(10):
        for c in sizes:
            sizer.ran(c, chunk_cost + run_cost * c)
            sizer.called(call)
    return sizer


def test_before_any_chunk_every_worker_gets_a_share_and_the_limit_is_generous():
    sizer = ChunkSizer(8)
    assert sizer.size(1024) == 128 and sizer.chunks(1024) == 8
    assert sizer.limit(1) == FIRST_RUN_LIMIT_S and sizer.limit(128) == 128 * FIRST_RUN_LIMIT_S
    assert sizer.busy_at_most(1024, 2) == 8
    assert ChunkSizer(32).busy_at_most(10, 1) == 10  # more workers than runs in flight


def test_the_fit_recovers_the_cost_per_chunk_and_per_run():
    sizer = measured(4, 0.007, 0.002)
    assert sizer.chunk_cost_s == pytest.approx(0.007) and sizer.run_cost_s == pytest.approx(0.002)
    assert sizer.expected_s(10) == pytest.approx(0.027)
    # one size only (a probe of one run): all of its time counts as per-run cost
    probe = ChunkSizer(4)
    probe.ran(1, 0.009)
    assert probe.chunk_cost_s == 0 and probe.run_cost_s == pytest.approx(0.009)


def test_a_slow_simulator_gets_one_run_chunks_and_a_limit_from_its_run_time():
    sizer = measured(4, 0.01, 1.0)
    assert sizer.size(1024) == 1 and sizer.chunks(1024) == 1024
    assert sizer.limit(1) == pytest.approx(LIMIT_FLOOR_S + LIMIT_FACTOR * 1.01)
    assert measured(4, 0.01, 1.0, timeout=7.0).limit(1) == 7.0  # farm.chunk_timeout


def test_an_experience_replay_gets_at_least_two_minutes_unless_the_user_fixes_the_limit():
    fast = measured(2, 0.007, 0.00001)  # numpy-like: a chunk's limit is a few seconds
    assert fast.limit(30_000) < 10 and fast.replay_limit(3_000) == REPLAY_FLOOR_S
    assert measured(2, 0.01, 1.0, timeout=7.0).replay_limit(100) == 7.0  # farm.chunk_timeout


def test_an_experience_replays_limit_grows_with_its_runs_at_the_measured_time_per_run():
    """A 7-D replay of 118,566 runs met a fixed 120 s and ended its campaign with exit 4."""
    sizer = measured(2, 0.007, 0.00001)
    per_run = sizer.run_s  # the chunks' seconds per run, their cost per chunk shared out
    assert sizer.replay_limit(118_566) == pytest.approx(LIMIT_FLOOR_S + LIMIT_FACTOR * 118_566 * per_run)
    assert sizer.replay_limit(2 * 118_566) > 1.9 * sizer.replay_limit(118_566) > REPLAY_FLOOR_S  # no fixed cap
    # a replay screens every kept state, slower per run than a chunk: the next limit follows the last replay
    sizer.replayed(30_000, 36.0)  # 1.2 ms a run
    assert sizer.replay_limit(118_566) == pytest.approx(LIMIT_FLOOR_S + LIMIT_FACTOR * 118_566 * 1.2e-3)
    assert sizer.replay_limit(100) == REPLAY_FLOOR_S  # a few runs: the floor


def test_a_chunk_holds_about_a_second():
    sizer = measured(1, 0.007, 0.002)
    c = sizer.size(1024)
    assert sizer.expected_s(c) <= 1.0 < sizer.expected_s(c + 1)


def test_many_workers_get_a_share_each_unless_the_workers_or_the_driver_cannot_afford_it():
    assert measured(8, 0.007, 0.002).size(1024) == 128  # a share per worker
    # 32 workers of 2 ms runs: 16-run shares, but the workers' cost per chunk (7 ms) and the
    # driver (1 ms a chunk) afford no chunks that short
    sizer = measured(32, 0.007, 0.002)
    c = sizer.size(512)
    afford = math.ceil((32 * 1e-3 / DRIVER_SHARE - 0.007) / 0.002)
    efficient = math.ceil(0.007 * 0.9 / (0.1 * 0.002))
    assert c == max(afford, efficient) > 16
    assert sizer.busy_at_most(1024, 2) == 32  # still every worker, 2 batches in flight
    # a fast vectorized back end: the per-chunk cost (7 ms) would dominate a share: whole
    # batches (once chunks of a share's size were measured: the fit is not extrapolated far)
    assert measured(2, 0.007, 18e-6, sizes=(1, 40, 512)).size(1024) == 1024
    # 1000 workers of 0.1 s runs: the driver cannot call a thousand 1-run chunks a second
    big = measured(1000, 0.01, 0.1)
    assert big.size(100_000) == math.ceil((1000 * 1e-3 / DRIVER_SHARE - 0.01) / 0.1)
    assert big.expected_s(big.size(100_000)) <= 2.1  # still about 2 s of work at most


def test_the_size_is_always_between_one_run_and_the_batch():
    rng = np.random.default_rng(0)  # test data only
    for _ in range(500):
        sizer = measured(int(rng.integers(1, 2000)), float(rng.uniform(0, 0.1)), float(10 ** rng.uniform(-6, 1)),
                         call=float(10 ** rng.uniform(-4, -1)))
        runs = int(rng.integers(1, 20_000))
        assert 1 <= sizer.size(runs) <= runs
        assert sizer.chunks(runs) * sizer.size(runs) >= runs


def test_a_rounds_first_chunks_on_idle_workers_hold_at_most_a_second_of_work():
    # 1,000 workers of 0.1 s runs at 1 ms a call: the driver affords chunks of 2 s
    sizer = measured(1000, 0.0, 0.1, call=1e-3)
    steady = sizer.size(40_000)
    assert steady == math.ceil(1000 * 1e-3 / DRIVER_SHARE / 0.1) == 20
    parts = sizer.cut(40_000, idle=1000)
    sizes = [len(p) for p in parts]
    first = sizes[0]
    assert 9 <= first and first * 0.1 <= 1.0  # at most a second's work on each idle worker
    assert sizes[:1000] == [first] * 1000 and set(sizes[1000:]) == {steady}  # then as usual
    np.testing.assert_array_equal(np.concatenate(parts), np.arange(40_000))  # every row once, in order
    assert [len(p) for p in sizer.cut(40_000)] == [steady] * 2000  # busy workers: cut as usual
    assert [len(p) for p in sizer.cut(5, urgent=True, idle=1000)] == [1] * 5  # replacements: one wave
    assert [len(p) for p in sizer.cut(5, urgent=True, lanes=1)] == [5]  # for the fast lane: one call


def test_a_noisy_fit_does_not_grow_a_batch_to_the_whole_campaign():
    # measured on Ray (numpy back end, 2 workers): many one- and two-run replacement chunks
    # at ~7 ms and a few batch chunks of ~3,000 runs whose times carry noise fitted a cost
    # per run of 0.15 us instead of ~15 us, and batches of up to 380,000 runs followed
    sizer = ChunkSizer(2)
    for k in range(200):
        sizer.ran(2, 0.007)
        if k % 20 == 0:
            sizer.ran(3000, 0.0075)  # a large chunk that happened to run fast
        sizer.called(5e-4)
    assert sizer.run_cost_s < 1e-6  # the fit is off ...
    assert sizer.batch_size(1024) <= 2 * EXTRAPOLATE * 3000  # ... but the batch grows only so far
    # a larger chunk measured corrects the fit (~15 us a run), and the floor follows it
    sizer.ran(12_000, 0.19)
    assert 1e-5 < sizer.run_cost_s < 2e-5
    assert 2_000 < sizer.batch_size(1024) < 2 * EXTRAPOLATE * 12_000
