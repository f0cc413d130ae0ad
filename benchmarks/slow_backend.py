"""A slow simulator for scaling benchmarks: the spec's numpy dynamics at the speed of a
real simulator process (SUMO: ~4 us per run and step, docs/benchmarks.md).

It costs ``STEP_COST_S`` per held run per step (the rollout core drops ended runs at
once, as a simulator removes finished vehicles). The cost is a sleep, standing in for a remote core:
on one machine, many workers then cost almost no CPU, so the benchmark measures the farm
(the coordinator and Ray), not this machine's two cores. The steps' costs are added up
and slept at the end of the rollout, in one sleep: on this KVM guest every sleep call
costs ~100-170 us of CPU, which per step (50 sleeps per chunk) nearly doubled a worker's
CPU per run (17.7 against 9.4 us). A chunk still takes as long as its steps cost, and
nothing is returned before that. tests/benchmarks checks that it is as slow as it says.

``SlowRunBackend`` is the same at 40 us per run-step: a full-horizon run of 50 states (49
steps) takes ~2 ms, the simulator of the real-Ray scaling benchmark (bench_scaling.py).
Either takes its step cost as an option, ``[scenario."slow_backend:SlowBackend"]
step_cost_s = ...``.
"""

from __future__ import annotations

import time

from scenarios.backend import NumpyBackend

STEP_COST_S = 4e-6  # [s] per run and step
RUN_STEP_COST_S = 40e-6  # [s] per run and step: ~2 ms a full-horizon run of 50 states


class SlowBackend(NumpyBackend):
    name = "slow"
    step_cost_s = STEP_COST_S

    def __init__(self, scenario, options=None):
        options = dict(options or {})
        self.step_cost_s = float(options.pop("step_cost_s", self.step_cost_s))
        super().__init__(scenario, options)
        self._owed_s = 0.0  # the cost of the steps taken since the rollout began

    def step(self, states, actions, noise, out) -> None:
        self._owed_s += self.step_cost_s * len(states)
        super().step(states, actions, noise, out)

    def clear(self) -> None:
        # the end of every rollout (also after an error): pay what its steps cost
        owed, self._owed_s = self._owed_s, 0.0
        if owed > 0:
            time.sleep(owed)
        super().clear()


class SlowRunBackend(SlowBackend):
    name = "slow-run"
    step_cost_s = RUN_STEP_COST_S
