"""The batch driver of a quantification campaign: the parallel contract
(shared/spec/algorithms.md, shared/spec/scaling.md) in one loop over named parts
(coordinator/driver/__init__.py lists them).

- Runs go out in batches of consecutive global sample indices; run i's randomness, its
  start included, comes from the stream (seed, i) alone (coordinator/stable_sampler.py).
- Results are committed strictly in sample-index order, chunk by chunk as they arrive,
  each run re-decided at the current coverage where it changed since its screening.
- Coupled counting: a run whose start is still its stream's draw at commit is *exact*
  (coordinator/driver/exact.py) and used as the one-run-at-a-time campaign would use it;
  any other is discarded unseen and replaced, applied ``lag`` indices later (sequential
  counting: lag 0, so the committed sequence is the sequential campaign's at any window).
  The head commits on past a replacement that is not back (a hold) and goes back if it
  changes the state; results never depend on holds, speculation or the look-ahead.
- A round ends after N_eps consecutive indices resolved and quiet after the last change;
  what is in flight is dropped and its indices re-used, so the committed sequence
  depends on the config and seed alone. Then delta decays and experience replay runs;
  with ``certify`` the last round is certification (coordinator/driver/phase.py).
"""

from __future__ import annotations

import time
from typing import Callable, Iterable
from weakref import WeakKeyDictionary

import numpy as np

from coordinator.adversary import AdversarySearch
from coordinator.algorithm import Algorithm, Event
from coordinator.rescreen import Rescreen
from coordinator.driver.commit_log import ChunkRows, CommitLog
from coordinator.driver.exact import verify
from coordinator.driver.launcher import Launcher
from coordinator.driver.lead import Lead
from coordinator.driver.lookahead import LookAhead
from coordinator.driver.phase import After, Phase
from coordinator.driver.pipeline import Pending, Pipeline, batch_shape
from coordinator.driver.recordings import Recordings
from coordinator.driver.replacements import Replacement, ReplacementQueue
from coordinator.driver.settings import CampaignSettings
from coordinator.driver.speculation import Speculations
from coordinator.driver.state import Counters, DriverState
from coordinator.executor import Chunk, Executor

VERIFY_BLOCK = 64  # runs checked for exactness at once after a change (then 4x more each time)
MAX_VERIFY_BLOCK = 1 << 16

Observer = Callable[["Campaign"], None]


class Campaign:
    """Drive ``algorithm`` with ``executor`` until the last round ends by the N_eps rule
    or ``settings.budget`` indices are committed. ``observers`` are called after every
    committed chunk (progress, status, checkpoints); ``adversary`` (actions.mode =
    "search") sees every committed run and re-weights the action mixture at round ends."""

    def __init__(self, algorithm: Algorithm, executor: Executor | None, settings: CampaignSettings,
                 observers: Iterable[Observer] = (), adversary: AdversarySearch | None = None,
                 restored: DriverState | None = None):
        """``restored``: continue where a checkpoint left off (the algorithm and the
        adversary hold their restored state already). ``executor`` None: a finished
        campaign read back, which runs nothing."""
        self.algorithm = algorithm
        self.executor = executor
        self.settings = settings
        self.observers = list(observers)
        self.adversary = adversary
        self.phase = Phase(algorithm, settings)
        restored = restored or DriverState(Counters(), [], [])
        self.counters = restored.counters
        self.final_distribution = restored.final_distribution
        self.launcher = Launcher(algorithm, executor, settings.seed, self.counters, adversary)
        self.pipeline = Pipeline(self.launcher, restored.pending,
                                 Lead(adaptive=not settings.lag and executor is not None and executor.concurrent))
        self.replacements = ReplacementQueue(self.launcher, self.counters, settings.lag, restored.replacements)
        self.look_ahead = LookAhead(settings.look_ahead, self.launcher, self.pipeline, self.replacements,
                                    self.counters, settings.batch_size)
        self.speculations = Speculations(settings.speculate)
        self.log = CommitLog()
        self.recordings = Recordings(settings.record_limit, self.counters)
        self._rescreens: WeakKeyDictionary[Chunk, Rescreen] = WeakKeyDictionary()
        self._rewound = False  # a held replacement changed the state: the head went back
        self._stop = False
        self._law_switched = False  # a check failed: the runs in flight were drawn by its law

    @property
    def certify(self) -> bool:
        return self.phase.certify

    @property
    def held(self):
        """The replacements the head committed past before they were back."""
        return self.replacements.held

    @property
    def n_eps(self) -> int:
        return self.settings.n_eps

    def quiet_needed(self) -> int:
        """Indices in a row that must be resolved and quiet to end the current round."""
        return self.phase.quiet_needed(self.counters.attempts)

    # -- the loop ---------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to return at the next chunk boundary (e.g. on SIGINT)."""
        self._stop = True

    @property
    def stopping(self) -> bool:
        return self._stop

    def run(self) -> Counters:
        c = self.counters
        started = time.monotonic() - c.elapsed_s
        if c.committed == 0 and not self.pipeline:
            self.phase.begin_if_last(c)  # delta0 = delta_min: the first round is the last
        while not c.done and not self._stop:
            self._fill()
            self._settle(wait=False)
            if self._rewound:
                self._rewound = False
                continue
            located = self.pipeline.locate(c.committed) if c.committed < self.settings.budget else None
            if located is None:  # the budget is spent
                if self._resolve_all():
                    c.done = True  # budget exhausted before the last round converged
                    break
                self._rewound = False
                continue
            if (self._enumerate if self.phase.enumerating else self._commit)(*located):
                self._end_round()
            elif self._law_switched:
                # every draw in flight is moved by the new law: drop them as a round end does
                # (their indices are drawn again, as their replacements would have been)
                self._law_switched = False
                self._drop_in_flight()
            else:
                held = self.replacements.held  # (no quiet application adds to a hold's "committed")
                self.pipeline.release(held.first.counts["committed"] if held else c.committed)
            c.elapsed_s = time.monotonic() - started
            for observe in self.observers:
                observe(self)
        c.elapsed_s = time.monotonic() - started
        return c

    def _fill(self) -> None:
        """Keep the batches drawn and sent ahead of the head, and launch the replacements
        the head will need."""
        s = self.settings
        batch, depth = batch_shape(s, self.phase.enumerating, lambda: self.executor.batch_size(s.batch_size),
                                   self.quiet_needed)
        self.pipeline.fill(self.counters.committed, batch, depth, s.budget, self.launcher.draw,
                           self.executor.run_seconds(), fixed=self.phase.enumerating)
        self.look_ahead.launch_moved()
        self.replacements.send()

    # -- committing a chunk ------------------------------------------------------------------
    def _commit(self, p: Pending, chunk: Chunk) -> bool:
        """Commit runs of one chunk of batch ``p`` in index order, from the head's index
        (``counters.committed``, the head, walks its indices) to the chunk's end, or until
        the head goes back (a held replacement changed the state). True if the round ended."""
        algo, c = self.algorithm, self.counters
        rows = ChunkRows.of(p, chunk, self._rescreen(chunk), c.committed)
        k, pos, ended, block = len(chunk), rows.logged, False, VERIFY_BLOCK
        # exactness is a function of the state version: what a check found for the rows
        # past a misprediction holds until the next change (its replacement changes nothing)
        verified = (-1, 0, np.zeros(0, dtype=bool))  # (version, first row, exact from there)
        while pos < k and not self._law_switched:
            if c.committed - c.streak_start >= self.quiet_needed():  # the streak is complete
                self._log_upto(rows, pos)
                ended = self._finish_streak()
                if ended or self._rewound:
                    break
                continue
            if c.committed >= self.settings.budget:
                break
            if self.replacements and self.replacements.first.due < c.committed:
                self._log_upto(rows, pos)
                self._apply_due()
                continue
            # exact runs from pos on, up to the streak's end and the next due replacement
            limit = min(k, pos + block, pos + self.quiet_needed() - (c.committed - c.streak_start))
            if self.replacements:
                limit = min(limit, pos + self.replacements.first.due + 1 - c.committed)
            version, first, known = verified
            if version == algo.version and first <= pos < first + len(known):
                limit = min(limit, first + len(known))
                exact = known[pos - first : limit - first]
            else:
                exact = verify(self.launcher, p, rows.at + pos, rows.at + limit)
                verified = (algo.version, pos, exact)
            bad = pos + (len(exact) if exact.all() else int(np.argmin(exact)))
            # (runs past ``bad`` are asked next time: after a misprediction or a block's end)
            stop = min(bad, algo.next_event(rows.rescreen, pos, rows.ids, end=bad))
            rows.counted[pos:stop] = True
            c.quiet += stop - pos
            c.escaped_in_streak += int(np.count_nonzero(chunk.screening.escaped[pos:stop]))
            c.committed += stop - pos
            pos = stop
            if pos == limit:  # quiet and exact up to the limit: look further at once next time
                block = min(4 * block, MAX_VERIFY_BLOCK)
                continue
            block = VERIFY_BLOCK
            if pos == bad:  # mispredicted: discarded unseen, replaced (sent at the next fill)
                c.committed += 1
                rows.kind[pos] = CommitLog.DISCARDED
                # its stream's current draw is known at this version: verified above
                self.replacements.replace(chunk.first_index + pos, p.draws.current(rows.at + pos))
                pos += 1
                continue
            change = rows.event(pos)
            if self.held:
                self._log_upto(rows, pos)
                if not self._may_apply(change):
                    break  # a held replacement changed the state first: the head went back
            c.committed += 1
            applied = self._change(change, chunk, pos)
            rows.changed[pos] = applied
            rows.counted[pos] = not applied  # a violation the check tolerates: one of its runs
            pos += 1
        if self._rewound:  # the rows from the hold on are committed again
            self._rewound = False
            return False
        self._log_upto(rows, pos)
        return ended

    def _may_apply(self, change: Event) -> bool:
        """A change with replacements held before it: apply it only once every one of them
        is applied (each could change the state first), or now, undone if one does. False
        if one did (the head went back)."""
        if self._settle(wait=False):
            return False
        algo, s = self.algorithm, self.settings
        if not self.held:
            return True
        if self.speculations.allowed(algo, self.executor.run_seconds(), s.lag, self.phase.settled):
            self.speculations.take(change.index, algo, self.counters)
            return True
        if not self.phase.settled:
            self.look_ahead.past_holds(change, self.counters.committed + self.quiet_needed())
        return not self._settle(wait=True)

    def _enumerate(self, p: Pending, chunk: Chunk) -> bool:
        """Commit one chunk of a deterministic certification (every centre once): a quiet
        run whose witnesses hold certifies its centre. True if every centre is certified."""
        algo, c = self.algorithm, self.counters
        rows = ChunkRows.of(p, chunk, self._rescreen(chunk), c.committed)
        k, pos, ended = len(chunk), rows.logged, False
        while pos < k:
            offset = algo.next_event(rows.rescreen, pos, rows.ids) - pos
            quiet = np.arange(pos, pos + offset)
            done = algo.certify_runs(rows.ids[quiet], lambda sel: rows.rescreen.witnesses(quiet[sel]))
            if done >= 0:
                offset, ended = done + 1, True
            rows.counted[pos : pos + offset] = algo.vertices.alive[rows.ids[pos : pos + offset]]
            pos += offset
            c.committed += offset
            if ended or pos == k:
                break
            c.committed += 1
            self._change(rows.event(pos), chunk, pos)
            rows.changed[pos] = True
            pos += 1
        self._log_upto(rows, pos)
        return ended

    def _rescreen(self, chunk: Chunk) -> Rescreen:
        """The chunk's runs re-decided at the current coverage: one per chunk and coverage
        (what it found stands until the coverage changes)."""
        coverage = self.algorithm.coverage
        rescreen = self._rescreens.get(chunk)
        if rescreen is None or rescreen.coverage is not coverage:
            rescreen = self._rescreens[chunk] = Rescreen(coverage, chunk.screening, chunk.outcomes, chunk.visited)
        return rescreen

    def _change(self, event: Event, chunk: Chunk, row: int) -> bool:
        """Apply a run that changes the state; the streak starts again at the head. A
        check's violation within its tolerance is only counted: the check goes on.
        True if applied."""
        c = self.counters
        if self.phase.tolerates(c):
            return False
        self.algorithm.apply(event)
        self.recordings.offer(chunk, row, event.index, event.start)
        if self.phase.changed(c):
            self._law_switched = True
        c.changes += 1
        c.start_streak()
        return True

    # -- replacements ------------------------------------------------------------------------
    def _use_replacement(self, r: Replacement, chunk: Chunk, row: int, held: bool = False) -> bool:
        """Replacement ``r``'s run (``chunk``, ``row``) as the run of its index; ``held``:
        it is the first hold (the head went past it). True if it changed the state."""
        c = self.counters
        # a hold is judged at the state as the head passed it (changes applied past it since
        # are undone if it changes the state: coordinator/driver/speculation.py)
        past = self.speculations.first if held and self.speculations else None
        if past is None:
            judged = self._rescreen(chunk)
        else:
            judged = Rescreen(past.algorithm.coverage, chunk.screening, chunk.outcomes, chunk.visited)
        start_id = r.draws.ids[:1]
        changes = judged.changes(row)
        if held and changes:
            if past is not None:
                self._undo_speculations()
                judged = self._rescreen(chunk)  # the state it was judged at, restored: decided there again
                judged.changes(row)
            self.replacements.rewind()
            if self.settings.lag:  # deferred counting: batches drawn past the hold, drawn again
                self.pipeline.forget_drawn_past(self.counters.committed)
            self._rewound = True
        counted = not changes and r.index >= (past.streak_start if past is not None else c.streak_start)
        escaped = int(chunk.screening.escaped[row]) if counted else 0
        c.runs_replaced += 1
        applied = changes and self._change(Event.of_run(r.index, chunk, row, r.start, start_id[0], judged), chunk, row)
        counted |= changes and not applied  # a violation the check tolerates: one of its runs
        if not changes and counted and past is None:  # (past a change, the streak it counts in has ended)
            c.quiet += 1
            c.escaped_in_streak += escaped
        self._log_rows(chunk, np.array([row]), r.index, r.start[None, :], start_id, CommitLog.REPLACEMENT,
                       np.array([applied]), np.array([counted]), now=True)
        if held and not changes:
            self.held.applied_quiet({"runs_replaced": 1, "quiet": int(counted), "escaped_in_streak": escaped},
                                    streak_until=None if past is None else past.index)
            self.speculations.settle(self.held)
        return changes

    def _apply_replacement(self, r: Replacement) -> bool:
        """Use queued replacement ``r`` if it is still what its stream draws now (else it
        is replaced again, unseen). True if it changed the state."""
        found = self.replacements.take(r)
        return found is not None and self._use_replacement(r, *found)

    def _apply_due(self) -> None:
        """The replacements due before the head's index: applied if back and nothing is
        held, else held (the head commits on past them)."""
        while (r := self.replacements.next_due()) is not None:
            self._apply_replacement(r)

    def _settle(self, wait: bool) -> bool:
        """Apply the held replacements, oldest first: those that are back (all of them,
        waiting, with ``wait``). True if one changed the state (the head went back)."""
        while self.held:
            r = self.held.first.replacement
            if not wait and not self.replacements.back(r):
                return False
            chunk, row = self.replacements.fetch(r)  # a stop while waiting leaves the hold in place
            if self._use_replacement(r, chunk, row, held=True):
                return True
        return False

    def _finish_streak(self) -> bool:
        """The head is at the streak's end: apply the held replacements and then the
        streak's queued ones, in due order. True if every index of the streak is resolved
        and quiet (the round ends); False if one changed the state (the streak starts again)."""
        if self._settle(wait=True):
            return False
        while (r := self.replacements.first_from(self.counters.streak_start)) is not None:
            if self._apply_replacement(r):
                return False
        return True

    def _resolve_all(self) -> bool:
        """The budget is spent: every committed index gets its run, so apply the
        replacements still pending (as a one-run-at-a-time campaign would have run them).
        False if a held one changed the state (the head went back below the budget)."""
        if self._settle(wait=True):
            return False
        while self.replacements:
            self._apply_replacement(self.replacements.first)
        return True

    def _undo_speculations(self) -> None:
        """The first hold changes the state, and changes were applied past it: the
        algorithm and the counters go back to how they stood before the first of them,
        and so do the recordings (the head goes back to the hold next)."""
        first = self.speculations.undo(self.algorithm, self.counters)
        self.recordings.forget_from(first.index)
        self.look_ahead.forget()

    # -- what commits leave ---------------------------------------------------------------------
    def _log_upto(self, rows: ChunkRows, end: int) -> None:
        """Log rows [rows.logged, end): runs are logged (and stored for experience replay)
        in the order they are committed, replacements in between. Called before anything
        that may wait: a stop then finds the ledger and the head in step."""
        at = np.arange(rows.logged, end)
        self._log_rows(rows.chunk, at, rows.chunk.first_index + rows.logged, rows.starts[at], rows.ids[at],
                       rows.kind[at], rows.changed[at], rows.counted[at])
        rows.logged = end

    def _log_rows(self, chunk: Chunk, rows: np.ndarray, first_index: int, starts: np.ndarray, ids: np.ndarray,
                  kind, changed: np.ndarray, counted: np.ndarray, now: bool = False) -> None:
        """Rows ``rows`` of ``chunk``, committed or discarded as indices ``first_index,
        first_index + 1, ...`` (``starts``, ``ids``: theirs): to the ledger; the runs used
        also to experience replay and the adversary. Held until the holds before them are
        applied, unless ``now`` (the first hold's own run)."""
        if len(rows) == 0:
            return
        algo = self.algorithm
        kind = np.asarray(kind, dtype=np.int8)
        if kind.ndim == 0:  # one kind for every row
            kind = np.full(len(rows), kind, dtype=np.int8)
        round_, delta = algo.round, algo.delta

        def apply() -> None:
            self.log.add(first_index, starts, chunk, rows, round_, delta, changed, counted, kind)
            used = np.flatnonzero(kind != CommitLog.DISCARDED)
            if len(used) == 0:
                return
            algo.record(chunk, rows[used], ids[used], starts[used])
            self.counters.count_truncations(chunk, rows[used])
            if self.adversary is not None:
                self.adversary.observe(first_index + used, chunk.outcomes[rows[used]])

        if now:
            apply()
        else:
            self.held.effect(apply)

    # -- round ends ------------------------------------------------------------------------------
    def _end_round(self) -> None:
        """The N_eps rule ended a round: drop what is in flight, then check, certify,
        finish, or start the next round."""
        c = self.counters
        self._drop_in_flight()
        after = self.phase.round_ended(c)
        if after is After.DONE:
            self.final_distribution = self.algorithm.sampling_description()
            c.converged = True
            c.done = True
            return
        if after is not After.CHECK:
            self._next_mixture()
        if after is After.NEXT_ROUND:
            self.algorithm.end_round()
            self._experience_replay()
        if after is not After.CHECK:
            self.phase.begin_if_last(c)
        c.start_streak()

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

    def _drop_in_flight(self) -> None:
        """Batches in flight and replacements not yet applied are dropped; their indices
        are drawn again."""
        self.pipeline.drop()
        self.replacements.drop()
        self.speculations.clear()

    # -- persistence -----------------------------------------------------------------------------
    def committed_algorithm(self) -> Algorithm:
        """The algorithm as ``state()`` has the driver: as the head passed the first hold
        (a copy, while changes are applied past it)."""
        return self.speculations.committed(self.algorithm)

    def take_recordings(self) -> list[dict]:
        """The recordings of runs committed for good since the last take (those past a
        change applied past holds stay until it is settled)."""
        return self.recordings.take(self.speculations.first.index if self.speculations else None)

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """The driver's state as a checkpoint keeps it (coordinator/driver/state.py)."""
        state = DriverState.of(self.counters, self.pipeline, self.replacements, self.speculations,
                               self.final_distribution, deferred=self.settings.lag > 0)
        return state.write(self.algorithm.coverage.n)
