"""How much unsafe volume does a finite run horizon K leave claimed safe?

The set sought has an infinite horizon; one run has K states. A start whose failure
comes after K steps is caught only through the exploration graph. Under Gamma* the
system is deterministic, so the exact reference is one rollout per grid point until it
fails (unsafe), leaves Sigma through a truncating facet or stops changing (safe).

    python experiments/horizon.py     # writes docs/horizon.json
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from coordinator.baselines import make_algorithm
from coordinator.driver import Campaign, CampaignSettings
from coordinator.spe import SPESettings
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios import make_scenario
from scenarios.base import CONTINUE, FAILURE

DOCS = Path(__file__).resolve().parents[1] / "docs"


def adversary_reference(scenario, points: np.ndarray, max_steps: int = 5000) -> np.ndarray:
    """Exact safe-set membership under the single adversarial action."""
    u = np.broadcast_to(scenario.adversarial_actions[0], (len(points), scenario.m))
    state = points.copy()
    safe = np.ones(len(points), dtype=bool)
    active = np.arange(len(points))
    for _ in range(max_steps):
        nxt = scenario.step(state, u[: len(state)], None)
        status = scenario.classify(nxt)
        safe[active[status == FAILURE]] = False
        moving = (status == CONTINUE) & (np.abs(nxt - state).max(axis=1) > 0)
        active, state = active[moving], np.ascontiguousarray(nxt[moving])
        if len(active) == 0:
            return safe
    raise RuntimeError("rollouts did not settle")


def quantified(scenario_name, policy, horizon, delta_min):
    sc = make_scenario(scenario_name, sv_policy=policy)
    algo = make_algorithm("spe", sc, SPESettings(delta0=2.0, delta_min=delta_min), 0)
    ex = LocalExecutor(SimSpec({"name": scenario_name, "sv_policy": policy}, {"mode": "adversarial"}, horizon, 0))
    settings = CampaignSettings(epsilon=0.001, beta=0.1, budget=3_000_000, batch_size=1024, pipeline_depth=2)
    Campaign(algo, ex, settings).run()
    return sc, algo.result()


def main() -> None:
    rows = []
    sc = make_scenario("lead-follow", sv_policy="idm")
    axes = [np.linspace(lo, hi, k) for lo, hi, k in zip(sc.lower, sc.upper, (81, 81, 281))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    for policy in ("idm", "brake"):
        truth = adversary_reference(make_scenario("lead-follow", sv_policy=policy), grid)
        for delta_min in (1.0, 0.5):
            for horizon in (5, 10, 20, 50, 100):
                _, safe_set = quantified("lead-follow", policy, horizon, delta_min)
                claimed = safe_set.contains(grid)
                row = {"policy": policy, "delta_min": delta_min, "K": horizon,
                       "unsafe_claimed_fraction_of_claimed": float((claimed & ~truth).sum() / claimed.sum()),
                       "unsafe_claimed_fraction_of_sigma": float((claimed & ~truth).mean()),
                       "iou": float((claimed & truth).sum() / (claimed | truth).sum())}
                rows.append(row)
                print(json.dumps(row), flush=True)
    DOCS.mkdir(exist_ok=True)
    (DOCS / "horizon.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
