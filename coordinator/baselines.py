"""The paper's other quantification algorithms, kept as baselines for SPE:

- ``AdaptiveExploration``   QNT^AE (Alg. 7): complete, not optimal (finds one invariant set)
- ``DeltaPruning``          QNT^deltaP (Alg. 6): incomplete (Theorem 6)
- ``VanillaSampling``       QNT^VS (Alg. 5): incomplete (Theorem 5)

Same contract as ``coordinator.spe.SPE`` (coordinator/algorithm.py). Their coverage has
no failure points: a run changes the state when it fails or leaves the covering.
"""

from __future__ import annotations

import numpy as np

from coordinator.algorithm import Algorithm, EmptySetError, Event, NoCertification, greedy_uncovered
from coordinator.coverage import Coverage, Insert, Kill, Recell, Reset
from coordinator.lattice import Lattice
from coordinator.stable_sampler import Draws, StableSampler, UniformLaw
from scenarios.base import Scenario
from scenarios.errors import ConfigError
from scenarios.streams import PURPOSE_START, RunStreams

RESTART_INDEX = 2**62  # stream index of the very first AE start state (no run has it)


class _CoverageOnly(NoCertification, Algorithm):
    """Shared parts of algorithms whose whole state is one covering + scalars."""

    append_only = ("vertices.points",)

    def _fresh(self, centres: np.ndarray, lo, hi, bounded: bool) -> Coverage:
        cov = Coverage(self.scenario.n, self._delta0, lo if not bounded else Lattice.tiling(lo, hi, self._delta0).anchor,
                       bounds=(lo, hi) if bounded else None, failures=False)
        cov.apply(Insert(centres), 0)
        return cov

    def _replace(self, fresh: Coverage) -> None:
        """A restart: the covering is replaced (a Reset for the mirrors)."""
        fresh.version = self.version
        self.coverage.apply(Reset(fresh.state()), self.version)
        self.state_epoch += 1

    # Start states uniform over the alive centres, each from its run's own stream. Any
    # change may move any draw (the driver draws a flagged run again and compares): these
    # baselines change their state rarely, or replace it whole.
    _stable: StableSampler | None = None

    def draw(self, streams: RunStreams) -> Draws:
        if self.vertices.alive_count == 0:
            raise EmptySetError("the safe set is empty: every centre was pruned")
        stable = self._sampling()
        law = UniformLaw(self.vertices.count, self._alive, self.vertices.alive_ids)
        return stable.draw(streams, law, self.version)

    def moved(self, draws: Draws) -> np.ndarray:
        return self._sampling().moved(draws)

    def _sampling(self) -> StableSampler:
        """The sampler, restarted after every change: its cap follows the vertex count."""
        if self._stable is None or self._stable_version != self.version:
            if self._stable is None:
                self._stable = StableSampler()
            self._stable.restart(self.vertices.count, self.version)
            self._stable_version = self.version
        return self._stable

    def _alive(self, ids: np.ndarray) -> np.ndarray:
        return self.vertices.alive[ids]

    def state(self) -> dict:
        out = self.coverage.state()
        out["scalars"] = np.array([self.delta, self.round, self.version, self.state_epoch], dtype=float)
        out.update(self._extra_state())
        return out

    def load_state(self, state: dict) -> None:
        self.coverage = Coverage.from_state(state)
        _, rnd, version, epoch = state["scalars"]
        self.round, self.version, self.state_epoch = int(rnd), int(version), int(epoch)
        self._load_extra(state)

    def _extra_state(self) -> dict:
        return {}

    def _load_extra(self, state: dict) -> None:
        pass


class AdaptiveExploration(_CoverageOnly):
    """Alg. 7: grow Phi_sigma from one random sigma0 ~ U(Sigma) by adding every visited
    state not yet covered; any failure restarts from a fresh sigma0."""

    name = "ae"
    decays = True

    def __init__(self, scenario: Scenario, settings, seed: int):
        self.scenario, self.settings, self.seed = scenario, settings, seed
        self._delta0 = settings.delta0
        self.version = 0
        self.round = 0
        self.restarts = 0
        self.state_epoch = 0
        self.coverage = self._fresh(self._sigma0(RunStreams.of(seed, [RESTART_INDEX])), scenario.lower,
                                    scenario.upper, bounded=False)

    def _sigma0(self, streams: RunStreams) -> np.ndarray:
        sc = self.scenario
        return sc.lower + (sc.upper - sc.lower) * streams.uniform(1, PURPOSE_START, sc.n)

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    def apply(self, event: Event) -> str:
        self.version += 1
        if event.failed:
            self.restarts += 1
            fresh = Coverage(self.scenario.n, self.delta, self.scenario.lower, failures=False)
            fresh.apply(Insert(self._sigma0(RunStreams.of(self.seed, [event.index]))), 0)
            self._replace(fresh)
            return "restarted"
        uncovered = event.uncovered
        if uncovered is None:
            uncovered = ~self.vertices.any_within(event.states, self.delta)
        states = event.states[uncovered]
        self.coverage.apply(Insert(states[greedy_uncovered(states, self.delta)]), self.version)
        return "explored"

    def end_round(self) -> bool:
        if self.final_round:
            return False
        self.version += 1
        self.coverage.apply(Recell(max(self.settings.gamma * self.delta, self.settings.delta_min)), self.version)
        self.round += 1
        return True

    def _extra_state(self):
        return {"restarts": np.array(self.restarts)}

    def _load_extra(self, state):
        self.restarts = int(state["restarts"])


class DeltaPruning(_CoverageOnly):
    """Alg. 6 at delta = delta_min: sample a live centre, and prune its box when its run
    leaves the current covering Phi_delta (a failure leaves it too). Ends by the N_eps
    rule (the paper runs a fixed N; a stopping rule makes it comparable)."""

    name = "delta-pruning"
    decays = False
    final_round = True

    def __init__(self, scenario: Scenario, settings, seed: int):
        self.scenario, self.settings = scenario, settings
        self._delta0 = settings.delta_min
        self.version = 0
        self.round = 0
        self.state_epoch = 0
        lattice = Lattice.tiling(scenario.lower, scenario.upper, self._delta0)
        self.coverage = self._fresh(lattice.box_centres(self._delta0), scenario.lower, scenario.upper, bounded=True)

    def apply(self, event: Event) -> str:
        self.version += 1
        self.coverage.apply(Kill(np.array([event.start_id])), self.version)
        return "pruned"

    def end_round(self) -> bool:
        return False


class VanillaSampling(_CoverageOnly):
    """Alg. 5: draw a random sub-box Phi of Sigma, validate it with VAL^eps-delta (runs
    from its delta-covering centres); the first failure draws a new box; N_eps quiet
    runs in a row accept it."""

    name = "vs"
    decays = False
    final_round = True

    def __init__(self, scenario: Scenario, settings, seed: int):
        self.scenario, self.settings, self.seed = scenario, settings, seed
        self._delta0 = settings.delta_min
        self.version = 0
        self.round = 0
        self.attempts = 0
        self.state_epoch = 0
        self.coverage = self._new_box(RunStreams.of(seed, [RESTART_INDEX]))

    def _new_box(self, streams: RunStreams) -> Coverage:
        sc = self.scenario
        a = sc.lower + (sc.upper - sc.lower) * streams.uniform(1, PURPOSE_START, sc.n)
        b = sc.lower + (sc.upper - sc.lower) * streams.uniform(2, PURPOSE_START, sc.n)
        lo, hi = np.minimum(a, b)[0], np.maximum(a, b)[0]
        lattice = Lattice.tiling(lo, hi, self._delta0)
        self.attempts += 1
        cov = Coverage(sc.n, self._delta0, lattice.anchor, failures=False)
        cov.apply(Insert(lattice.box_centres(self._delta0)), 0)
        return cov

    def apply(self, event: Event) -> str:
        self.version += 1
        self._replace(self._new_box(RunStreams.of(self.seed, [event.index])))
        return "rejected"

    def end_round(self) -> bool:
        return False

    def _extra_state(self):
        return {"attempts": np.array(self.attempts)}

    def _load_extra(self, state):
        self.attempts = int(state["attempts"])


def make_algorithm(name: str, scenario: Scenario, settings, seed: int, deterministic: bool = False) -> Algorithm:
    from coordinator.spe import SPE

    if settings.boundary and name != "spe":
        raise ConfigError("quantify.boundary: the boundary band is an SPE option; allowed with algorithm = 'spe'")
    if name == "spe":
        return SPE(scenario, settings, deterministic)
    return {"ae": AdaptiveExploration, "delta-pruning": DeltaPruning, "vs": VanillaSampling}[name](
        scenario, settings, seed)
