"""The scaling benchmark's slow simulator must be as slow as it says (docs/benchmarks.md)."""

import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from scenarios import make_backend  # noqa: E402
from scenarios.action_modes import make_action_policy  # noqa: E402
from scenarios.rollout import run_scenario  # noqa: E402
from scenarios.streams import RunStreams  # noqa: E402


def test_the_slow_backend_costs_its_step_cost_per_live_run_step_and_simulates_the_same_runs():
    from slow_backend import STEP_COST_S

    slow = make_backend({"name": "lead-follow", "sv_policy": "idm", "backend": "slow_backend:SlowBackend"})
    fast = make_backend({"name": "lead-follow", "sv_policy": "idm"})
    sc = fast.scenario
    starts = sc.lower + (sc.upper - sc.lower) * np.random.default_rng(0).random((400, 3))
    policy = make_action_policy("uniform", sc)
    t0 = time.perf_counter()
    got = run_scenario(slow, starts, 50, policy, RunStreams.of(0, np.arange(400)))
    elapsed = time.perf_counter() - t0
    ref = run_scenario(fast, starts, 50, policy, RunStreams.of(0, np.arange(400)))
    np.testing.assert_array_equal(got.lengths, ref.lengths)
    np.testing.assert_array_equal(got.outcomes, ref.outcomes)
    live_run_steps = int(got.lengths.sum() - len(got))
    assert live_run_steps > 10_000
    assert elapsed >= 0.95 * live_run_steps * STEP_COST_S  # a lower bound: sleeps never end early


def test_the_real_ray_benchmarks_simulator_takes_about_2_ms_a_full_horizon_run():
    """bench_scaling.py's simulator, wall time per run measured on runs that last the whole
    horizon (a quiet start: the lead far ahead), 64 at a time as a worker simulates them (its
    numpy steps cost ~7 ms of CPU a chunk on top, whatever the chunk's size), and one at a
    time (never less than the sleep)."""
    from slow_backend import RUN_STEP_COST_S

    slow = make_backend({"name": "lead-follow", "sv_policy": "idm", "backend": "slow_backend:SlowRunBackend"})
    policy = make_action_policy("uniform", slow.scenario)
    quiet = np.array([[10.0, 10.0, 60.0]])
    assert 49 * RUN_STEP_COST_S == pytest.approx(1.96e-3)
    for count, repeats, most in ((64, 3, 4e-3), (1, 10, None)):
        t0 = time.perf_counter()
        for r in range(repeats):
            batch = run_scenario(slow, np.repeat(quiet, count, axis=0), 50, policy,
                                 RunStreams.of(0, np.arange(r * count, (r + 1) * count)))
            assert (batch.lengths == 50).all()  # every run the whole horizon
        per_run = (time.perf_counter() - t0) / (count * repeats)
        assert per_run >= 1.96e-3 and (most is None or per_run < most), f"{1e3 * per_run:.2f} ms a run of {count}"
