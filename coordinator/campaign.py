"""The batch driver of a quantification campaign: the parallel contract
(shared/spec/algorithms.md) in one place.

- Runs go out in batches of consecutive global sample indices; run i's randomness comes
  from the stream (seed, i) alone.
- Batch b's start states are drawn from the algorithm state right after batch b - D was
  committed (D = pipeline depth): the driver keeps D batches drawn ahead and draws the
  next one only after committing the oldest. Which worker simulates what, and when,
  cannot change what is drawn.
- Results are committed strictly in sample-index order.
- N_eps rule: a round ends after N_eps consecutive committed runs that changed nothing
  *and were drawn from the state as it is now* (their draw version equals the current
  version). A run drawn before the last change still has its evidence used, but does not
  count. At a round end, runs of the batch after the N_eps-th, and all batches in flight,
  are dropped and their indices re-used: the committed sequence depends only on the
  config and the seed.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from scenarios.streams import RunStreams


@dataclass
class Pending:
    first_index: int
    starts: np.ndarray
    start_ids: np.ndarray
    version: int
    handle: Any = None


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


@dataclass
class CommitLog:
    """Columns of the committed-run record since the last flush (the run ledger)."""

    sample_index: list = field(default_factory=list)
    round: list = field(default_factory=list)
    delta: list = field(default_factory=list)
    start: list = field(default_factory=list)
    outcome: list = field(default_factory=list)
    steps: list = field(default_factory=list)
    changed: list = field(default_factory=list)
    counted: list = field(default_factory=list)

    def add(self, batch, rows, rnd, delta, changed: bool, counted: bool) -> None:
        if len(rows) == 0:
            return
        self.sample_index.append(batch.indices[rows].astype(np.int64))
        self.round.append(np.full(len(rows), rnd, dtype=np.int32))
        self.delta.append(np.full(len(rows), delta))
        self.start.append(batch.trajectories[0, rows])
        self.outcome.append(batch.outcomes[rows].astype(np.int8))
        self.steps.append((batch.lengths[rows] - 1).astype(np.int32))
        self.changed.append(np.full(len(rows), changed))
        self.counted.append(np.full(len(rows), counted))

    def take(self) -> dict[str, np.ndarray] | None:
        if not self.sample_index:
            return None
        out = {name: np.concatenate(getattr(self, name)) for name in self.__dataclass_fields__}
        for name in self.__dataclass_fields__:
            getattr(self, name).clear()
        return out


class Campaign:
    """Drive ``algorithm`` with ``executor`` until the last round ends by the N_eps rule
    or ``budget`` runs are committed."""

    def __init__(self, algorithm, executor, *, n_eps: int, budget: int, batch_size: int,
                 pipeline_depth: int, seed: int, on_batch: Callable[["Campaign"], None] | None = None,
                 record_limit: int = 0):
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
        self.recordings: list[dict] = []  # runs to record, since the last flush
        self._stop = False

    # -- drawing ------------------------------------------------------------------------
    def _next_draw_index(self) -> int:
        if self.pending:
            last = self.pending[-1]
            return last.first_index + len(last.starts)
        return self.counters.committed

    def _fill(self) -> None:
        while len(self.pending) < self.depth:
            first = self._next_draw_index()
            size = min(self.batch_size, self.budget - first)
            if size <= 0:
                return
            streams = RunStreams.of(self.seed, np.arange(first, first + size, dtype=np.uint64))
            starts, ids = self.algorithm.draw(streams)
            self.pending.append(Pending(first, starts, ids, self.algorithm.version))
        for p in self.pending:
            if p.handle is None:
                p.handle = self.executor.submit(p.first_index, p.starts)

    # -- committing ------------------------------------------------------------------------
    def _commit(self, p: Pending, batch) -> bool:
        """Commit one batch in index order. True if the round ended inside it."""
        algo, c = self.algorithm, self.counters
        size = len(batch)
        pos, chunk = 0, 32
        while pos < size:
            rows = np.arange(pos, min(pos + chunk, size))
            offset, escaped = algo.scan(batch, rows, p.start_ids[rows])
            quiet_rows = rows[:offset]
            counted = p.version == algo.version
            if counted and c.quiet + offset >= self.n_eps:
                take = self.n_eps - c.quiet
                self._commit_quiet(batch, p, quiet_rows[:take], counted, escaped[:take])
                c.quiet = self.n_eps
                return True
            self._commit_quiet(batch, p, quiet_rows, counted, escaped)
            if offset < len(rows):
                row = int(rows[offset])
                algo.apply(batch, row, int(p.start_ids[row]))
                self._maybe_record(batch, row)
                c.quiet = 0
                c.escaped_in_streak = 0
                c.changes += 1
                self.log.add(batch, np.array([row]), algo.round, algo.delta, True, False)
                algo.record(batch, np.array([row]), p.start_ids[[row]])
                c.committed += 1
                pos = row + 1
                chunk = max(16, chunk // 4)  # after a change, more changes tend to follow
            else:
                pos += len(rows)
                chunk = min(4 * chunk, 16384)
            if c.committed >= self.budget:
                return False
        return False

    def _maybe_record(self, batch, row: int) -> None:
        """Keep the trajectory of a state-changing failure for the MCAP recording (the
        runs worth looking at), up to ``record_limit`` per campaign."""
        from scenarios.base import FAILURE, OUTCOME_NAMES

        c = self.counters
        if c.recorded >= self.record_limit or batch.outcomes[row] != FAILURE:
            return
        self.recordings.append({"sample_index": int(batch.indices[row]), "trajectory": batch.trajectory(row).copy(),
                                "outcome": OUTCOME_NAMES[int(batch.outcomes[row])]})
        c.recorded += 1

    def _commit_quiet(self, batch, p, rows, counted, escaped) -> None:
        if len(rows) == 0:
            return
        c = self.counters
        self.log.add(batch, rows, self.algorithm.round, self.algorithm.delta, False, counted)
        self.algorithm.record(batch, rows, p.start_ids[rows])
        c.committed += len(rows)
        if counted:
            c.quiet += len(rows)
            c.escaped_in_streak += int(np.count_nonzero(escaped))

    # -- the loop -------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to return at the next batch boundary (e.g. on SIGINT)."""
        self._stop = True

    def run(self) -> Counters:
        c = self.counters
        started = time.monotonic() - c.elapsed_s
        while not c.done and not self._stop:
            self._fill()
            if not self.pending:
                c.done = True  # budget exhausted before the last round converged
                break
            p = self.pending.popleft()
            batch = self.executor.result(p.handle)
            c.runs_simulated += len(batch)
            c.steps_simulated += batch.steps
            round_ended = self._commit(p, batch)
            if round_ended:
                c.runs_dropped += len(batch) - (c.committed - p.first_index)
                for q in self.pending:
                    self.executor.cancel(q.handle)
                self.pending.clear()
                c.round_ends.append(c.committed)
                c.rounds_completed += 1
                if self.algorithm.final_round:
                    self.final_distribution = self.algorithm.sampling_description()
                    c.converged = True
                    c.done = True
                else:
                    self.algorithm.end_round()
                    c.quiet = 0
                    c.escaped_in_streak = 0
            elif c.committed >= self.budget:
                c.done = True
            c.elapsed_s = time.monotonic() - started
            if self.on_batch is not None:
                self.on_batch(self)
        c.elapsed_s = time.monotonic() - started
        return c

    # -- persistence --------------------------------------------------------------------
    def pending_state(self) -> dict:
        """Draws in flight, so that a resumed campaign re-simulates exactly them."""
        out = {"pending.count": np.array(len(self.pending))}
        for i, p in enumerate(self.pending):
            out[f"pending.{i}.first_index"] = np.array(p.first_index)
            out[f"pending.{i}.starts"] = p.starts
            out[f"pending.{i}.start_ids"] = p.start_ids
            out[f"pending.{i}.version"] = np.array(p.version)
        return out

    def load_pending(self, state: dict) -> None:
        self.pending.clear()
        for i in range(int(state["pending.count"])):
            self.pending.append(Pending(int(state[f"pending.{i}.first_index"]), state[f"pending.{i}.starts"],
                                        state[f"pending.{i}.start_ids"], int(state[f"pending.{i}.version"])))
