"""Model-based reference safe sets for the numpy scenarios, and set comparison.

The safe set is the set of states from which no admissible action sequence reaches a
failure facet before a truncating one (infinite horizon). For the scenarios here:

- ``toy``: closed form (``Toy.safe``).
- ``lead-follow`` / ``fleet3`` under a single adversarial action: the system is then
  deterministic, and one rollout per point until failure, truncation or standstill
  decides membership exactly (``safe_under_adversary``). This is the reference for
  every campaign run with ``actions.mode = "adversarial"``.
- With ``brake`` and uniform Gamma as well: the brake SV ignores the lead, and maximal
  lead braking minimises the lead's position at every future time, so a sequence that
  fails implies Gamma* fails no later; a truncation through p10 > 70 under Gamma* implies
  one for every sequence (the gap can only grow while v1 > v0, and the brake SV slows
  faster than any lead). So Gamma* is exactly the worst case.
- With ``idm`` and uniform Gamma, Gamma* is not provably worst: ``falsify`` searches
  random action sequences from Gamma*-safe points, and ``compare`` reports how many it
  breaks (the reference is then an upper bound on the safe set).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from scenarios.streams import RunStreams
from scenarios.actions import UniformActions
from scenarios.base import CONTINUE, FAILURE, Scenario
from scenarios.run import run_scenario


def safe_under_adversary(scenario: Scenario, points: np.ndarray, max_steps: int = 5000,
                         chunk: int = 1 << 18) -> np.ndarray:
    """(B, n) -> (B,) bool: the rollout under Gamma*[0] never fails."""
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
            raise RuntimeError(f"adversarial rollouts did not settle within {max_steps} steps")
        out[lo : lo + chunk] = safe
    return out


def reference_safe(scenario: Scenario, points: np.ndarray) -> np.ndarray:
    if scenario.name == "toy":
        return scenario.safe(points)
    if len(scenario.adversarial_actions) != 1:
        raise ValueError(f"no model-based reference for scenario {scenario.name!r}")
    if hasattr(scenario, "rollout"):
        return safe_by_simulation(scenario, points)
    return safe_under_adversary(scenario, points)


def safe_by_simulation(scenario: Scenario, points: np.ndarray, horizon: int = 400, chunk: int = 4096) -> np.ndarray:
    """A black-box SV (SUMO) has no model, but under the single adversarial action the
    system is deterministic: simulating every grid point long enough (here 40 s: the
    lead stops within 4 s and the SV settles) decides membership by the simulator itself."""
    from scenarios.actions import AdversarialActions

    out = np.empty(len(points), dtype=bool)
    policy = AdversarialActions(deterministic=True)
    for lo in range(0, len(points), chunk):
        part = points[lo : lo + chunk]
        idx = np.arange(lo, lo + len(part))
        batch = run_scenario(scenario, part, horizon, policy, RunStreams.of(0, idx))
        out[lo : lo + len(part)] = batch.outcomes != FAILURE
    return out


def falsify(scenario: Scenario, safe_points: np.ndarray, tries: int = 4, horizon: int = 200, seed: int = 0) -> int:
    """How many reference-safe points fail under some random action sequence."""
    if len(safe_points) == 0:
        return 0
    broken = np.zeros(len(safe_points), dtype=bool)
    for k in range(tries):
        idx = np.arange(k * len(safe_points), (k + 1) * len(safe_points))
        batch = run_scenario(scenario, safe_points, horizon, UniformActions(), RunStreams.of(seed, idx))
        broken |= batch.outcomes == FAILURE
    return int(broken.sum())


def grid(scenario: Scenario, points_per_axis: int | None = None) -> np.ndarray:
    """Cell midpoints of a regular grid over Sigma, (G, n); about 1.5e6 points by default."""
    k = points_per_axis or int(round(1.5e6 ** (1 / scenario.n)))
    axes = [lo + (hi - lo) * (np.arange(k) + 0.5) / k for lo, hi in zip(scenario.lower, scenario.upper)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, scenario.n)


def claimed(scenario: Scenario, centres: np.ndarray, half_width: float, points: np.ndarray) -> np.ndarray:
    from coordinator.spatial import PointIndex

    index = PointIndex(scenario.n, 2 * half_width, scenario.lower)
    if len(centres):
        index.insert(centres)
    return index.any_within(points, half_width)


def compare_boxes(scenario: Scenario, centres: np.ndarray, half_width: float,
                  grid_points_per_axis: int | None = None, truth: np.ndarray | None = None) -> dict:
    """IoU, precision (claimed volume truly safe), recall (true safe volume claimed) and
    the l-inf Hausdorff distance between the quantified set and the reference, on a grid."""
    points = grid(scenario, grid_points_per_axis)
    truth = reference_safe(scenario, points) if truth is None else truth
    got = claimed(scenario, centres, half_width, points)
    both = (got & truth).sum()
    cell = float(np.prod((scenario.upper - scenario.lower) / round(len(points) ** (1 / scenario.n))))
    out = {"grid_points": int(len(points)), "iou": float(both / max((got | truth).sum(), 1)),
           "precision": float(both / max(got.sum(), 1)), "recall": float(both / max(truth.sum(), 1)),
           "claimed_volume": float(got.sum() * cell), "reference_volume": float(truth.sum() * cell),
           "hausdorff": hausdorff(points[got], points[truth])}
    return out


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) == 0 or len(b) == 0:
        return float("inf") if len(a) != len(b) else 0.0
    d_ab = cKDTree(b).query(a, p=np.inf)[0].max()
    d_ba = cKDTree(a).query(b, p=np.inf)[0].max()
    return float(max(d_ab, d_ba))
