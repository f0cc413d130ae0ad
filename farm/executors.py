"""Executors: where batches of runs are simulated. The coordinator sees one interface:

    submit(first_index, starts) -> handle     start simulating runs first_index.. on starts
    ready(handles) -> handles                 those finished (non-blocking poll)
    result(handle) -> RunBatch                wait for one batch
    cancel(handle)                            drop a batch (its runs are not committed)

Workers are stateless: they hold a scenario back end built from a plain spec and the
campaign seed, and simulate whatever they are sent. ``LocalExecutor`` simulates in the
coordinator's process when a result is asked for (so a dropped batch costs nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from farm.memory import keep_freed_memory
from scenarios.streams import RunStreams
from scenarios import make_scenario
from scenarios.actions import make_action_policy
from scenarios.run import RunBatch, ScenarioError, run_scenario


@dataclass(frozen=True)
class SimSpec:
    """Everything a worker needs to simulate: plain data, cheap to ship."""

    scenario: dict  # the [scenario] config section
    actions: dict  # the [actions] config section
    horizon: int
    seed: int


def build_simulator(spec: SimSpec):
    keep_freed_memory()  # this process simulates batches from now on
    sc_cfg = spec.scenario
    scenario = make_scenario(sc_cfg["name"], backend=sc_cfg.get("backend", "numpy"),
                             sv_policy=sc_cfg.get("sv_policy", "idm"), disturbance=sc_cfg.get("disturbance", 0.0),
                             failure_facets=sc_cfg.get("failure_facets"), sumo=sc_cfg.get("sumo"))
    act = spec.actions
    policy = make_action_policy(act.get("mode", "uniform"), scenario, act.get("value"), act.get("policy"))
    return scenario, policy


def simulate(scenario, policy, spec: SimSpec, first_index: int, starts: np.ndarray) -> RunBatch:
    indices = np.arange(first_index, first_index + len(starts), dtype=np.uint64)
    try:
        batch = run_scenario(scenario, starts, spec.horizon, policy, RunStreams.of(spec.seed, indices))
    except ScenarioError:
        raise
    except Exception as exc:  # a user scenario raised: name the run, not just the batch
        raise _culprit(scenario, policy, spec, indices, starts, exc) from None
    keep = int(batch.lengths.max())  # ship only the rows some run used
    return RunBatch(batch.indices, np.ascontiguousarray(batch.trajectories[:keep]), batch.lengths, batch.outcomes)


def _culprit(scenario, policy, spec, indices, starts, exc) -> ScenarioError:
    """Bisect the batch (runs depend on their own key only) down to the first run that
    raises on its own."""
    lo, hi = 0, len(starts)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        try:
            run_scenario(scenario, starts[lo:mid], spec.horizon, policy, RunStreams.of(spec.seed, indices[lo:mid]))
            lo = mid
        except Exception:  # noqa: BLE001 - any error narrows the search
            hi = mid
    return ScenarioError(f"scenario {scenario.name!r} raised {type(exc).__name__}: {exc} on sample index "
                         f"{int(indices[lo])} (start state {starts[lo].tolist()})")


class LocalExecutor:
    """In-process, lazy: a batch is simulated when its result is first asked for."""

    name = "local"
    workers = 1

    def __init__(self, spec: SimSpec):
        self.spec = spec
        self.scenario, self.policy = build_simulator(spec)
        self._jobs: dict[int, tuple[int, np.ndarray]] = {}
        self._next = 0
        self.runs_simulated = 0
        self.steps_simulated = 0

    def submit(self, first_index: int, starts: np.ndarray) -> int:
        handle = self._next
        self._next += 1
        self._jobs[handle] = (first_index, starts)
        return handle

    def result(self, handle: int) -> RunBatch:
        first_index, starts = self._jobs.pop(handle)
        batch = simulate(self.scenario, self.policy, self.spec, first_index, starts)
        self.runs_simulated += len(batch)
        self.steps_simulated += batch.steps
        return batch

    def cancel(self, handle: int) -> None:
        self._jobs.pop(handle, None)

    def close(self) -> None:
        self._jobs.clear()
