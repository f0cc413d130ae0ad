"""Reference safe sets by rollout under the single adversarial action.

With one action in Gamma* and no disturbance the system is deterministic, so one rollout
per point decides membership of the safe set under Gamma*:

- ``safe_until_standstill``: a scenario with a functional step, stepped until every run
  fails, truncates or stands still (its state stops changing: nothing can happen later);
- ``safe_by_simulation``: a black-box back end (e.g. SUMO), run for the scenario's
  ``adversary_settle_steps`` steps, after which the scenario declares nothing changes.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import CONTINUE, FAILURE, Scenario, ScenarioError
from scenarios.streams import RunStreams

MAX_STEPS = 5000


def safe_until_standstill(scenario: Scenario, points: np.ndarray, max_steps: int = MAX_STEPS,
                          chunk: int = 1 << 18) -> np.ndarray:
    """(G, n) -> (G,) bool: the rollout under Gamma*[0] never fails."""
    out = np.empty(len(points), dtype=bool)
    u_row = scenario.adversarial_actions[0]
    for lo in range(0, len(points), chunk):
        state = np.ascontiguousarray(points[lo : lo + chunk], dtype=float)
        safe = np.ones(len(state), dtype=bool)
        active = np.arange(len(state))
        for _ in range(max_steps):
            nxt = scenario.step(state, np.broadcast_to(u_row, (len(state), scenario.m)), None)
            status = scenario.classify(nxt)
            safe[active[status == FAILURE]] = False
            moving = (status == CONTINUE) & (np.abs(nxt - state).max(axis=1) > 0)
            active, state = active[moving], np.ascontiguousarray(nxt[moving])
            if len(active) == 0:
                break
        else:
            raise ScenarioError(f"scenario {scenario.error_name!r}: adversarial rollouts did not come to a standstill within "
                                f"{max_steps} steps; its reference_safe() cannot use safe_until_standstill")
        out[lo : lo + chunk] = safe
    return out


def safe_by_simulation(backend, points: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """A black-box SV has no model, but under the single adversarial action the system is
    deterministic: simulating every point for ``adversary_settle_steps`` decides
    membership by the simulator itself."""
    from scenarios.actions import AdversarialActions
    from scenarios.rollout import run_scenario

    scenario = backend.scenario
    horizon = scenario.adversary_settle_steps
    out = np.empty(len(points), dtype=bool)
    policy = AdversarialActions(deterministic=True)
    for lo in range(0, len(points), chunk):
        part = points[lo : lo + chunk]
        batch = run_scenario(backend, part, horizon, policy, RunStreams.of(0, np.arange(lo, lo + len(part))))
        out[lo : lo + len(part)] = batch.outcomes != FAILURE
    return out
