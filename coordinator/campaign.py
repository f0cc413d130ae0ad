"""The batch driver of a quantification campaign: the parallel contract
(shared/spec/algorithms.md, shared/spec/scaling.md) in one place.

- Runs go out in batches of consecutive global sample indices; run i's randomness,
  its start included, comes from the stream (seed, i) alone: its start is what its
  stream draws from the algorithm's state (coordinator/stable_sampler.py).
- Results are committed strictly in sample-index order, chunk by chunk as they arrive.
  Workers screen their runs against a mirror of the coverage (coordinator/coverage.py);
  the driver takes a screening as it is when nothing changed since, and otherwise
  re-decides each run at the current version from its witnesses.
- Coupled counting. At commit a run is *exact* when its start is still the draw its
  stream makes at the current state (only runs whose examined slots a change touched are
  looked at again, and the law asked about those slots); an exact run is what the one-run-at-a-time campaign runs at that
  index, and is used as it would use it. A *mispredicted* run is discarded unseen and
  replaced: the current draw, the same index and streams, applied ``lag`` indices later
  (``counting = "sequential"``: lag 0, waited for at the head, so the committed sequence
  is the sequential campaign's at any window; ``"deferred"``: lag = the window,
  batch_size x pipeline_depth). A replacement that a later change moves is replaced again.
- The head does not wait for a due replacement that is not back: it commits on past it
  (a hold, coordinator/replacements.py) as long as nothing changes the state, and goes
  back if the replacement, once applied, does. Results never depend on it. With slow
  runs a change does not wait for the holds before it: it is applied, a copy of the state
  before it kept, and undone if a hold, judged at that state, changes it
  (coordinator/speculation.py). Where it does wait, the runs it will call for are
  launched meanwhile, worked out on a copy of the algorithm (``_launch_past_holds``):
  used only if still drawn when the head gets there, so results never depend on them.
- The streak is the index range after the last change. A round ends when N_eps
  consecutive indices of it are resolved (exact or replaced) and quiet: the head stops
  at its end and waits for the streak's replacements. Batches in flight and replacements
  of indices before the streak are then dropped, their indices re-used: the committed
  sequence depends on the config and seed alone.
- At a round end the driver decays the algorithm's resolution and runs experience
  replay: the algorithm names its stored runs, the executor screens them where they are,
  the algorithm applies what is new.
- With ``certify``, the last round is certification (the final set checked as validate
  checks it): closing rounds and checks (coordinator/certification.py), or every final
  centre once for a deterministic system. A closing round's change restarts its count; a
  check's change ends the check and a closing round follows. A campaign of one round
  (delta0 = delta_min) certifies from its first run.
"""

from __future__ import annotations

import bisect
import dataclasses
import time
from collections import deque
from dataclasses import asdict, dataclass, field
from typing import Callable, Iterable

import numpy as np

from coordinator.adversary import AdversarySearch
from coordinator.algorithm import Algorithm, Event
from coordinator import certification
from coordinator.commit_log import CommitLog
from coordinator.coverage import Rescreen
from coordinator.executor import Chunk, Executor
from coordinator.replacements import Held, Replacement, ReplacementGroup
from coordinator.sample_size import n_eps
from coordinator.speculation import Speculations
from coordinator.stable_sampler import Draws
from scenarios.base import FAILURE, OUTCOME_NAMES, TRUNCATED
from scenarios.errors import ConfigError
from scenarios.streams import RunStreams

COUNTING = ("sequential", "deferred")
VERIFY_BLOCK = 64  # runs checked for exactness at once after a change (then 4x more each time)
MAX_VERIFY_BLOCK = 1 << 16
LEAD_PER_WORKER = 4  # replacements launched this many runs per worker ahead of the head
WHAT_IF = True  # launch the runs a change waiting for holds will call for (never changes a result)
WHAT_IF_CHANGES = 8  # ... and, for slow runs, those of the changes after it, as far as results are in
WHAT_IF_RUN_S = 0.01  # [s] runs at least this long (as measured) for the first
WHAT_IF_CHAIN_RUN_S = 0.2  # [s] runs at least this long for the changes after it
# A deterministic system's certification (every centre once) draws, batch by batch, the
# next centres not drawn yet at the state the batch is drawn at: the order follows the
# batches. Under sequential counting they are these (the default window), whatever
# farm.batch_size and pipeline_depth say, so that those change no result there either.
ENUMERATION_BATCH = 1024
ENUMERATION_DEPTH = 2


@dataclass(frozen=True)
class CampaignSettings:
    """What the driver needs besides the algorithm and the executor (the config's
    quantify.epsilon, beta, budget, certify, certify_margin, farm.batch_size,
    pipeline_depth, counting, seed and record.quantify_runs)."""

    epsilon: float = 0.001
    beta: float = 0.1
    budget: int = 2_000_000
    batch_size: int = 1024
    pipeline_depth: int = 2
    seed: int = 0
    certify: bool = False
    record_limit: int = 0  # state-changing failures kept for the MCAP recording
    counting: str = "sequential"
    certify_margin: float = certification.MARGIN  # closing rounds aim at eps / margin

    def __post_init__(self):
        if self.counting not in COUNTING:
            raise ConfigError(f"farm.counting: {self.counting!r} is not allowed; allowed: {', '.join(COUNTING)}")

    @property
    def n_eps(self) -> int:
        """Quiet runs in a row that end a round (Lemma 2)."""
        return n_eps(self.epsilon, self.beta)

    @property
    def lag(self) -> int:
        """Indices after which a mispredicted run's replacement is applied."""
        return 0 if self.counting == "sequential" else self.batch_size * self.pipeline_depth

    def certification_quiet(self, attempt: int) -> int:
        """Quiet runs in a row that pass check ``attempt`` (1, 2, ...): beta split over the
        checks, so that the set finally exported keeps it."""
        return certification.check_quiet(self.epsilon, self.beta, attempt)

    def closing_quiet(self, share: float) -> int:
        """Quiet runs in a row that end a closing round over a band of ``share`` of the centres."""
        return certification.closing_quiet(self.epsilon, self.beta, self.certify_margin, share)


@dataclass
class Pending:
    """A batch of draws from ``first_index`` on, and its chunks fetched so far (kept until
    every run of the batch is committed for good: the head may go back into it)."""

    first_index: int
    draws: Draws
    starts: np.ndarray
    handles: list = field(default_factory=list)
    next_handle: int = 0
    chunks: list = field(default_factory=list)  # fetched, in index order (contiguous)
    ends: list = field(default_factory=list)  # each fetched chunk's end index

    def __len__(self) -> int:
        return len(self.draws)

    @property
    def end(self) -> int:
        return self.first_index + len(self.draws)

    def done(self, head: int) -> int:
        """Its runs before index ``head``."""
        return min(max(head - self.first_index, 0), len(self.draws))

    def chunk_at(self, index: int) -> Chunk | None:
        """The fetched chunk that holds run ``index``, if fetched."""
        at = bisect.bisect_right(self.ends, index)
        return self.chunks[at] if at < len(self.chunks) else None

    def fetched(self, chunk: Chunk) -> None:
        self.chunks.append(chunk)
        self.ends.append(chunk.first_index + len(chunk))


@dataclass
class Counters:
    """Where a campaign stands. Runs simulated and read back are committed (the head's
    runs, a discarded one included), replaced, or dropped (``runs_dropped``)."""

    committed: int = 0  # the head: the next sample index to commit (indices are contiguous)
    quiet: int = 0  # the N_eps counter: indices of the streak resolved and quiet
    streak_start: int = 0  # the first index after the last change
    escaped_in_streak: int = 0  # counted quiet runs that left Phi_delta near PhiBar
    changes: int = 0
    runs_simulated: int = 0
    steps_simulated: int = 0
    runs_discarded: int = 0  # mispredicted runs, discarded unseen (replacements that moved again too)
    runs_replaced: int = 0  # replacements applied
    rounds_completed: int = 0
    done: bool = False
    converged: bool = False  # the last round ended by the N_eps rule
    round_ends: list = field(default_factory=list)  # committed count at each round end
    elapsed_s: float = 0.0
    recorded: int = 0  # runs handed to the recorder so far
    attempts: int = 0  # sampled certification: checks begun; deterministic: 1 + changes while certifying
    certification_from: int = -1  # the committed count when certification began (-1: it did not)
    closing_ends: list = field(default_factory=list)  # committed count at each closing round's end
    truncations: list = field(default_factory=list)  # committed truncated runs per facet (Scenario.facets() order)

    def count_truncations(self, chunk: Chunk, rows: np.ndarray) -> None:
        """Add the truncated runs among the chunk's (used) ``rows``, by the facet they left
        Sigma through."""
        if chunk.exits is None:
            return
        left = chunk.exits[rows][chunk.outcomes[rows] == TRUNCATED]
        if len(left):
            counts = np.bincount(left, minlength=len(self.truncations))
            counts[: len(self.truncations)] += np.asarray(self.truncations, dtype=np.int64)
            self.truncations = counts.tolist()

    @property
    def runs_certification(self) -> int:
        """Committed runs since certification began (closing rounds and checks; for a
        deterministic system, its last round, which is its certification)."""
        return self.committed - self.certification_from if self.certification_from >= 0 else 0

    @property
    def runs_dropped(self) -> int:
        """Runs simulated whose results were not used: in flight at a round end."""
        return self.runs_simulated - self.committed - self.runs_replaced


Observer = Callable[["Campaign"], None]


class Campaign:
    """Drive ``algorithm`` with ``executor`` until the last round ends by the N_eps rule
    or ``settings.budget`` indices are committed. ``observers`` are called after every
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
        self.replacements: deque[Replacement] = deque(restored.replacements if restored is not None else ())
        self.final_distribution = restored.final_distribution if restored is not None else ""
        self.log = CommitLog()
        self.recordings: list[dict] = []  # runs to record, since the last flush
        # replacements to submit at the next chunk boundary (read back ones are re-simulated)
        self._unsent: list[Replacement] = list(self.replacements)
        # runs launched ahead for in-flight draws a change moved, by index: a mispredicted
        # run's replacement, simulated before the head asks for it
        self._ahead: dict[int, Replacement] = {}
        self._changes_seen = self.counters.changes
        self._ahead_to = 0  # launched ahead up to this index (when nothing changed since)
        self.launched_past_holds = 0  # runs launched for a change waiting for holds (a statistic)
        self.held = Held()  # replacements the head committed past before they were back
        self.speculations = Speculations()  # changes applied past holds, and the state before each
        self._rewound = False  # a held replacement changed the state: the head went back
        self._stop = False
        self._law_switched = False  # a check failed: the runs in flight were drawn by its law

    @property
    def n_eps(self) -> int:
        return self.settings.n_eps

    def _streams(self, indices) -> RunStreams:
        return RunStreams.of(self.settings.seed, np.asarray(indices, dtype=np.uint64))

    # -- drawing ------------------------------------------------------------------------
    def _next_draw_index(self) -> int:
        if self.pending:
            return self.pending[-1].end
        return self.counters.committed

    def _fill(self) -> None:
        """Keep ``pipeline_depth`` batches drawn and submitted ahead of the head (fewer
        when the budget ends; ``ENUMERATION_DEPTH`` of ``ENUMERATION_BATCH`` while a
        deterministic certification enumerates); batches the head has passed but may go
        back into do not count."""
        s, algo = self.settings, self.algorithm
        batch, depth = s.batch_size, s.pipeline_depth
        if s.lag == 0 and algo.enumerates:  # fixed batches (ENUMERATION_BATCH), never the workers
            batch, depth = ENUMERATION_BATCH, ENUMERATION_DEPTH
        elif s.lag == 0:
            # sequential counting: the batch size changes no sampled run, so it follows the
            # workers (but no more than the round's quiet runs: runs in flight past a round's
            # end are dropped, and each is a draw a change can move; docs/benchmarks.md,
            # "2026-11-26, morning": many workers of short runs)
            batch = min(self.executor.batch_size(s.batch_size), max(s.batch_size, self.quiet_needed()))
        head = self.counters.committed
        ahead = sum(1 for p in self.pending if p.end > head)
        while ahead < depth:
            first = self._next_draw_index()
            size = min(batch, s.budget - first)
            if size <= 0:
                break
            draws = algo.draw(self._streams(np.arange(first, first + size)))
            self.pending.append(Pending(first, draws, algo.vertices.points[draws.ids]))  # may be < size
            ahead += 1
        for p in self.pending:
            if not p.handles and not p.chunks:
                done = p.done(head)
                p.handles = self.executor.submit(p.first_index + done, p.starts[done:], algo.coverage,
                                                 actions=self._actions())
        self._launch_ahead()
        self._send_replacements()

    def _actions(self) -> dict | None:
        return self.adversary.policy.state() if self.adversary is not None else None

    # -- exact or replaced -----------------------------------------------------------------
    def _verify(self, p: Pending, lo: int, hi: int) -> np.ndarray:
        """(hi - lo,) bool: which runs ``lo:hi`` of batch ``p`` are exact now: their streams
        draw their starts. A stream whose current draw a change may have moved is drawn
        again (and its current draw kept: a start the set moved away from is not drawn
        again until a change touches what its stream draws now)."""
        algo = self.algorithm
        span = p.draws.span(lo, hi)
        moved = algo.moved(span)
        exact = span.now == span.ids
        if moved.any():
            exact[moved], _ = self._redraw(p, lo + np.flatnonzero(moved))
        return exact

    def _redraw(self, p: Pending, rows: np.ndarray) -> tuple[np.ndarray, Draws]:
        """Draw runs ``rows`` of batch ``p`` again: -> (still their starts, the fresh draws);
        the fresh draws become their current ones (later checks start from now)."""
        fresh = self.algorithm.draw(self._streams(p.first_index + rows))
        p.draws.track(rows, fresh)
        # the start too: after the algorithm went back to a copy (coordinator/speculation.py)
        # an id may name another centre than the one the run was launched from
        same_id = fresh.ids == p.draws.ids[rows]
        same = same_id & (self.algorithm.vertices.points[fresh.ids] == p.starts[rows]).all(axis=1)
        p.draws.now[rows[same_id & ~same]] = -1  # its stream draws another start under that id
        return same, fresh

    def _replace(self, index: int) -> None:
        """Launch the replacement of run ``index`` from its stream's current draw, due
        ``lag`` indices after the head (a run launched ahead for that draw is taken)."""
        c = self.counters
        due = max(index, c.committed - 1) + self.settings.lag
        ahead = self._ahead.pop(index, None)
        if ahead is not None and self._still_drawn(ahead):
            ahead.due = due
            self._queue(ahead)
        else:
            draws = self.algorithm.draw(self._streams([index]))
            replacement = Replacement(index, draws, self.algorithm.vertices.points[draws.ids[0]], due)
            self._queue(replacement)
            self._unsent.append(replacement)
        c.runs_discarded += 1

    def _queue(self, r: Replacement) -> None:
        """Queue ``r`` in due order (then index order: a replacement drawn again keeps its place)."""
        at = len(self.replacements)
        while at and (self.replacements[at - 1].due, self.replacements[at - 1].index) > (r.due, r.index):
            at -= 1
        self.replacements.insert(at, r)

    def _still_drawn(self, r: Replacement) -> bool:
        """Is ``r``'s start what its stream draws now?"""
        algo = self.algorithm
        if not algo.moved(r.draws)[0]:
            return True
        fresh = algo.draw(self._streams([r.index]))
        if fresh.ids[0] != r.draws.ids[0]:
            return False
        # (a run launched for a change not applied yet may name a centre that the change
        # would have inserted under that id: its start must be the centre's too)
        if not np.array_equal(r.start, algo.vertices.points[fresh.ids[0]]):
            return False
        r.draws = fresh  # renewed: later checks start from now
        return True

    def _launch_past_holds(self, event: Event) -> None:
        """The head waits at a change for replacements it passed: launch now the runs the
        change will call for if they come back quiet (most do), worked out on a copy of
        the algorithm with the change applied; then, as far as results are in, the same
        for the changes that follow it there (up to ``WHAT_IF_CHANGES``; a run whose
        start the copy would move counts as quiet: its replacement is not back). Launched
        as runs ahead, with draws not known: each is used only if it is what its stream
        draws when the head needs it, start included (``_still_drawn``), so results never
        depend on it."""
        algo, run_s = self.algorithm, self.executor.run_seconds()
        if not WHAT_IF or run_s is None or run_s < WHAT_IF_RUN_S or algo.enumerates or (
                algo.certifying and not algo.closing):
            return
        what_if = algo.copy()
        # each change worked out costs the driver a few milliseconds and a call per run it
        # launches, and saves up to a run's time (docs/benchmarks.md, "2026-11-26, later
        # morning"): not at all for fast runs, further ahead for slow ones
        for _ in range(WHAT_IF_CHANGES if run_s >= WHAT_IF_CHAIN_RUN_S else 1):
            what_if.apply(event)
            drawn = self._launch_moved(what_if, event.index + 1)
            event = self._next_change(what_if, event.index + 1, drawn)
            if event is None:
                break
        self._send_replacements()

    def _launch_moved(self, what_if: Algorithm, head: int) -> dict:
        """Launch the runs in flight within the lead of ``head`` whose starts ``what_if``
        moves. Returns what ``what_if`` draws there: batch -> (first row, vertex ids)."""
        end = head + self._lead()
        drawn = {}
        for p in self.pending:
            lo, hi = max(p.done(head), head - p.first_index), min(len(p), end - p.first_index)
            if not p.handles or lo >= hi:
                continue
            rows = np.arange(lo, hi)
            fresh = what_if.draw(self._streams(p.first_index + rows))
            drawn[id(p)] = (lo, fresh.ids)
            for k in np.flatnonzero(fresh.ids != p.draws.ids[rows]):
                start_id = fresh.ids[k : k + 1].copy()
                if self._launch_run(int(p.first_index + rows[k]), Draws.unknown(start_id),
                                    what_if.vertices.points[start_id[0]].copy()):
                    self.launched_past_holds += 1
        return drawn

    def _next_change(self, what_if: Algorithm, index: int, drawn: dict) -> Event | None:
        """The first run from ``index`` on that changes ``what_if``'s state, among the runs
        back (fetched in order, without waiting) and drawn as ``what_if`` draws them
        (``drawn``, from ``_launch_moved``); None when the results in end first (or the
        draws worked out, or a round's quiet runs)."""
        last = self.counters.committed + self.quiet_needed()
        while index < last:
            p = next((q for q in self.pending if q.first_index <= index < q.end), None)
            if p is None or id(p) not in drawn:
                return None
            chunk = p.chunk_at(index)
            if chunk is None:
                if p.next_handle >= len(p.handles) or not self.executor.ready(p.handles[p.next_handle]):
                    return None
                self._fetch_next(p)
                continue
            at = index - chunk.first_index
            lo, ids = drawn[id(p)]
            first, last_row = index - p.first_index, chunk.first_index + len(chunk) - p.first_index
            if first < lo or last_row > lo + len(ids):
                return None
            allowed = np.zeros(len(chunk), dtype=bool)
            allowed[at:] = ids[first - lo : last_row - lo] == p.draws.ids[first:last_row]
            rescreen = Rescreen(what_if.coverage, chunk.screening, chunk.outcomes, chunk.visited)
            row = rescreen.next_event(at, allowed)
            if row < len(chunk):
                k = chunk.first_index - p.first_index + row
                return _event(chunk.first_index + row, chunk, row, p.starts[k], p.draws.ids[k], rescreen)
            index = chunk.first_index + len(chunk)
        return None

    def _launch_ahead(self) -> None:
        """Draws in flight near the head that a change moved: launch their replacements
        now, so that the head finds them done. Only within ``_lead()`` indices of the head:
        farther ones may move again before the head needs them. (Results never depend on
        this: a run is used only if it is what its stream draws when its index is committed.)"""
        algo, head = self.algorithm, self.counters.committed
        for index in [i for i in self._ahead if i < head]:  # the head passed them unused
            del self._ahead[index]
        changed = self.counters.changes != self._changes_seen
        self._changes_seen = self.counters.changes
        start = head if changed else max(head, self._ahead_to)
        end = head + self._lead()
        self._ahead_to = end
        for p in self.pending:
            lo, hi = max(p.done(head), start - p.first_index), min(len(p), end - p.first_index)
            if not p.handles or lo >= hi:
                continue
            flagged = lo + np.flatnonzero(algo.moved(p.draws.span(lo, hi)))
            if len(flagged) == 0:
                continue
            same, fresh = self._redraw(p, flagged)
            for k in np.flatnonzero(~same):
                self._launch_run(int(p.first_index + flagged[k]), fresh.rows(np.array([k])),
                                 algo.vertices.points[fresh.ids[k]])

    def _launch_run(self, index: int, draws: Draws, start: np.ndarray) -> bool:
        """Launch a run ahead for index ``index`` from ``start`` (its draw ``draws``),
        unless one from that start is launched already. True if launched."""
        known = self._ahead.get(index)
        if known is not None and known.draws.ids[0] == draws.ids[0] and np.array_equal(known.start, start):
            return False
        self._ahead[index] = r = Replacement(index, draws, start, index)
        self._unsent.append(r)
        return True

    def _lead(self) -> int:
        """How far ahead of the head replacements are launched: a few rounds of every
        worker's run (the head commits about a run per worker in a run's time)."""
        return max(self.settings.batch_size, LEAD_PER_WORKER * self.executor.workers)

    def _send_replacements(self) -> None:
        """Submit the replacements launched since the last call, as one batch."""
        if not self._unsent:
            return
        batch, self._unsent = self._unsent, []
        indices = np.array([r.index for r in batch], dtype=np.int64)
        group = ReplacementGroup(self.executor.submit(int(indices[0]), np.stack([r.start for r in batch]),
                                                      self.algorithm.coverage, actions=self._actions(),
                                                      indices=indices))
        for position, r in enumerate(batch):
            r.group, r.position = group, position

    def _take(self, group: ReplacementGroup) -> None:
        """Fetch the next chunk of ``group`` (its handle is dropped only once it is read:
        a stop while waiting leaves the group as it was)."""
        c = self.counters
        chunk = self.executor.result(group.handles[0])
        group.handles.pop(0)
        c.runs_simulated += len(chunk)
        c.steps_simulated += chunk.steps
        group.fetched(chunk)

    def _fetch(self, r: Replacement) -> tuple[Chunk, int]:
        """Wait for replacement ``r``'s run: its chunk and row."""
        if r.group is None:
            self._send_replacements()
        found = r.group.find(r.position)
        while found is None:
            self._take(r.group)
            found = r.group.find(r.position)
        return found

    def _back(self, r: Replacement) -> bool:
        """Is replacement ``r``'s run back (fetched without waiting for a worker)?"""
        if r.group is None:
            self._send_replacements()
        group = r.group
        while group.find(r.position) is None:
            if not group.handles or not self.executor.ready(group.handles[0]):
                return False
            self._take(group)
        return True

    # -- holds -------------------------------------------------------------------------------
    def _settle(self, wait: bool) -> bool:
        """Apply the held replacements, oldest first: those that are back (all of them,
        waiting, with ``wait``). True if one changed the state (the head went back)."""
        while self.held:
            r = self.held.first.replacement
            if not wait and not self._back(r):
                return False
            chunk, row = self._fetch(r)  # a stop while waiting leaves the hold in place
            if self._use_replacement(r, chunk, row, held=True):
                return True
        return False

    def _rewind_to_first_hold(self) -> None:
        """The first hold's replacement changes the state: back to just after its index."""
        hold, later = self.held.rewind(self.counters)
        head = self.counters.committed
        kept = {id(r) for r in hold.queue}
        dropped = later + [r for r in self.replacements if id(r) not in kept]
        self.replacements = deque(hold.queue)
        for r in dropped:  # drawn for indices the head commits again: launched ahead, if still drawn then
            if r.index >= head and r.index not in self._ahead:
                self._ahead[r.index] = r
        self._rewound = True

    # -- committing ------------------------------------------------------------------------
    def _streak_complete(self) -> bool:
        c = self.counters
        return c.committed - c.streak_start >= self.quiet_needed()

    def _finish_streak(self) -> bool:
        """The head is at the streak's end: apply the held replacements and then the
        streak's queued ones, in due order. True if every index of the streak is resolved
        and quiet (the round ends); False if one changed the state (the streak starts again)."""
        c = self.counters
        if self._settle(wait=True):
            return False
        while True:
            waiting = [r for r in self.replacements if r.index >= c.streak_start]
            if not waiting:
                return True
            if self._apply_replacement(waiting[0]):
                return False

    def _resolve_all(self) -> bool:
        """The budget is spent: every committed index gets its run, so apply the
        replacements still pending (as a one-run-at-a-time campaign would have run them).
        False if a held one changed the state (the head went back below the budget)."""
        if self._settle(wait=True):
            return False
        while self.replacements:
            self._apply_replacement(self.replacements[0])
        return True

    def _apply_due(self) -> None:
        """The replacements due before the head's index: applied if back and nothing is
        held, else held (the head commits on past them)."""
        c = self.counters
        while self.replacements and self.replacements[0].due < c.committed:
            r = self.replacements[0]
            if not self._still_drawn(r):  # a change since moved it: replaced again, unseen
                self.replacements.popleft()
                self._replace(r.index)
            elif self.held or not self._back(r):
                self.replacements.popleft()
                self.held.hold(r, c, self.replacements)
            else:
                self._apply_replacement(r)

    def _apply_replacement(self, r: Replacement) -> bool:
        """Use queued replacement ``r`` as the run of its index if it is still what its
        stream draws now, else replace it again (unseen). True if it changed the state."""
        if not self._still_drawn(r):
            self.replacements.remove(r)
            self._replace(r.index)
            return False
        chunk, row = self._fetch(r)  # a stop while waiting leaves it queued
        self.replacements.remove(r)
        return self._use_replacement(r, chunk, row)

    def _use_replacement(self, r: Replacement, chunk: Chunk, row: int, held: bool = False) -> bool:
        """Replacement ``r``'s run (``chunk``, ``row``) as the run of its index; ``held``:
        it is the first hold (the head went past it). True if it changed the state."""
        algo, c = self.algorithm, self.counters
        # a hold is judged at the state as the head passed it (changes applied past it since
        # are undone if it changes the state: coordinator/speculation.py)
        past = self.speculations.first if held and self.speculations else None
        if past is None:
            judged = self._rescreen(chunk)
        else:
            judged = Rescreen(past.algorithm.coverage, chunk.screening, chunk.outcomes, chunk.visited)
        start_id = r.draws.ids[:1]
        changes = judged.next_event(row) == row
        if held and changes:
            if past is not None:
                self._undo_speculations()
                judged = self._rescreen(chunk)  # the state it was judged at, restored: decided there again
                judged.next_event(row)
            self._rewind_to_first_hold()
        counted = not changes and r.index >= (past.streak_start if past is not None else c.streak_start)
        escaped = int(chunk.screening.escaped[row]) if counted else 0
        c.runs_replaced += 1
        if changes:
            self._change(_event(r.index, chunk, row, r.start, start_id[0], judged), chunk, row)
        elif counted and past is None:  # (past a change, the streak it counts in has ended)
            c.quiet += 1
            c.escaped_in_streak += escaped
        self._log_rows(chunk, np.array([row]), r.index, r.start[None, :], start_id, CommitLog.REPLACEMENT,
                       np.array([changes]), np.array([counted]), now=True)
        if held and not changes:
            self.held.applied_quiet({"runs_replaced": 1, "quiet": int(counted), "escaped_in_streak": escaped},
                                    streak_until=None if past is None else past.index)
            self.speculations.settle(self.held)
        return changes

    def _undo_speculations(self) -> None:
        """The first hold changes the state, and changes were applied past it: the
        algorithm and the counters go back to how they stood before the first of them,
        and so do the recordings (the head goes back to the hold next)."""
        first = self.speculations.undo(self.algorithm, self.counters)
        self.recordings = [r for r in self.recordings if r["sample_index"] < first.index]
        self._changes_seen = -1  # every draw in flight is looked at again

    def _change(self, event: Event, chunk: Chunk, row: int) -> None:
        """Apply a run that changes the state; the streak starts again at the head."""
        algo, c = self.algorithm, self.counters
        algo.apply(event)
        self._maybe_record(chunk, row, event.index, event.start)
        if algo.enumerates:
            c.attempts += 1
        elif algo.certifying and not algo.closing:  # the check failed: close again (spends no beta)
            algo.begin_closing()
            self._law_switched = True
        c.quiet = 0
        c.escaped_in_streak = 0
        c.changes += 1
        c.streak_start = c.committed  # runs before the head were decided at the old state

    def _rescreen(self, chunk: Chunk) -> Rescreen:
        """The chunk's runs re-decided at the current coverage: one per chunk, kept with it
        (what it found stands until the coverage changes)."""
        coverage = self.algorithm.coverage
        if chunk.rescreen is None or chunk.rescreen.coverage is not coverage:
            chunk.rescreen = Rescreen(coverage, chunk.screening, chunk.outcomes, chunk.visited)
        return chunk.rescreen

    def _commit(self, p: Pending, chunk: Chunk) -> bool:
        """Commit runs of one chunk of batch ``p`` in index order, from the head's index
        (``counters.committed``, the head, walks its indices) to the chunk's end, or until
        the head goes back (a held replacement changed the state). True if the round ended."""
        algo, c = self.algorithm, self.counters
        at = chunk.first_index - p.first_index
        k = len(chunk)
        starts, ids = p.starts[at : at + k], p.draws.ids[at : at + k]
        rescreen = self._rescreen(chunk)
        kind = np.zeros(k, dtype=np.int8)
        changed = np.zeros(k, dtype=bool)
        counted = np.zeros(k, dtype=bool)
        pos = c.committed - chunk.first_index
        ended, block, logged = False, VERIFY_BLOCK, pos

        def log_upto(end: int) -> int:
            """Log rows [logged, end): runs are logged (and stored for experience replay) in
            the order they are committed, replacements in between. Called before anything
            that may wait: a stop then finds the ledger and the head in step."""
            rows = np.arange(logged, end)
            self._log_rows(chunk, rows, chunk.first_index + logged, starts[rows], ids[rows], kind[rows],
                           changed[rows], counted[rows])
            return end

        def event_at(row: int) -> Event:
            return _event(chunk.first_index + row, chunk, row, starts[row], ids[row], rescreen)

        while pos < k and not self._law_switched:
            if algo.enumerates:  # every centre once: any quiet run whose witnesses hold counts
                offset = algo.next_event(rescreen, pos, ids) - pos
                quiet = np.arange(pos, pos + offset)
                done = algo.certify_runs(ids[quiet], lambda rows: rescreen.witnesses(quiet[rows]))
                if done >= 0:
                    offset, ended = done + 1, True
                counted[pos : pos + offset] = algo.vertices.alive[ids[pos : pos + offset]]
                pos += offset
                c.committed += offset
                if ended or pos == k:
                    break
            else:
                if self._streak_complete():
                    logged = log_upto(pos)
                    ended = self._finish_streak()
                    if ended or self._rewound:
                        break
                    continue
                if c.committed >= self.settings.budget:
                    break
                if self.replacements and self.replacements[0].due < c.committed:
                    logged = log_upto(pos)
                    self._apply_due()
                    continue
                # exact runs from pos on, up to the streak's end and the next due replacement
                limit = min(k, pos + block, pos + self.quiet_needed() - (c.committed - c.streak_start))
                if self.replacements:
                    limit = min(limit, pos + self.replacements[0].due + 1 - c.committed)
                exact = self._verify(p, at + pos, at + limit)
                bad = pos + (len(exact) if exact.all() else int(np.argmin(exact)))
                event = algo.next_event(rescreen, pos, ids)
                stop = min(bad, event)
                counted[pos:stop] = True
                c.quiet += stop - pos
                c.escaped_in_streak += int(np.count_nonzero(chunk.screening.escaped[pos:stop]))
                c.committed += stop - pos
                pos = stop
                if pos == limit:  # quiet and exact up to the limit: look further at once next time
                    block = min(4 * block, MAX_VERIFY_BLOCK)
                    continue
                block = VERIFY_BLOCK
                if pos == bad:  # mispredicted: discarded unseen, replaced
                    c.committed += 1
                    kind[pos] = CommitLog.DISCARDED
                    # sent with this pass's others (at the next fill, or when the head
                    # needs one): a call per pass, not per misprediction, since a chunk
                    # costs the driver and its worker about the same whatever its runs
                    self._replace(chunk.first_index + pos)
                    pos += 1
                    continue
                change = event_at(pos)
                if self.held:  # a change: only once every replacement before it is applied ...
                    logged = log_upto(pos)
                    if self._settle(wait=False):
                        break
                    if self.held and self.speculations.allowed(algo, self.executor.run_seconds(), self.settings.lag):
                        self.speculations.take(change.index, algo, c)  # ... or applied now, undone if one changes it
                    elif self.held:
                        self._launch_past_holds(change)
                        if self._settle(wait=True):
                            break
            c.committed += 1
            self._change(event_at(pos) if algo.enumerates else change, chunk, pos)
            changed[pos] = True
            pos += 1
        if self._rewound:  # the rows from the hold on are committed again
            self._rewound = False
            return False
        log_upto(pos)
        return ended

    def _log_rows(self, chunk: Chunk, rows: np.ndarray, first_index: int, starts: np.ndarray, ids: np.ndarray,
                  kind, changed: np.ndarray, counted: np.ndarray, now: bool = False) -> None:
        """Rows ``rows`` of ``chunk``, committed or discarded as indices ``first_index,
        first_index + 1, ...`` (``starts``, ``ids``: theirs): to the ledger; the runs used
        also to experience replay and the adversary. Held until the holds before them are
        applied, unless ``now`` (the first hold's own run)."""
        if len(rows) == 0:
            return
        algo = self.algorithm
        kind = np.broadcast_to(np.asarray(kind, dtype=np.int8), (len(rows),))
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

    def _maybe_record(self, chunk: Chunk, row: int, index: int, start: np.ndarray) -> None:
        """Keep the trajectory of a state-changing failure for the MCAP recording (the
        runs worth looking at), up to ``record_limit`` per campaign."""
        c = self.counters
        if c.recorded >= self.settings.record_limit or chunk.outcomes[row] != FAILURE:
            return
        self.recordings.append({"sample_index": index, "trajectory": chunk.trajectory(row, start),
                                "outcome": OUTCOME_NAMES[int(chunk.outcomes[row])]})
        c.recorded += 1

    # -- the loop -------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to return at the next chunk boundary (e.g. on SIGINT)."""
        self._stop = True

    @property
    def stopping(self) -> bool:
        return self._stop

    def _at_head(self) -> tuple[Pending, Chunk] | None:
        """The batch and fetched chunk that hold the head's run (fetching, in order, the
        chunks up to it); None when no batch is drawn there (the budget is spent)."""
        head = self.counters.committed
        p = next((q for q in self.pending if q.first_index <= head < q.end), None)
        if p is None:
            return None
        chunk = p.chunk_at(head)
        while chunk is None:
            chunk = self._fetch_next(p)
            if not chunk.first_index <= head < chunk.first_index + len(chunk):
                chunk = None
        return p, chunk

    def _fetch_next(self, p: Pending) -> Chunk:
        """Fetch batch ``p``'s next chunk (waiting for it), in index order."""
        chunk = self.executor.result(p.handles[p.next_handle])
        p.next_handle += 1
        self.counters.runs_simulated += len(chunk)
        self.counters.steps_simulated += chunk.steps
        p.fetched(chunk)
        return chunk

    def _release(self) -> None:
        """Drop the batches whose every run is committed for good (the head cannot go back
        into them: they end before the first hold's index)."""
        final = self.held.first.counts["committed"] if self.held else self.counters.committed
        while self.pending and self.pending[0].end <= final:
            self.pending.popleft()

    def run(self) -> Counters:
        c = self.counters
        started = time.monotonic() - c.elapsed_s
        if c.committed == 0 and not self.pending:
            self._certify_at_once()  # delta0 = delta_min: the first round is the last
        while not c.done and not self._stop:
            self._fill()
            self._settle(wait=False)
            if self._rewound:
                self._rewound = False
                continue
            located = self._at_head() if c.committed < self.settings.budget else None
            if located is None:  # the budget is spent
                if self._resolve_all():
                    c.done = True  # budget exhausted before the last round converged
                    break
                self._rewound = False
                continue
            if self._commit(*located):
                self._end_round()
            elif self._law_switched:
                # every draw in flight is moved by the new law: drop them as a round end does
                # (their indices are drawn again, as their replacements would have been)
                self._law_switched = False
                self._drop_in_flight()
            else:
                self._release()
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
        if algo.closing:  # a closing round ended: check the set (within the certification round)
            c.closing_ends.append(c.committed)
            algo.begin_check()
            c.attempts += 1
        else:
            c.round_ends.append(c.committed)
            c.rounds_completed += 1
            # a last round run by SPE's rule: a checkpoint written before certification took
            # the last round's place, resumed
            if algo.final_round and self.certify and not algo.certifying:
                self._next_mixture()
                self._certify_at_once()
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
        c.streak_start = c.committed

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
        """Indices in a row that must be resolved and quiet to end the current round."""
        if self.algorithm.closing:
            return self.settings.closing_quiet(self.algorithm.closing_share())
        if self.algorithm.certifying:
            return self.settings.certification_quiet(max(self.counters.attempts, 1))
        return self.settings.n_eps

    def _certify_at_once(self) -> None:
        """With ``certify``, the last round (at delta_min) is the certification itself.
        A deterministic system runs every final centre once (VAL^delta): exact, so the
        N_eps rule's epsilon-almost statement, and the runs spent on it, would add nothing.
        A sampled system starts with a closing round: it prunes and explores as SPE's last
        round would, but strictly and over the band where the violations are, so the set
        is not first settled by the lenient rule and then settled again (the runs that
        saves: docs/certification.md). Only the checks certify (docs/guarantee.md), so how
        the set they check came about does not touch the guarantee. Called as the last
        round begins (for a campaign of one round: as it starts)."""
        algo = self.algorithm
        if self.certify and algo.final_round and not algo.certifying:
            algo.begin_certification()
            if algo.deterministic:
                self.counters.attempts = 1
            self.counters.certification_from = self.counters.committed

    def _drop_in_flight(self) -> None:
        """Batches in flight and replacements not yet applied are dropped; their indices
        are drawn again."""
        for q in self.pending:
            for handle in q.handles[q.next_handle :]:
                self.executor.cancel(handle)
        self.pending.clear()
        groups = {id(r.group): r.group for r in [*self.replacements, *self._ahead.values()] if r.group is not None}
        for group in groups.values():
            for handle in group.handles:
                self.executor.cancel(handle)
        self.replacements.clear()
        self.held.clear()
        self.speculations.clear()
        self._unsent = []
        self._ahead.clear()

    # -- persistence --------------------------------------------------------------------
    def committed_algorithm(self) -> Algorithm:
        """The algorithm as ``state()`` has the driver: as the head passed the first hold
        (a copy, while changes are applied past it)."""
        return self.speculations.committed(self.algorithm)

    def take_recordings(self) -> list[dict]:
        """The recordings of runs committed for good since the last take (those past a
        change applied past holds stay until it is settled)."""
        if not self.speculations:
            taken, self.recordings = self.recordings, []
            return taken
        until = self.speculations.first.index
        taken = [r for r in self.recordings if r["sample_index"] < until]
        self.recordings = [r for r in self.recordings if r["sample_index"] >= until]
        return taken

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """The driver's state: arrays (the draws not yet committed and the replacements
        not yet applied, so that a resumed campaign re-simulates exactly them) and
        JSON-able metadata (the counters). With holds, the state as the head passed the
        first of them (what follows it is not committed for good)."""
        counters, replacements = self.counters, list(self.replacements)
        if self.held:
            hold = self.held.first
            counters = dataclasses.replace(self.counters, **hold.counts, **self.speculations.committed_counts())
            replacements = [hold.replacement, *hold.queue]
        head = counters.committed
        open_ = [p for p in self.pending if p.end > head]
        arrays = {"pending.count": np.array(len(open_))}
        for i, p in enumerate(open_):
            done = p.done(head)
            arrays[f"pending.{i}.first_index"] = np.array(p.first_index + done)
            arrays[f"pending.{i}.starts"] = p.starts[done:]
            arrays[f"pending.{i}.start_ids"] = p.draws.ids[done:]
            arrays[f"pending.{i}.fixed"] = np.array(p.draws.fixed)
        n = self.algorithm.coverage.n
        arrays["replacements.index"] = np.array([r.index for r in replacements], dtype=np.int64)
        arrays["replacements.start_id"] = np.array([r.draws.ids[0] for r in replacements], dtype=np.int64)
        arrays["replacements.start"] = np.stack([r.start for r in replacements]) if replacements else np.empty((0, n))
        arrays["replacements.due"] = np.array([r.due for r in replacements], dtype=np.int64)
        meta = {"counters": asdict(counters), "final_distribution": self.final_distribution}
        return arrays, meta



def _event(index: int, chunk: Chunk, row: int, start: np.ndarray, start_id, rescreen: Rescreen) -> Event:
    """Run ``row`` of ``chunk`` (sample index ``index``, from ``start``, vertex ``start_id``)
    as the change it makes at ``rescreen``'s coverage."""
    return Event(index, start, int(start_id), bool(chunk.outcomes[row] == FAILURE),
                 rescreen.candidates(row), *rescreen.classification(row))

@dataclass
class DriverState:
    """A campaign driver's state read back from ``Campaign.state()``'s output, to start a
    ``Campaign`` where a checkpoint left off. Draws read back are checked again before
    they are used (their examined slots are not kept)."""

    counters: Counters
    pending: list[Pending]
    replacements: list[Replacement]
    final_distribution: str = ""

    @classmethod
    def read(cls, arrays: dict[str, np.ndarray], meta: dict) -> "DriverState":
        """Raises KeyError, TypeError or ValueError when the checkpoint is damaged."""
        pending = []
        for i in range(int(arrays["pending.count"])):
            ids = arrays[f"pending.{i}.start_ids"].astype(np.int64)
            fixed = bool(arrays[f"pending.{i}.fixed"]) if f"pending.{i}.fixed" in arrays else False
            pending.append(Pending(int(arrays[f"pending.{i}.first_index"]), Draws.unknown(ids, fixed),
                                   arrays[f"pending.{i}.starts"]))
        replacements = [Replacement(int(index), Draws.unknown(np.array([start_id], dtype=np.int64)), start, int(due))
                        for index, start_id, start, due in zip(arrays["replacements.index"],
                                                               arrays["replacements.start_id"],
                                                               arrays["replacements.start"], arrays["replacements.due"])]
        return cls(Counters(**meta["counters"]), pending, replacements, meta.get("final_distribution", ""))
