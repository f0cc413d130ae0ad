"""bench_scaling.py's ``CallClock``: the driver's CPU in the executor's calls, its waits
for results apart (docs/scaling.md's "in the calls" column)."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from farm.ray_runtime.executor import RayExecutor  # noqa: E402
from scenarios.simulator import SimSpec  # noqa: E402


def test_the_call_clock_counts_the_calls_and_leaves_the_waits_out_and_the_runs_unchanged(ray_local):
    from bench_scaling import CallClock

    # runs of ~50 ms (sleeping): the driver waits for every chunk it reads
    scenario = {"name": "lead-follow", "sv_policy": "idm", "backend": "slow_backend:SlowRunBackend",
                "slow_backend:SlowRunBackend": {"step_cost_s": 0.001}}
    spec = SimSpec(scenario, {"mode": "uniform"}, 50, 0)
    starts = np.tile([10.0, 10.0, 60.0], (16, 1))  # the lead far ahead: every run lasts the horizon
    plain = RayExecutor(spec, 2).start()
    try:
        expected = [plain.result(h) for h in plain.submit(0, starts)]
    finally:
        plain.close()
    ex = RayExecutor(spec, 2).start()
    clock = CallClock(ex)
    try:
        got = [ex.result(h) for h in ex.submit(0, starts)]
    finally:
        ex.close()
    # the chunks' sizes follow measured times (a loaded machine cuts them otherwise): the
    # runs, in order, are what must not change
    for field in ("lengths", "outcomes"):
        np.testing.assert_array_equal(np.concatenate([getattr(c, field) for c in got]),
                                      np.concatenate([getattr(c, field) for c in expected]))
    assert sum(len(c) for c in got) == len(starts)
    assert (np.concatenate([c.lengths for c in got]) == 50).all()
    assert clock.in_waits > 0  # it waited (polling Ray) for chunks of ~50 ms a run
    assert 0 < clock.seconds < clock.in_calls  # the waits are inside the calls, and left out
