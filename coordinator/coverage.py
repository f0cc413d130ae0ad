"""The state a run is screened against, and the screening itself.

A ``Coverage`` holds what decides whether a committed run changes a quantification:
the alive centres (``vertices``: is a visited state within delta of the covering?) and,
for SPE, the failure start states PhiBar (``failures``: is it within delta of a known
failure?). It is changed only through ``apply(change)``, so a *mirror* on a worker that
applies the same changes in the same order answers every query exactly as the
coordinator's copy does (queries are exact: see coordinator/spatial.py).

Every change is numbered (``seq``): a mirror is in sync when it has applied the same
numbered changes. Screening a run against the coverage at seq v (``screen``) gives its
*event*: FAIL (it
reached a failure facet), EXPLORE (a visited state is neither within delta of an alive
centre nor of a failure: a new state) or QUIET; ESCAPED marks a quiet run that left the
covering only near a failure. It also gives, per run, the *witnesses* (ids of the alive
centres that covered its states) and its explore states. That lets the coordinator
re-decide a run at a later seq c without its trajectory (``Rescreen``):

- a failure is a failure;
- a quiet run stays quiet as long as all its witnesses are alive (failures only grow,
  so a state near one stays near; a state whose witness lives stays covered);
- an explore run stays one iff one of its explore states is still uncovered and not
  near a failure; its other states cannot have become new (same two reasons); and only
  the centres inserted and failures added since v can have changed that, so those few
  points decide it (``classify_since``) unless delta or the strict mode changed;
- only runs with a killed witness need their visited states again.

delta is fixed within a round and every run drawn in a round is committed or dropped
in it, so a run is never re-decided at another delta.

In *strict* mode (a certification round: the set must hold its runs as validate will
check it) a state near a failure is no excuse: every uncovered state is an event.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coordinator.levels import LeveledIndex
from coordinator.spatial import PointIndex
from coordinator.alive_points import FrozenPoints
from scenarios.base import FAILURE

QUIET, FAIL, EXPLORE = 0, 1, 2
# states x points compared at once when re-deciding states against the points added since
# their screening (below it, cheaper than the index's ~30 array operations per query batch)
BRUTE_FORCE_LIMIT = 1 << 15


# -- changes --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Insert:
    points: np.ndarray  # (k, n) new alive centres (ids continue the count)
    half_width: float | None = None  # their boxes' (mixed sizes only; None: the current delta)


@dataclass(frozen=True)
class Kill:
    ids: np.ndarray


@dataclass(frozen=True)
class AddFailures:
    points: np.ndarray


@dataclass(frozen=True)
class Resize:
    ids: np.ndarray  # alive centres whose boxes take ``half_width`` (mixed sizes: a round end)
    half_width: float


@dataclass(frozen=True)
class Recell:
    delta: float  # a new round: new half-width, cells of 2 * delta


@dataclass(frozen=True)
class Strict:
    on: bool  # every uncovered state is an event (certification)


@dataclass(frozen=True)
class Reset:
    state: dict  # a whole coverage (``Coverage.state()``): e.g. a restart of AE


@dataclass
class Screening:
    """Per-run screening of a chunk of k runs at coverage (``epoch``, ``seq``)."""

    seq: int
    epoch: int
    event: np.ndarray  # (k,) int8 QUIET / FAIL / EXPLORE
    escaped: np.ndarray  # (k,) bool
    witness_offsets: np.ndarray  # (k + 1,) run r's witnesses: witnesses[off[r]:off[r + 1]]
    witnesses: np.ndarray  # (W,) int32 vertex ids
    explore_offsets: np.ndarray  # (k + 1,)
    explore_states: np.ndarray  # (E, n)

    def __len__(self) -> int:
        return len(self.event)


class Coverage:
    """Alive centres and failure points at half-width ``delta`` (see module docstring)."""

    ORDERING = [1, 2]  # of ``state()["coverage"]``: the version and the epoch (they order changes)

    def __init__(self, n: int, delta: float, origin, bounds=None, failures: bool = True, mixed: bool = False):
        """``mixed``: boxes keep their own half-widths (boundary refinement): a round
        end resizes only some of them, and a state is covered by a box at its own size."""
        self.n = n
        self.delta = float(delta)
        index = LeveledIndex if mixed else PointIndex
        self.vertices = index(n, 2 * delta, origin, bounds=bounds)
        # failures (start states) lie in Sigma too: the dense grid answers their queries
        self.failures = PointIndex(n, 2 * delta, origin, bounds=bounds) if failures else None
        self.seq = 0  # changes applied (a mirror applies the same ones, in order)
        self.version = 0  # the algorithm version of the last change applied
        self.epoch = 0  # bumped by Reset: vertex ids of older screenings mean nothing
        self.kill_seq = -1  # seq of the last Kill (witness checks needed after it)
        self.insert_seq = -1  # seq of the last Insert (a newer centre may be a state's witness now)
        self.strict = False  # certification: near a failure does not excuse leaving the covering
        self._ancestors: dict[int, int] = {}  # epoch -> the last seq of it this coverage holds (``fork``)
        self._log: list[tuple[int, object]] | None = None
        self._forget_history()

    def fork(self, epoch: int) -> None:
        """This coverage is a copy taken earlier and restored (the algorithm went back to
        it, coordinator/driver/speculation.py) after changes up to ``epoch``: its change numbers
        after the copy were used since for other changes. A new epoch tells screenings made
        since apart; those made at its state or before (``descends``) still hold."""
        self._ancestors = {**self._ancestors, self.epoch: self.seq}
        self.epoch = max(self.epoch, epoch) + 1

    def descends(self, epoch: int, seq: int) -> bool:
        """Is (``epoch``, ``seq``) a state of this coverage's own history (a screening made
        there is as good as one of this epoch at that seq)?"""
        return epoch == self.epoch or self._ancestors.get(epoch, -1) >= seq

    # -- changes ---------------------------------------------------------------------------
    def apply(self, change, version: int) -> None:
        if isinstance(change, Insert):
            if len(change.points):
                self._insert(change.points, change.half_width)
                self.insert_seq = self.seq + 1
        elif isinstance(change, Kill):
            self.vertices.kill(change.ids)
            self.kill_seq = self.seq + 1
        elif isinstance(change, AddFailures):
            self.failures.insert(change.points)
        elif isinstance(change, Recell):
            self.delta = float(change.delta)
            self.vertices.recell(2 * change.delta)
            if self.failures is not None:
                self.failures.recell(2 * change.delta)
        elif isinstance(change, Resize):
            self.vertices.resize(change.ids, change.half_width)
        elif isinstance(change, Strict):
            self.strict = change.on
        elif isinstance(change, Reset):
            self._load(change.state)
            self.epoch += 1
            self._ancestors = {}
        else:
            raise TypeError(f"not a coverage change: {change!r}")
        self.seq += 1
        self.version = version
        if isinstance(change, (Recell, Resize, Strict, Reset)):
            self._forget_history()
        else:
            self._counts.append((self.vertices.count, self.failures.count if self.failures is not None else 0))
        if self._log is not None:
            self._log.append((self.seq, version, change))

    def start_log(self) -> None:
        """Keep the changes applied from now on (for mirrors on other processes)."""
        if self._log is None:
            self._log = []

    def changes_since(self, seq: int) -> list[tuple[int, int, object]]:
        return [entry for entry in (self._log or []) if entry[0] > seq]

    def trim_log(self, seq: int) -> None:
        """Forget changes every mirror has applied (up to ``seq``)."""
        if self._log:
            self._log = [entry for entry in self._log if entry[0] > seq]

    def sync(self, changes) -> None:
        """Apply the logged changes this mirror has not applied yet, in order. A stretch
        of inserts, kills and failures is applied as one insert, one failure insert and
        one kill: the index ends the same (a dense cell names its newest alive centre
        point, a chain lists alive points newest first, kills only take away what was
        there), with a few dozen array operations per stretch instead of per change: every
        worker applies every change, so the per-change cost is paid once per worker."""
        pending = [entry for entry in changes if entry[0] > self.seq]
        at = 0
        while at < len(pending):
            end = at
            while end < len(pending) and isinstance(pending[end][2], (Insert, Kill, AddFailures)):
                end += 1
            if end > at:
                self._apply_stretch(pending[at:end])
            else:  # a change of the rules (Recell, Resize, Strict, Reset)
                self.apply(pending[at][2], pending[at][1])
                end = at + 1
            at = end

    def _apply_stretch(self, entries) -> None:
        inserts, kills, failures = [], [], []
        v_count = self.vertices.count
        f_count = self.failures.count if self.failures is not None else 0
        for offset, (_, _, change) in enumerate(entries, start=1):
            if isinstance(change, Insert):
                inserts.append(change)
                v_count += len(change.points)
                if len(change.points):
                    self.insert_seq = self.seq + offset
            elif isinstance(change, Kill):
                kills.append(change.ids)
                self.kill_seq = self.seq + offset
            else:
                failures.append(change.points)
                f_count += len(change.points)
            self._counts.append((v_count, f_count))
        if v_count > self.vertices.count:
            inserts = [i for i in inserts if len(i.points)]
            widths = None
            if self.mixed:
                widths = np.concatenate([np.full(len(i.points), self.delta if i.half_width is None else i.half_width)
                                         for i in inserts])
            self._insert(np.concatenate([i.points for i in inserts]), widths)
        if failures:
            self.failures.insert(np.concatenate(failures))
        if kills:
            self.vertices.kill(np.concatenate(kills))
        self.seq += len(entries)
        self.version = entries[-1][1]
        if self._log is not None:  # the entries' own numbers: they follow this mirror's seq
            self._log.extend(entries)

    @property
    def mixed(self) -> bool:
        if isinstance(self.vertices, FrozenPoints):
            return self.vertices.half_width is not None
        return isinstance(self.vertices, LeveledIndex)

    def freeze(self) -> None:
        """The campaign is done: keep the points, alive flags and half-widths, drop the
        indexes (no query, change or snapshot follows)."""
        mixed = self.mixed
        self.vertices = FrozenPoints(self.vertices, self.vertices.half_width if mixed else None)
        if self.failures is not None:
            self.failures = FrozenPoints(self.failures, None)

    def _insert(self, points: np.ndarray, half_width) -> None:
        if self.mixed:
            self.vertices.insert(points, half_width)
        elif half_width is not None and np.any(np.abs(np.asarray(half_width) - self.delta) > 1e-12 * self.delta):
            raise ValueError("coverage: boxes of another half-width need a mixed coverage")
        else:
            self.vertices.insert(points)

    def half_widths(self, ids: np.ndarray) -> np.ndarray:
        """The half-widths of the boxes of centres ``ids``."""
        if self.mixed:
            return self.vertices.half_width[ids].copy()
        return np.full(len(ids), self.delta)

    # -- history: the points added since a seq ----------------------------------------------
    def _forget_history(self) -> None:
        """Start counting points anew at this seq: what changed the rules (delta, strict
        mode, a whole new coverage) ends what can be re-decided by the points added."""
        self._history_base = self.seq
        self._counts = [(self.vertices.count, self.failures.count if self.failures is not None else 0)]

    def counts_at(self, seq: int) -> tuple[int, int] | None:
        """(vertex count, failure count) after change ``seq``, if no change of the rules
        came after it (None: re-decide from the whole coverage)."""
        at = seq - self._history_base
        return self._counts[at] if 0 <= at < len(self._counts) else None

    # -- snapshot -------------------------------------------------------------------------
    def state(self) -> dict:
        if isinstance(self.vertices, FrozenPoints):
            raise RuntimeError("coverage: the indexes were released (the campaign is done)")
        out = {f"vertices.{k}": v for k, v in self.vertices.state().items()}
        if self.failures is not None:
            out.update({f"failures.{k}": v for k, v in self.failures.state().items()})
        out["coverage"] = np.array([self.delta, self.version, self.epoch, self.kill_seq, self.seq, self.strict],
                                   dtype=float)
        return out

    def _load(self, state: dict) -> None:
        index = LeveledIndex if "vertices.half_width" in state else PointIndex
        self.vertices = index.from_state({k[9:]: v for k, v in state.items() if k.startswith("vertices.")})
        if any(k.startswith("failures.") for k in state):
            self.failures = PointIndex.from_state({k[9:]: v for k, v in state.items() if k.startswith("failures.")})
        else:
            self.failures = None
        delta, _, _, kill_seq, _, strict = state["coverage"]
        self.delta, self.kill_seq, self.strict = float(delta), int(kill_seq), bool(strict)

    @classmethod
    def from_state(cls, state: dict) -> "Coverage":
        cov = cls.__new__(cls)
        cov.n = state["vertices.points"].shape[1]
        cov._log = None
        cov._load(state)
        _, version, epoch, _, seq, _ = state["coverage"]
        cov.version, cov.epoch, cov.seq = int(version), int(epoch), int(seq)
        cov.insert_seq = cov.seq  # not kept: screenings older than a restore are never asked
        cov._ancestors = {}
        cov._forget_history()
        return cov

    # -- screening -------------------------------------------------------------------------
    def classify_states(self, states: np.ndarray):
        """(S, n) -> witness ids (S,) (-1: not covered) and near (S,) bool (uncovered
        and within delta of a failure; never in strict mode)."""
        witness = self.vertices.cover(states, self.delta)
        near = np.zeros(len(states), dtype=bool)
        if self.failures is not None and self.failures.count and not self.strict:
            uncovered = np.flatnonzero(witness < 0)
            near[uncovered] = self.failures.any_within(states[uncovered], self.delta)
        return witness, near

    def classify_since(self, states: np.ndarray, seq: int):
        """``classify_states`` for states that were new at change ``seq`` (uncovered and
        not near a failure then; in strict mode, uncovered), decided by the points added
        since: centres alive then did not cover them and failures only grow, so only a
        centre inserted since can cover one and only a failure added since can be near
        it. Returns (uncovered, near) as bool arrays, or None when the rules changed since
        ``seq`` or the brute-force comparison would be large (ask ``classify_states``)."""
        counts = self.counts_at(seq)
        if counts is None:
            return None
        v0, f0 = counts
        f_count = self.failures.count if self.failures is not None else 0
        if len(states) * (self.vertices.count - v0 + f_count - f0) > BRUTE_FORCE_LIMIT:
            return None
        covered = self.vertices.covered_by_since(states, self.delta, v0)
        if covered is None:  # mixed sizes: a resized box lies among them
            return None
        uncovered = ~covered
        near = np.zeros(len(states), dtype=bool)
        if f_count and not self.strict:
            near[uncovered] = self.failures.covered_by_since(states[uncovered], self.delta, f0)
        return uncovered, near

    def screen(self, states: np.ndarray, offsets: np.ndarray, outcomes: np.ndarray) -> Screening:
        """Screen k runs (visited states in CSR form, see RunBatch.visited) now."""
        k = len(outcomes)
        counts = np.diff(offsets)
        run = np.repeat(np.arange(k), counts)
        witness, near = self.classify_states(states)
        covered = witness >= 0
        explore = ~covered & ~near
        event = np.where(np.bincount(run[explore], minlength=k) > 0, EXPLORE, QUIET).astype(np.int8)
        event[outcomes == FAILURE] = FAIL
        escaped = np.bincount(run[~covered & near], minlength=k) > 0
        # witnesses of a run, consecutive repeats dropped (a run lingers in a cell)
        w_keep = covered.copy()
        prev_same = np.zeros(len(states), dtype=bool)
        prev_same[1:] = (witness[1:] == witness[:-1]) & (run[1:] == run[:-1])
        w_keep &= ~prev_same
        w_off = np.zeros(k + 1, dtype=np.int64)
        np.cumsum(np.bincount(run[w_keep], minlength=k), out=w_off[1:])
        e_off = np.zeros(k + 1, dtype=np.int64)
        np.cumsum(np.bincount(run[explore], minlength=k), out=e_off[1:])
        # int32 ids (CheckedCentres refuses more than 2^31 centres): a chunk's summary is
        # mostly witnesses, ~26 per run, and goes back through Ray
        return Screening(self.seq, self.epoch, event, escaped, w_off, witness[w_keep].astype(np.int32), e_off,
                         states[explore])
