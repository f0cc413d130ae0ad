"""Model-based reference safe sets for the numpy scenarios, and set comparison.

The safe set is the set of states from which no admissible action sequence reaches a
failure facet before a truncating one (infinite horizon). For the scenarios here:

- ``toy``: closed form (``Toy.safe``), via ``Scenario.reference_safe``.
- ``lead-follow`` / ``fleet3`` under a single adversarial action: the system is then
  deterministic, and one rollout per point until failure, truncation or standstill
  decides membership exactly (``scenarios.worst_case_rollout``). This is the reference for
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

from coordinator.binomial import clopper_pearson
from scenarios.actions import UniformActions
from scenarios.base import FAILURE, Scenario
from scenarios.errors import UserError
from scenarios.rollout import run_scenario
from scenarios.streams import RunStreams
from scenarios.worst_case_rollout import safe_by_simulation


class NoReference(UserError, ValueError):
    """The scenario offers no reference to compare with (one-line message)."""


def reference_safe(backend, points: np.ndarray) -> np.ndarray:
    """(G, n) -> (G,) bool membership of the reference safe set: the scenario's own
    model (``Scenario.reference_safe``), else, for a single adversarial action, the
    back end simulated long enough to settle (``adversary_settle_steps``)."""
    scenario = backend.scenario
    if not scenario.external_sv:
        truth = scenario.reference_safe(points)
        if truth is not None:
            return np.asarray(truth, dtype=bool)
    if len(scenario.adversarial_actions) != 1 or not scenario.adversary_settle_steps:
        raise NoReference(f"compare: scenario {scenario.name!r} has no reference safe set: it defines no "
                          f"reference_safe() model, and no single adversarial action with adversary_settle_steps "
                          f"to simulate one")
    return safe_by_simulation(backend, points)


def falsify(backend, safe_points: np.ndarray, tries: int = 4, horizon: int = 200, seed: int = 0) -> int:
    """How many reference-safe points fail under some random action sequence."""
    return int(falsified(backend, safe_points, slice(None), tries, horizon, seed).sum())


def falsified(backend, safe_points: np.ndarray, rows, tries: int = 4, horizon: int = 200,
              seed: int = 0) -> np.ndarray:
    """Which of ``safe_points[rows]`` (a slice or index array) fail under one of
    ``tries`` random action sequences. Try k of point i is run (seed, k *
    len(safe_points) + i), so any split of the points into ``rows`` gives the answer of
    the whole (a first part can be timed for an estimate)."""
    total = len(safe_points)
    index = np.arange(total)[rows]
    points = safe_points[rows]
    broken = np.zeros(len(points), dtype=bool)
    if len(points) == 0:
        return broken
    for k in range(tries):
        batch = run_scenario(backend, points, horizon, UniformActions(), RunStreams.of(seed, k * total + index))
        broken |= batch.outcomes == FAILURE
    return broken


def grid(scenario: Scenario, points_per_axis: int | None = None) -> np.ndarray:
    """Cell midpoints of a regular grid over Sigma, (G, n); about 1.5e6 points by default."""
    k = points_per_axis or int(round(1.5e6 ** (1 / scenario.n)))
    axes = [lo + (hi - lo) * (np.arange(k) + 0.5) / k for lo, hi in zip(scenario.lower, scenario.upper)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, scenario.n)


def uniform_points(scenario: Scenario, count: int, seed: int = 0) -> np.ndarray:
    """``count`` states uniform in Sigma, (count, n), from their own generator: the
    Monte-Carlo alternative to ``grid`` where a grid is too coarse (k^n points)."""
    u = np.random.default_rng([seed, 0x636F6D70]).random((count, scenario.n))
    return scenario.lower + u * (scenario.upper - scenario.lower)


def compare_sampled(safe_set, points: np.ndarray, truth: np.ndarray, level: float = 0.95) -> dict:
    """IoU, precision and recall of ``safe_set`` against the reference membership
    ``truth`` at ``points`` uniform in Sigma, each with its exact (Clopper-Pearson)
    ``level`` interval: given a point in the union, in the claimed set or in the
    reference, the events "in both" are independent Bernoulli draws of IoU, precision
    and recall. The volumes are shares of Sigma's. No Hausdorff distance: random points
    do not bound one."""
    got = safe_set.contains(points)
    both, union, claimed, safe = (int((got & truth).sum()), int((got | truth).sum()), int(got.sum()),
                                  int(truth.sum()))
    out = {"sample_points": int(len(points)), "interval_level": level}
    for name, k, n in (("iou", both, union), ("precision", both, claimed), ("recall", both, safe)):
        out[name] = float(k / max(n, 1))
        out[f"{name}_interval"] = list(clopper_pearson(k, n, level))
    out["claimed_share"], out["reference_share"] = claimed / len(points), safe / len(points)
    return out


def compare_boxes(backend, safe_set, grid_points_per_axis: int | None = None, truth: np.ndarray | None = None) -> dict:
    """IoU, precision (claimed volume truly safe), recall (true safe volume claimed) and
    the l-inf Hausdorff distance between the quantified set (a ``SafeSet``) and the
    reference, on a grid.

    ``missed_depth_boxes`` / ``overclaimed_depth_boxes``: how deep into the reference's
    safe (unsafe) region the errors reach: the largest l-inf distance from a missed
    (wrongly claimed) grid point to the nearest grid point on the other side, in box
    widths (2 x the smallest half-width). A box that straddles the boundary is pruned or
    kept whole, so errors up to 1 box width plus a grid cell (``grid_cell_boxes``, its
    widest axis) are the boxes' boundary layer; more means a region away from the
    boundary was missed or claimed."""
    scenario = backend.scenario
    points = grid(scenario, grid_points_per_axis)
    truth = reference_safe(backend, points) if truth is None else truth
    got = safe_set.contains(points)
    both = (got & truth).sum()
    spacing = (scenario.upper - scenario.lower) / round(len(points) ** (1 / scenario.n))
    cell = float(np.prod(spacing))
    box_width = 2 * safe_set.finest
    out = {"grid_points": int(len(points)), "iou": float(both / max((got | truth).sum(), 1)),
           "precision": float(both / max(got.sum(), 1)), "recall": float(both / max(truth.sum(), 1)),
           "claimed_volume": float(got.sum() * cell), "reference_volume": float(truth.sum() * cell),
           "hausdorff": hausdorff(points[got], points[truth]),
           "missed_depth_boxes": _depth(points[truth & ~got], points[~truth]) / box_width,
           "overclaimed_depth_boxes": _depth(points[got & ~truth], points[truth]) / box_width,
           "grid_cell_boxes": float(spacing.max() / box_width)}
    return out


def _depth(errors: np.ndarray, other_side: np.ndarray) -> float:
    """Largest l-inf distance from an error point to the other side (0 without errors)."""
    if len(errors) == 0:
        return 0.0
    if len(other_side) == 0:
        return float("inf")
    return float(cKDTree(other_side).query(errors, p=np.inf)[0].max())


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) == 0 or len(b) == 0:
        return float("inf") if len(a) != len(b) else 0.0
    d_ab = cKDTree(b).query(a, p=np.inf)[0].max()
    d_ba = cKDTree(a).query(b, p=np.inf)[0].max()
    return float(max(d_ab, d_ba))
