"""The batch driver of a quantification campaign: the parallel contract
(shared/spec/algorithms.md) in one place.

- Runs go out in batches of consecutive global sample indices; run i's randomness comes
  from the stream (seed, i) alone.
- Batch b's start states are drawn from the algorithm state right after batch b - D was
  committed (D = pipeline depth): the driver keeps D batches drawn ahead and draws the
  next one only after committing the oldest. Which worker simulates what, and when,
  cannot change what is drawn.
- Results are committed strictly in sample-index order, chunk by chunk as they arrive.
  Workers screen their runs against a mirror of the coverage (coordinator/coverage.py);
  the driver takes a screening as it is when nothing changed since, and otherwise
  re-decides each run at the current version from its witnesses.
- N_eps rule: a round ends after N_eps consecutive committed runs that changed nothing
  *and were drawn from the state as it is now* (their draw version equals the current
  version). A run drawn before the last change still has its evidence used, but does not
  count. At a round end, runs after the N_eps-th, and all chunks in flight, are dropped
  and their indices re-used: the committed sequence depends only on the config and seed.
- With ``certify``, the last round is followed by a certification round (SPE: the final
  set checked as validate checks it; its count is N_eps, or every final centre once for
  a deterministic system). A change there re-opens the set and restarts the count.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from coordinator.algorithm import Algorithm, Event
from coordinator.coverage import Rescreen
from coordinator.executor import Chunk
from scenarios.base import FAILURE, OUTCOME_NAMES, TRUNCATED
from scenarios.streams import RunStreams


@dataclass
class Pending:
    """A batch drawn at ``version``; ``done`` of its runs are committed."""

    first_index: int
    starts: np.ndarray
    start_ids: np.ndarray
    version: int
    handles: list = field(default_factory=list)
    done: int = 0
    next_handle: int = 0

    def __len__(self) -> int:
        return len(self.starts)


@dataclass
class Counters:
    committed: int = 0  # == the next sample index to commit (indices are contiguous)
    quiet: int = 0  # the N_eps counter
    escaped_in_streak: int = 0  # counted quiet runs that left Phi_delta near PhiBar
    changes: int = 0
    runs_simulated: int = 0
    steps_simulated: int = 0
    runs_dropped: int = 0
    rounds_completed: int = 0
    done: bool = False
    converged: bool = False  # the last round ended by the N_eps rule
    round_ends: list = field(default_factory=list)  # committed count at each round end
    elapsed_s: float = 0.0
    recorded: int = 0  # runs handed to the recorder so far
    attempts: int = 0  # certification attempts (a change during certification starts the next)
    truncations: list = field(default_factory=list)  # committed truncated runs per facet (Scenario.facets() order)

    def count_truncations(self, chunk: Chunk, k: int) -> None:
        """Add the truncated runs among the chunk's first ``k`` (committed) rows, by the
        facet they left Sigma through."""
        left = chunk.exits[:k][chunk.outcomes[:k] == TRUNCATED]
        if len(left):
            counts = np.bincount(left, minlength=len(self.truncations))
            counts[: len(self.truncations)] += np.asarray(self.truncations, dtype=np.int64)
            self.truncations = counts.tolist()


class CommitLog:
    """Columns of the committed-run record since the last flush (the run ledger).

    Per chunk, what every row shares (first sample index, round, delta) is kept once and
    expanded at ``take``: a campaign shorter than ``farm.checkpoint_every`` holds the log
    of all its runs (2.2 M at delta_min 0.125), and those columns were 20 of 51 bytes a
    run."""

    COLUMNS = ("sample_index", "round", "delta", "start", "outcome", "steps", "changed", "counted")

    def __init__(self):
        self.shared: list[tuple[int, int, int, float]] = []  # (first sample index, rows, round, delta)
        self.start: list[np.ndarray] = []
        self.outcome: list[np.ndarray] = []
        self.steps: list[np.ndarray] = []
        self.changed: list[np.ndarray] = []
        self.counted: list[np.ndarray] = []

    def add(self, first_index: int, starts: np.ndarray, chunk: Chunk, rows: np.ndarray, rnd: int, delta: float,
            changed: np.ndarray, counted: np.ndarray) -> None:
        """``rows`` are the chunk's first rows, 0..k-1 (a chunk is committed in order)."""
        if len(rows) == 0:
            return
        self.shared.append((first_index, len(rows), rnd, delta))
        self.start.append(starts[rows])
        self.outcome.append(chunk.outcomes[rows].astype(np.int8))
        self.steps.append((chunk.lengths[rows] - 1).astype(np.int32))
        self.changed.append(changed)
        self.counted.append(counted)

    def take(self) -> dict[str, np.ndarray] | None:
        if not self.shared:
            return None
        first, rows, rounds, deltas = (np.array(c) for c in zip(*self.shared))
        within = np.arange(int(rows.sum())) - np.repeat(np.cumsum(rows) - rows, rows)
        out = {"sample_index": np.repeat(first.astype(np.int64), rows) + within,
               "round": np.repeat(rounds.astype(np.int32), rows), "delta": np.repeat(deltas.astype(float), rows)}
        self.shared.clear()
        for name in self.COLUMNS[3:]:  # a column's pieces go as it is joined: ~1x the log held, not 2x
            pieces = getattr(self, name)
            out[name] = np.concatenate(pieces)
            pieces.clear()
        return {name: out[name] for name in self.COLUMNS}


class Campaign:
    """Drive ``algorithm`` with ``executor`` until the last round ends by the N_eps rule
    or ``budget`` runs are committed."""

    def __init__(self, algorithm: Algorithm, executor, *, n_eps: int, budget: int, batch_size: int,
                 pipeline_depth: int, seed: int, on_batch: Callable[["Campaign"], None] | None = None,
                 record_limit: int = 0, certify: bool = False,
                 certify_quiet: Callable[[int], int] | None = None, adversary=None):
        self.algorithm = algorithm
        self.executor = executor
        self.n_eps = n_eps
        self.budget = budget
        self.batch_size = batch_size
        self.depth = pipeline_depth
        self.seed = seed
        self.on_batch = on_batch
        self.counters = Counters()
        self.log = CommitLog()
        self.pending: deque[Pending] = deque()
        self.final_distribution = ""
        self.record_limit = record_limit
        self.certify = certify
        # the quiet runs attempt i of a sampled certification needs (default: n_eps); the
        # driver splits beta over the attempts so that the set finally exported keeps it
        self.certify_quiet = certify_quiet
        self.recordings: list[dict] = []  # runs to record, since the last flush
        self._stop = False
        # actions.mode = "search" (coordinator/adversary.py): sees every committed run and
        # re-weights the action mixture at each round end; None for a fixed policy
        self.adversary = adversary

    # -- drawing ------------------------------------------------------------------------
    def _next_draw_index(self) -> int:
        if self.pending:
            last = self.pending[-1]
            return last.first_index + len(last)
        return self.counters.committed

    def _fill(self) -> None:
        """Keep ``depth`` batches drawn and submitted (fewer when the budget ends)."""
        while len(self.pending) < self.depth:
            first = self._next_draw_index()
            size = min(self.batch_size, self.budget - first)
            if size <= 0:
                break
            streams = RunStreams.of(self.seed, np.arange(first, first + size, dtype=np.uint64))
            starts, ids = self.algorithm.draw(streams)
            self.pending.append(Pending(first, starts, ids, self.algorithm.version))  # len(starts) may be < size
        for p in self.pending:
            if not p.handles:
                first = p.first_index + p.done
                p.handles = self.executor.submit(first, p.starts[p.done :], self.algorithm.coverage,
                                                 actions=self._actions())

    def _next_mixture(self) -> None:
        """A round ended and another follows: it samples the re-weighted search mixture."""
        if self.adversary is not None:
            self.adversary.end_round(self.counters.committed)

    def _actions(self) -> dict | None:
        return self.adversary.policy.state() if self.adversary is not None else None

    # -- committing ------------------------------------------------------------------------
    def _commit(self, p: Pending, chunk: Chunk) -> bool:
        """Commit one chunk of batch ``p`` in index order. True if the round ended in it."""
        algo, c = self.algorithm, self.counters
        at = chunk.first_index - p.first_index
        k = len(chunk)
        starts, ids = p.starts[at : at + k], p.start_ids[at : at + k]
        rescreen = Rescreen(algo.coverage, chunk.screening, chunk.outcomes, chunk.visited)
        changed = np.zeros(k, dtype=bool)
        counted = np.zeros(k, dtype=bool)
        rnd, delta = algo.round, algo.delta
        pos, ended = 0, False
        while pos < k:
            offset = algo.next_event(rescreen, pos, ids) - pos
            if algo.enumerates:  # every centre once: any quiet run whose witnesses hold counts
                quiet = np.arange(pos, pos + offset)
                trusted = rescreen.trusted(quiet)
                done = algo.certify_runs(chunk, quiet, ids[quiet], trusted)
                if done >= 0:
                    offset, ended = done - pos + 1, True
                counted[pos : pos + offset] = trusted[:offset]
            elif p.version == algo.version:  # drawn from the state as it is now: counts
                need = self.quiet_needed()
                if c.quiet + offset >= need:
                    offset, ended = need - c.quiet, True
                counted[pos : pos + offset] = True
                c.quiet += offset
                c.escaped_in_streak += int(np.count_nonzero(chunk.screening.escaped[pos : pos + offset]))
            pos += offset
            if ended or pos == k:
                break
            event = Event(chunk.first_index + pos, starts[pos], int(ids[pos]), bool(chunk.outcomes[pos] == FAILURE),
                          rescreen.candidates(pos), *rescreen.classification(pos))
            algo.apply(event)
            self._maybe_record(chunk, pos, starts[pos])
            changed[pos] = True
            if algo.certifying:
                c.attempts += 1
            c.quiet = 0
            c.escaped_in_streak = 0
            c.changes += 1
            pos += 1
        rows = np.arange(pos)
        c.committed += pos
        c.count_truncations(chunk, pos)
        p.done = at + pos
        self.log.add(chunk.first_index, starts, chunk, rows, rnd, delta, changed[:pos], counted[:pos])
        algo.record(chunk, rows, ids[:pos], starts[:pos])
        if self.adversary is not None:
            self.adversary.observe(chunk.first_index + rows, chunk.outcomes[:pos])
        return ended

    def _maybe_record(self, chunk: Chunk, row: int, start: np.ndarray) -> None:
        """Keep the trajectory of a state-changing failure for the MCAP recording (the
        runs worth looking at), up to ``record_limit`` per campaign."""
        c = self.counters
        if c.recorded >= self.record_limit or chunk.outcomes[row] != FAILURE:
            return
        self.recordings.append({"sample_index": chunk.first_index + row, "trajectory": chunk.trajectory(row, start),
                                "outcome": OUTCOME_NAMES[int(chunk.outcomes[row])]})
        c.recorded += 1

    # -- the loop -------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to return at the next chunk boundary (e.g. on SIGINT)."""
        self._stop = True

    def run(self) -> Counters:
        c = self.counters
        started = time.monotonic() - c.elapsed_s
        if c.committed == 0 and not self.pending:
            self._certify_at_once()  # delta0 = delta_min: the first round is the last
        while not c.done and not self._stop:
            self._fill()
            if not self.pending:
                c.done = True  # budget exhausted before the last round converged
                break
            p = self.pending[0]
            chunk = self.executor.result(p.handles[p.next_handle])
            p.next_handle += 1
            c.runs_simulated += len(chunk)
            c.steps_simulated += chunk.steps
            committed_before = c.committed
            round_ended = self._commit(p, chunk)
            if round_ended:
                c.runs_dropped += len(chunk) - (c.committed - committed_before)
                self._drop_in_flight()
                c.round_ends.append(c.committed)
                c.rounds_completed += 1
                if self.algorithm.final_round and self.certify and not self.algorithm.certifying:
                    self._next_mixture()
                    self.algorithm.begin_certification()
                    c.attempts = 1
                    c.quiet = 0
                    c.escaped_in_streak = 0
                elif self.algorithm.final_round:
                    self.final_distribution = self.algorithm.sampling_description()
                    c.converged = True
                    c.done = True
                else:
                    self._next_mixture()
                    self.algorithm.end_round(self.executor)
                    c.quiet = 0
                    c.escaped_in_streak = 0
                    self._certify_at_once()
            else:
                if p.done == len(p):
                    self.pending.popleft()
                if c.committed >= self.budget:
                    c.done = True
            c.elapsed_s = time.monotonic() - started
            if self.on_batch is not None:
                self.on_batch(self)
        c.elapsed_s = time.monotonic() - started
        return c

    def quiet_needed(self) -> int:
        """Runs in a row that must change nothing to end the current round."""
        if self.algorithm.certifying and self.certify_quiet is not None:
            return self.certify_quiet(max(self.counters.attempts, 1))
        return self.algorithm.required_quiet(self.n_eps)

    def _certify_at_once(self) -> None:
        """A deterministic system's last round is its certification: every final centre
        run once (VAL^delta) is exact, so the N_eps rule's epsilon-almost statement, and
        the runs spent on it, would add nothing."""
        algo = self.algorithm
        if self.certify and getattr(algo, "deterministic", False) and algo.final_round and not algo.certifying:
            algo.begin_certification()
            self.counters.attempts = 1

    def _drop_in_flight(self) -> None:
        for q in self.pending:
            for handle in q.handles[q.next_handle :]:
                self.executor.cancel(handle)
        self.pending.clear()

    # -- persistence --------------------------------------------------------------------
    def pending_state(self) -> dict:
        """Draws not yet committed, so that a resumed campaign re-simulates exactly them."""
        out = {"pending.count": np.array(len(self.pending))}
        for i, p in enumerate(self.pending):
            out[f"pending.{i}.first_index"] = np.array(p.first_index + p.done)
            out[f"pending.{i}.starts"] = p.starts[p.done :]
            out[f"pending.{i}.start_ids"] = p.start_ids[p.done :]
            out[f"pending.{i}.version"] = np.array(p.version)
        return out

    def load_pending(self, state: dict) -> None:
        self.pending.clear()
        for i in range(int(state["pending.count"])):
            self.pending.append(Pending(int(state[f"pending.{i}.first_index"]), state[f"pending.{i}.starts"],
                                        state[f"pending.{i}.start_ids"], int(state[f"pending.{i}.version"])))
