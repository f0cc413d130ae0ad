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
- At a round end the driver decays the algorithm's resolution and runs experience
  replay: the algorithm names its stored runs, the executor screens them where they are,
  the algorithm applies what is new.
- With ``certify``, the last round is followed by a certification round (the final set
  checked as validate checks it; its count is N_eps split over attempts, or every final
  centre once for a deterministic system). A change there re-opens the set and restarts
  the count.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import asdict, dataclass, field
from typing import Callable, Iterable

import numpy as np

from coordinator.adversary import AdversarySearch
from coordinator.algorithm import Algorithm, Event
from coordinator.commit_log import CommitLog
from coordinator.coverage import Rescreen
from coordinator.executor import Chunk, Executor
from coordinator.sample_size import n_eps, n_eps_attempt
from scenarios.base import FAILURE, OUTCOME_NAMES
from scenarios.streams import RunStreams


@dataclass(frozen=True)
class CampaignSettings:
    """What the driver needs besides the algorithm and the executor (the config's
    quantify.epsilon, beta, budget, certify, farm.batch_size, pipeline_depth, seed and
    record.quantify_runs)."""

    epsilon: float = 0.001
    beta: float = 0.1
    budget: int = 2_000_000
    batch_size: int = 1024
    pipeline_depth: int = 2
    seed: int = 0
    certify: bool = False
    record_limit: int = 0  # state-changing failures kept for the MCAP recording

    @property
    def n_eps(self) -> int:
        """Quiet runs in a row that end a round (Lemma 2)."""
        return n_eps(self.epsilon, self.beta)

    def certification_quiet(self, attempt: int) -> int:
        """Quiet runs in a row that certify at sampled attempt ``attempt`` (1, 2, ...): beta
        split over the attempts, so that the set finally exported keeps it."""
        return n_eps_attempt(self.epsilon, self.beta, attempt)


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


Observer = Callable[["Campaign"], None]


class Campaign:
    """Drive ``algorithm`` with ``executor`` until the last round ends by the N_eps rule
    or ``settings.budget`` runs are committed. ``observers`` are called after every
    committed chunk (progress, status, checkpoints); ``adversary`` (actions.mode =
    "search") sees every committed run and re-weights the action mixture at round ends."""

    def __init__(self, algorithm: Algorithm, executor: Executor | None, settings: CampaignSettings,
                 observers: Iterable[Observer] = (), adversary: AdversarySearch | None = None,
                 restored: "DriverState | None" = None):
        """``restored``: continue where a checkpoint left off (the algorithm and the
        adversary hold their restored state already). ``executor`` None: a finished
        campaign read back, which runs nothing."""
        self.algorithm = algorithm
        self.executor = executor
        self.settings = settings
        self.observers = list(observers)
        self.adversary = adversary
        self.certify = settings.certify and algorithm.certifies
        self.counters = restored.counters if restored is not None else Counters()
        self.pending: deque[Pending] = deque(restored.pending if restored is not None else ())
        self.final_distribution = restored.final_distribution if restored is not None else ""
        self.log = CommitLog()
        self.recordings: list[dict] = []  # runs to record, since the last flush
        self._stop = False

    @property
    def n_eps(self) -> int:
        return self.settings.n_eps

    # -- drawing ------------------------------------------------------------------------
    def _next_draw_index(self) -> int:
        if self.pending:
            last = self.pending[-1]
            return last.first_index + len(last)
        return self.counters.committed

    def _fill(self) -> None:
        """Keep ``pipeline_depth`` batches drawn and submitted (fewer when the budget ends)."""
        s = self.settings
        while len(self.pending) < s.pipeline_depth:
            first = self._next_draw_index()
            size = min(s.batch_size, s.budget - first)
            if size <= 0:
                break
            streams = RunStreams.of(s.seed, np.arange(first, first + size, dtype=np.uint64))
            starts, ids = self.algorithm.draw(streams)
            self.pending.append(Pending(first, starts, ids, self.algorithm.version))  # len(starts) may be < size
        for p in self.pending:
            if not p.handles:
                first = p.first_index + p.done
                p.handles = self.executor.submit(first, p.starts[p.done :], self.algorithm.coverage,
                                                 actions=self._actions())

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
        if c.recorded >= self.settings.record_limit or chunk.outcomes[row] != FAILURE:
            return
        self.recordings.append({"sample_index": chunk.first_index + row, "trajectory": chunk.trajectory(row, start),
                                "outcome": OUTCOME_NAMES[int(chunk.outcomes[row])]})
        c.recorded += 1

    # -- the loop -------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to return at the next chunk boundary (e.g. on SIGINT)."""
        self._stop = True

    @property
    def stopping(self) -> bool:
        return self._stop

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
            if self._commit(p, chunk):
                c.runs_dropped += len(chunk) - (c.committed - committed_before)
                self._end_round()
            else:
                if p.done == len(p):
                    self.pending.popleft()
                if c.committed >= self.settings.budget:
                    c.done = True
            c.elapsed_s = time.monotonic() - started
            for observe in self.observers:
                observe(self)
        c.elapsed_s = time.monotonic() - started
        return c

    def _end_round(self) -> None:
        """The N_eps rule ended a round: drop what is in flight, then certify, finish, or
        start the next round."""
        c, algo = self.counters, self.algorithm
        self._drop_in_flight()
        c.round_ends.append(c.committed)
        c.rounds_completed += 1
        if algo.final_round and self.certify and not algo.certifying:
            self._next_mixture()
            algo.begin_certification()
            c.attempts = 1
        elif algo.final_round:
            self.final_distribution = algo.sampling_description()
            c.converged = True
            c.done = True
            return
        else:
            self._next_mixture()
            algo.end_round()
            self._experience_replay()
            self._certify_at_once()
        c.quiet = 0
        c.escaped_in_streak = 0

    def _experience_replay(self) -> None:
        """The algorithm names its stored runs, the executor screens their states where
        they are held, the algorithm adds what is new at the new resolution."""
        pieces = self.algorithm.replay_pieces()
        found = self.executor.screen_stored(pieces, self.algorithm.coverage) if pieces else []
        self.algorithm.apply_replay(pieces, found)

    def _next_mixture(self) -> None:
        """A round ended and another follows: it samples the re-weighted search mixture."""
        if self.adversary is not None:
            self.adversary.end_round(self.counters.committed)

    def quiet_needed(self) -> int:
        """Runs in a row that must change nothing to end the current round."""
        if self.algorithm.certifying:
            return self.settings.certification_quiet(max(self.counters.attempts, 1))
        return self.settings.n_eps

    def _certify_at_once(self) -> None:
        """A deterministic system's last round is its certification: every final centre
        run once (VAL^delta) is exact, so the N_eps rule's epsilon-almost statement, and
        the runs spent on it, would add nothing."""
        algo = self.algorithm
        if self.certify and algo.deterministic and algo.final_round and not algo.certifying:
            algo.begin_certification()
            self.counters.attempts = 1

    def _drop_in_flight(self) -> None:
        for q in self.pending:
            for handle in q.handles[q.next_handle :]:
                self.executor.cancel(handle)
        self.pending.clear()

    # -- persistence --------------------------------------------------------------------
    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """The driver's state: arrays (the draws not yet committed, so that a resumed
        campaign re-simulates exactly them) and JSON-able metadata (the counters)."""
        arrays = {"pending.count": np.array(len(self.pending))}
        for i, p in enumerate(self.pending):
            arrays[f"pending.{i}.first_index"] = np.array(p.first_index + p.done)
            arrays[f"pending.{i}.starts"] = p.starts[p.done :]
            arrays[f"pending.{i}.start_ids"] = p.start_ids[p.done :]
            arrays[f"pending.{i}.version"] = np.array(p.version)
        meta = {"counters": asdict(self.counters), "final_distribution": self.final_distribution}
        return arrays, meta


@dataclass
class DriverState:
    """A campaign driver's state read back from ``Campaign.state()``'s output, to start a
    ``Campaign`` where a checkpoint left off."""

    counters: Counters
    pending: list[Pending]
    final_distribution: str = ""

    @classmethod
    def read(cls, arrays: dict[str, np.ndarray], meta: dict) -> "DriverState":
        """Raises KeyError, TypeError or ValueError when the checkpoint is damaged."""
        pending = [Pending(int(arrays[f"pending.{i}.first_index"]), arrays[f"pending.{i}.starts"],
                           arrays[f"pending.{i}.start_ids"], int(arrays[f"pending.{i}.version"]))
                   for i in range(int(arrays["pending.count"]))]
        return cls(Counters(**meta["counters"]), pending, meta.get("final_distribution", ""))
