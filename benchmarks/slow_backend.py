"""A slow simulator for scaling benchmarks: the spec's numpy dynamics at the speed of a
real simulator process (SUMO: ~4 us per run and step, docs/benchmarks.md).

It sleeps ``STEP_COST_S`` per held run per step, and drops ended runs at once, as a
simulator removes finished vehicles. The sleep stands in for a remote core: on one
machine, many workers then cost almost no CPU, so the benchmark measures the farm (the
coordinator and Ray), not this machine's two cores. tests/benchmarks checks that it is
as slow as it says.

    [scenario]
    backend = "slow_backend:SlowBackend"    # benchmarks/ on the path
"""

from __future__ import annotations

import time

from scenarios.backend import NumpyBackend

STEP_COST_S = 4e-6  # [s] per run and step


class SlowBackend(NumpyBackend):
    name = "slow"
    compact_below = 1.0  # a simulator stops paying for a run when it ends
    step_cost_s = STEP_COST_S

    def step(self, states, actions, noise, out) -> None:
        time.sleep(self.step_cost_s * len(states))
        super().step(states, actions, noise, out)
