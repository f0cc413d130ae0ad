"""The paper's other quantification algorithms, kept as baselines for SPE:

- ``AdaptiveExploration``   QNT^AE (Alg. 7): complete, not optimal (finds one invariant set)
- ``DeltaPruning``          QNT^deltaP (Alg. 6): incomplete (Theorem 6)
- ``VanillaSampling``       QNT^VS (Alg. 5): incomplete (Theorem 5)

Same ask/tell interface as ``coordinator.spe.SPE``.
"""

from __future__ import annotations

import numpy as np

from coordinator.covering import Lattice
from coordinator.runs import first_true_per_run, visited_states
from coordinator.spatial import PointIndex
from coordinator.spe import EmptySetError, SPESettings, greedy_uncovered
from scenarios.streams import PURPOSE_START, RunStreams
from scenarios.base import FAILURE, Scenario
from scenarios.run import RunBatch

RESTART_INDEX = 2**62  # stream index of the very first AE start state (no run has it)


def _uniform_pick(ids: np.ndarray, streams: RunStreams) -> np.ndarray:
    u = streams.uniform(0, PURPOSE_START, 1)[:, 0]
    return ids[np.minimum((u * len(ids)).astype(np.int64), len(ids) - 1)]


class _IndexState:
    """Shared persistence for algorithms whose state is one PointIndex + scalars."""

    def state(self) -> dict:
        out = {f"vertices.{k}": v for k, v in self.vertices.state().items()}
        out["scalars"] = np.array([self.delta, self.round, self.version], dtype=float)
        out.update(self._extra_state())
        return out

    def load_state(self, state: dict) -> None:
        self.vertices = PointIndex.from_state({k[9:]: v for k, v in state.items() if k.startswith("vertices.")})
        delta, rnd, version = state["scalars"]
        self.delta, self.round, self.version = float(delta), int(rnd), int(version)
        self._load_extra(state)

    def _extra_state(self) -> dict:
        return {}

    def _load_extra(self, state: dict) -> None:
        pass

    def result(self) -> tuple[np.ndarray, float]:
        return self.vertices.alive_points(), self.delta

    def counts(self) -> dict:
        return {"boxes": self.vertices.alive_count, "vertices": self.vertices.count,
                "delta": self.delta, "round": self.round}

    def record(self, batch, rows, start_ids) -> None:
        pass

    def draw(self, streams):
        ids = self.vertices.alive_ids()
        if len(ids) == 0:
            raise EmptySetError("the safe set is empty: every centre was pruned")
        chosen = _uniform_pick(ids, streams)
        return self.vertices.points[chosen].copy(), chosen

    def _first_leaving(self, batch: RunBatch, rows, counts=None):
        """Offset of the first run that fails or visits a state outside the covering
        (``counts`` masks runs whose change would be a no-op)."""
        fail = batch.outcomes[rows] == FAILURE
        states, pos = visited_states(batch, rows)
        left = ~self.vertices.any_within(states, self.delta)
        change = fail | first_true_per_run(left, pos, len(rows))
        if counts is not None:
            change &= counts
        offset = int(np.argmax(change)) if change.any() else len(rows)
        return offset, np.zeros(offset, dtype=bool)

    def sampling_description(self) -> str:
        return "start states uniform over the alive centres"


class AdaptiveExploration(_IndexState):
    """Alg. 7: grow Phi_sigma from one random sigma0 ~ U(Sigma) by adding every visited
    state not yet covered; any failure restarts from a fresh sigma0."""

    name = "ae"
    decays = True

    def __init__(self, scenario: Scenario, settings: SPESettings, seed: int):
        self.scenario, self.settings, self.seed = scenario, settings, seed
        self.delta = settings.delta0
        self.round = 0
        self.version = 0
        self.restarts = 0
        self._restart(RunStreams.of(seed, [RESTART_INDEX]))

    def _restart(self, streams: RunStreams) -> None:
        sc = self.scenario
        sigma0 = sc.lower + (sc.upper - sc.lower) * streams.uniform(1, PURPOSE_START, sc.n)
        self.vertices = PointIndex(sc.n, 2 * self.delta, sc.lower)
        self.vertices.insert(sigma0)

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    def scan(self, batch: RunBatch, rows, start_ids):
        return self._first_leaving(batch, rows)  # a failure restarts, a new state explores

    def apply(self, batch: RunBatch, row: int, start_id: int) -> str:
        self.version += 1
        if batch.outcomes[row] == FAILURE:
            self.restarts += 1
            self._restart(RunStreams.of(self.seed, batch.indices[row : row + 1]))
            return "restarted"
        states, _ = visited_states(batch, np.array([row]))
        states = states[~self.vertices.any_within(states, self.delta)]
        self.vertices.insert(states[greedy_uncovered(states, self.delta)])
        return "explored"

    def end_round(self) -> bool:
        if self.final_round:
            return False
        self.delta = max(self.settings.gamma * self.delta, self.settings.delta_min)
        self.vertices.recell(2 * self.delta)
        self.round += 1
        self.version += 1
        return True

    def _extra_state(self):
        return {"restarts": np.array(self.restarts)}

    def _load_extra(self, state):
        self.restarts = int(state["restarts"])


class DeltaPruning(_IndexState):
    """Alg. 6 at delta = delta_min: sample a live centre, and prune its box when its run
    leaves the current covering Phi_delta (a failure leaves it too). Ends by the N_eps
    rule (the paper runs a fixed N; a stopping rule makes it comparable)."""

    name = "delta-pruning"
    decays = False
    final_round = True

    def __init__(self, scenario: Scenario, settings: SPESettings, seed: int):
        self.scenario, self.settings = scenario, settings
        self.delta = settings.delta_min
        self.round = 0
        self.version = 0
        lattice = Lattice.tiling(scenario.lower, scenario.upper, self.delta)
        self.vertices = PointIndex(scenario.n, 2 * self.delta, lattice.anchor,
                                   bounds=(scenario.lower, scenario.upper))
        self.vertices.insert(lattice.box_centres(self.delta))

    def scan(self, batch, rows, start_ids):
        # a stale draw's centre may be pruned already: pruning it again changes nothing
        return self._first_leaving(batch, rows, counts=self.vertices.alive[start_ids])

    def apply(self, batch, row, start_id) -> str:
        self.version += 1
        self.vertices.kill([int(start_id)])
        return "pruned"

    def end_round(self) -> bool:
        return False


class VanillaSampling(_IndexState):
    """Alg. 5: draw a random sub-box Phi of Sigma, validate it with VAL^eps-delta (runs
    from its delta-covering centres); the first failure draws a new box; N_eps quiet
    runs in a row accept it."""

    name = "vs"
    decays = False
    final_round = True

    def __init__(self, scenario: Scenario, settings: SPESettings, seed: int):
        self.scenario, self.settings, self.seed = scenario, settings, seed
        self.delta = settings.delta_min
        self.round = 0
        self.version = 0
        self.attempts = 0
        self._new_box(RunStreams.of(seed, [RESTART_INDEX]))

    def _new_box(self, streams: RunStreams) -> None:
        sc = self.scenario
        a = sc.lower + (sc.upper - sc.lower) * streams.uniform(1, PURPOSE_START, sc.n)
        b = sc.lower + (sc.upper - sc.lower) * streams.uniform(2, PURPOSE_START, sc.n)
        lo, hi = np.minimum(a, b)[0], np.maximum(a, b)[0]
        lattice = Lattice.tiling(lo, hi, self.delta)
        self.vertices = PointIndex(sc.n, 2 * self.delta, lattice.anchor)
        self.vertices.insert(lattice.box_centres(self.delta))
        self.attempts += 1

    def scan(self, batch, rows, start_ids):
        return self._first_leaving(batch, rows)  # VAL^eps-delta on the current box

    def apply(self, batch, row, start_id) -> str:
        self.version += 1
        self._new_box(RunStreams.of(self.seed, batch.indices[row : row + 1]))
        return "rejected"

    def end_round(self) -> bool:
        return False

    def _extra_state(self):
        return {"attempts": np.array(self.attempts)}

    def _load_extra(self, state):
        self.attempts = int(state["attempts"])


def make_algorithm(name: str, scenario: Scenario, settings: SPESettings, seed: int):
    from coordinator.spe import SPE

    if settings.boundary and name != "spe":
        raise ValueError("quantify.boundary: the boundary band is an SPE option; allowed with algorithm = 'spe'")
    if name == "spe":
        return SPE(scenario, settings)
    return {"ae": AdaptiveExploration, "delta-pruning": DeltaPruning, "vs": VanillaSampling}[name](
        scenario, settings, seed)
