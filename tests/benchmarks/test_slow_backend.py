"""The scaling benchmark's slow simulator must be as slow as it says (docs/benchmarks.md)."""

import sys
import time
from pathlib import Path

import numpy as np

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
