"""The quantification-algorithm contract: ask/tell over explicit state.

``coordinator.driver`` drives every algorithm the same way (the parallel contract):

    draw(streams)             ask: start vertices for a batch from each run's own stream,
                              at the state as it is now (its ``version``)
    moved(draws)              which earlier draws a change since may have moved (coupled
                              counting: a moved draw is drawn again and, if it differs,
                              replaced by the driver)
    next_event(rescreen, lo, ids)  the first run lo.. of a screened chunk that changes
                              the state now
    apply(event)              tell: a run that changes the state (prune, explore, ...)
    record(chunk, rows, ids, starts)  tell: the committed runs of a chunk
    end_round()               the round ended by the N_eps rule: decay delta
    replay_pieces(), apply_replay(pieces, found)   experience replay at a round end: the
                              algorithm names its stored runs, the driver has the executor
                              screen them, the algorithm applies what is new
    begin_certification(), certify_runs(...)   the certification round, for an algorithm
                              that ``certifies``; begin_check(), begin_closing() switch a
                              sampled one between closing rounds and checks

Everything a run is screened against lives in ``coverage`` and changes only through
``coverage.apply``, so that workers can screen runs on mirrors of it (see
coordinator/coverage.py). ``version`` counts changes; a run counts toward N_eps only if
its start is what its stream draws at the current state (coordinator/stable_sampler.py).

The shared conformance suite every algorithm passes is ``coordinator/testing.py``.
"""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coordinator.coverage import Coverage
from coordinator.rescreen import Rescreen
from coordinator.safe_set import SafeSet
from coordinator.stable_sampler import Draws
from scenarios.base import FAILURE, Scenario
from scenarios.errors import UserError
from scenarios.streams import RunStreams


class EmptySetError(UserError, RuntimeError):
    """Every candidate was pruned: the quantified safe set is empty (the config asks for
    a set that does not exist at this resolution)."""


@dataclass(frozen=True)
class Event:
    """A committed run that changes the algorithm state."""

    index: int  # its global sample index (the stream key with the seed)
    start: np.ndarray  # (n,) its start state
    start_id: int  # the vertex it was drawn from
    failed: bool
    states: np.ndarray  # (s, n) its visited states that can be new now, in time order
    # what the screening already knows of ``states`` at the current state (None: ask the
    # coverage): (s,) not within delta of an alive centre, and (s,) uncovered but within
    # delta of a failure (None in strict mode, where the screening does not excuse them)
    uncovered: np.ndarray | None = None
    near_failure: np.ndarray | None = None

    @classmethod
    def of_run(cls, index: int, chunk, row: int, start: np.ndarray, start_id, rescreen: Rescreen) -> "Event":
        """Run ``row`` of ``chunk`` (a ``coordinator.executor.Chunk``; sample index ``index``,
        from ``start``, vertex ``start_id``) as the change it makes at ``rescreen``'s coverage."""
        return cls(index, start, int(start_id), bool(chunk.outcomes[row] == FAILURE), rescreen.candidates(row),
                   *rescreen.classification(row))


class Algorithm(ABC):
    """A quantification algorithm (paper Alg. 5-8) over explicit state."""

    name: str = ""
    scenario: Scenario
    decays: bool = True  # delta shrinks round by round (False: a single round)
    # can end with a certification round (the final set checked as validate checks it)
    certifies: bool = False
    # a run is a function of its start state (one adversarial action, no disturbance):
    # certification then runs every final centre once
    deterministic: bool = False
    certifying: bool = False  # in the certification round now
    coverage: Coverage
    version: int = 0
    round: int = 0
    # what ``apply`` never changes, shared by a ``copy`` (experience replay stores only
    # the effects of final commits: coordinator/driver/campaign.py)
    SHARED: tuple[str, ...] = ("replay", "scenario", "settings", "lattice")
    restorable: bool = False  # ``restore`` is supported (``_forget_draws`` is implemented)

    @property
    def delta(self) -> float:
        return self.coverage.delta

    @property
    def vertices(self):
        return self.coverage.vertices

    @property
    @abstractmethod
    def final_round(self) -> bool:
        """The current round is the last one (its end ends the campaign)."""

    @abstractmethod
    def draw(self, streams: RunStreams) -> Draws:
        """Start vertices for the first B' <= B streams, each from its own stream at the
        current state (the starts are ``vertices.points[draws.ids]``). B' < B ends the
        batch early (e.g. a certification with fewer centres left to run than the batch
        has runs); its indices go to the next batch."""

    @abstractmethod
    def moved(self, draws: Draws) -> np.ndarray:
        """(B,) bool: which of these draws a change since they were made may have moved
        (a draw not flagged is what its stream draws now; a flagged one is drawn again)."""

    def next_event(self, rescreen: Rescreen, lo: int, start_ids: np.ndarray, end: int | None = None) -> int:
        """The first run at or after ``lo`` (and before ``end``) of a screened chunk that
        changes the state now (the chunk's length if none)."""
        return rescreen.next_event(lo, end=end)

    @abstractmethod
    def apply(self, event: Event) -> str:
        """Apply one run's change; bump ``version``; return what happened."""

    def record(self, chunk, rows: np.ndarray, start_ids: np.ndarray, starts: np.ndarray) -> None:
        """The committed runs of a chunk (e.g. for experience replay)."""

    @abstractmethod
    def end_round(self) -> bool:
        """Decay delta (the round ended by the N_eps rule); False after the last round."""

    def replay_pieces(self) -> list:
        """Experience replay, right after ``end_round``: the stored runs whose states the
        executor should screen at the new resolution (``coordinator.experience_replay.Stored``);
        empty when the algorithm keeps none."""
        return []

    def apply_replay(self, pieces: list, found: list) -> None:
        """Experience replay: per piece, the (states, run positions) the executor found new."""

    # -- certification: the final set checked the way validate checks a set --------------
    @property
    def enumerates(self) -> bool:
        """Certification checks every centre once (a deterministic system, VAL^delta)."""
        return self.certifying and self.deterministic

    @abstractmethod
    def begin_certification(self) -> None:
        """Enter certification (only when ``certifies``): a sampled system's starts with a
        closing round (coordinator/certification.py)."""

    @property
    def closing(self) -> bool:
        """In a closing round of a sampled certification: its changes spend no beta."""
        return False

    def closing_share(self) -> float:
        """The closing rounds' edge: its share of the alive centres."""
        return 1.0

    def begin_check(self) -> None:
        """A closing round ended: the next rounds check the set (they spend beta)."""
        raise NotImplementedError(f"{type(self).__name__} has no closing rounds")

    def begin_closing(self) -> None:
        """A check found a violation, applied already: a closing round follows."""
        raise NotImplementedError(f"{type(self).__name__} has no closing rounds")

    @abstractmethod
    def certify_runs(self, start_ids: np.ndarray, witnesses: Callable[[np.ndarray], tuple]) -> int:
        """Enumerating certification: quiet runs from centres ``start_ids`` certify their
        centres. ``witnesses(rows)`` gives, for the runs at positions ``rows``, the alive
        centres that cover their states now, in CSR form (offsets, ids); ask it only for
        the runs that can certify (it screens runs again: most of a certification's cost).
        Returns the position of the run after which every alive centre is certified, or -1."""

    # -- copies -----------------------------------------------------------------------------
    def copy(self) -> "Algorithm":
        """A copy that ``apply`` can change without touching this one (it shares ``SHARED``)."""
        return copy.deepcopy(self, self._shared_memo())

    def restore(self, snapshot: "Algorithm") -> None:
        """Become ``snapshot`` (a ``copy`` of this algorithm taken earlier) again, in place:
        whoever holds this object holds the restored state. The version and the coverage's
        epoch move past both states': draws the changes since the copy may have moved are
        drawn again, and runs screened since are screened again, before they count."""
        version, epoch, left = self.version, self.coverage.epoch, dict(self.__dict__)
        memo = self._shared_memo()
        memo[id(snapshot)] = self  # the snapshot's references to itself are to this object now
        state = copy.deepcopy(snapshot.__dict__, memo)
        self.__dict__.clear()
        self.__dict__.update(state)
        since = self.version
        self.version = max(self.version, version) + 1
        self.coverage.fork(epoch)
        self._forget_draws(left, since)

    def _forget_draws(self, left: dict, since: int) -> None:
        """After ``restore``: draws made on the state left (``left``: its attributes), which
        went on from version ``since``, may have moved where its changes touched them."""
        raise NotImplementedError(f"{self.name}: restore is not supported")

    def _shared_memo(self) -> dict:
        return {id(v): v for v in (getattr(self, name, None) for name in self.SHARED) if v is not None}

    # -- the end ----------------------------------------------------------------------------
    def stop_committing(self) -> None:
        """The campaign is done: no run will be committed any more. Drop what serves
        only commits and is not part of ``state`` (indexes), before the last checkpoint
        gathers the state."""

    def release(self) -> None:
        """The campaign is done and checkpointed: drop what only a running campaign or
        its checkpoints need, before the result files and plots are made. ``result``,
        ``counts`` and ``failure_points`` still answer; ``state`` need not."""

    def result(self) -> SafeSet:
        """The quantified set: a box of half-width delta around every alive centre."""
        return SafeSet.uniform(self.vertices.alive_points(), self.delta, self.scenario.state_names)

    def failure_points(self) -> np.ndarray:
        """(F, n) start states of runs that failed and pruned (PhiBar), if kept."""
        return np.empty((0, self.coverage.n))

    @property
    def held(self) -> int:
        """The centres held, alive or pruned: what the algorithm's memory follows."""
        return self.vertices.count

    def counts(self) -> dict:
        return {"boxes": self.vertices.alive_count, "vertices": self.vertices.count, "delta": self.delta,
                "round": self.round}

    def sampling_description(self) -> str:
        return "start states uniform over the alive centres"

    # -- persistence ------------------------------------------------------------------------
    @abstractmethod
    def state(self) -> dict[str, np.ndarray]:
        """The whole algorithm state as named numpy arrays (no pickle)."""

    @abstractmethod
    def load_state(self, state: dict[str, np.ndarray]) -> None: ...

    # arrays of ``state()`` that only grow by appended rows between resets of
    # ``state_epoch``: a checkpoint writes only their new rows
    append_only: tuple[str, ...] = ()
    state_epoch: int = 0

    def content(self) -> dict[str, np.ndarray]:
        """``state()`` but for the counters that only order draws and screenings: the
        version ("scalars"[2]) and the coverage's (``Coverage.ORDERING``). Two campaigns
        that committed the same runs have the same content whatever their executors; the
        counters run further where changes applied past holds were undone (``restore``)."""
        out = dict(self.state())
        out["scalars"] = np.delete(out["scalars"], 2)
        out["coverage"] = np.delete(out["coverage"], Coverage.ORDERING)
        return out


class NoCertification:
    """For an algorithm that does not certify (``certifies = False``): the driver never
    asks, so these say so if it does."""

    certifies = False

    def begin_certification(self) -> None:
        raise NotImplementedError(f"{type(self).__name__} does not certify")

    def certify_runs(self, start_ids, witnesses) -> int:
        raise NotImplementedError(f"{type(self).__name__} does not certify")


GREEDY_WINDOWED = 64  # points from which the greedy pass compares each only with its neighbours


def greedy_uncovered(points: np.ndarray, delta: float) -> np.ndarray:
    """Indices of ``points`` kept when adding them in order and skipping any point
    within l-inf ``delta`` of one already kept (line 15 applied point by point)."""
    kept: list[int] = []
    covered = np.zeros(len(points), dtype=bool)
    r = delta + 1e-9
    windowed = len(points) > GREEDY_WINDOWED
    if windowed:
        # many points (experience replay): a kept point is compared only with the points
        # whose first coordinate lies near its own (sorted; the window is wider than r,
        # so it holds every point within r, each decided by the same comparison)
        order = np.argsort(points[:, 0], kind="stable")
        xs = points[order, 0]
        margin = r + 1e-6 * (1.0 + np.abs(points[:, 0]))
        lo = np.searchsorted(xs, points[:, 0] - margin, side="left")
        hi = np.searchsorted(xs, points[:, 0] + margin, side="right")
    for i in range(len(points)):
        if covered[i]:
            continue
        kept.append(i)
        if windowed:
            later = order[lo[i] : hi[i]]
            later = later[later > i]
        else:
            later = slice(i, None)
        covered[later] |= np.abs(points[later] - points[i]).max(axis=1) <= r
    return np.asarray(kept, dtype=np.int64)
