"""Runs launched before the commit head asks for them. Its one promise: it never changes
a result. Each run launched here waits in the replacement queue's ``ahead``
(coordinator/driver/replacements.py) and is used only if it is what its stream draws, start
included, when the head needs a replacement for its index; otherwise it is simulated for
nothing. A test switches it off (``CampaignSettings.look_ahead``) and compares hashes.

Two kinds:
- draws in flight near the head that a change moved: their replacements, launched now
  so that the head finds them done (``launch_moved``);
- while a change waits for the holds before it: the runs it will call for if they come
  back quiet (most do), worked out on a copy of the algorithm with the change applied, and,
  for slow runs, those of the changes after it as far as results are in (``past_holds``).
"""

from __future__ import annotations

import numpy as np

from coordinator.algorithm import Algorithm, Event
from coordinator.rescreen import Rescreen
from coordinator.driver.exact import redraw
from coordinator.stable_sampler import Draws

LEAD_PER_WORKER = 4  # replacements launched this many runs per worker ahead of the head
WHAT_IF_CHANGES = 8  # changes worked out past holds, for slow runs, as far as results are in
WHAT_IF_RUN_S = 0.01  # [s] runs at least this long (as measured) for the first
WHAT_IF_CHAIN_RUN_S = 0.2  # [s] runs at least this long for the changes after it


class LookAhead:
    def __init__(self, enabled: bool, launcher, pipeline, queue, counters, batch_size: int):
        self.enabled = enabled
        self.launcher, self.pipeline, self.queue, self.counters = launcher, pipeline, queue, counters
        self.batch_size = batch_size
        self._changes_seen = counters.changes
        self._ahead_to = 0  # launched ahead up to this index (when nothing changed since)
        self.launched_past_holds = 0  # runs launched for a change waiting for holds (a statistic)

    def lead(self) -> int:
        """How far ahead of the head runs are launched: a few rounds of every worker's run
        (the head commits about a run per worker in a run's time); farther draws may move
        again before the head needs them."""
        return max(self.batch_size, LEAD_PER_WORKER * self.launcher.workers)

    def forget(self) -> None:
        """The algorithm went back to a copy: every draw in flight is looked at again."""
        self._changes_seen = -1

    def launch_moved(self) -> None:
        """Draws in flight within ``lead()`` of the head that a change moved: launch their
        replacements now."""
        head = self.counters.committed
        self.queue.forget_ahead_before(head)
        if not self.enabled:
            return
        changed = self.counters.changes != self._changes_seen
        self._changes_seen = self.counters.changes
        start = head if changed else max(head, self._ahead_to)
        end = head + self.lead()
        self._ahead_to = end
        algorithm = self.launcher.algorithm
        for p in self.pipeline:
            lo, hi = max(p.done(head), start - p.first_index), min(len(p), end - p.first_index)
            if not p.handles or lo >= hi:
                continue
            flagged = lo + np.flatnonzero(algorithm.moved(p.draws.span(lo, hi)))
            if len(flagged) == 0:
                continue
            same, fresh = redraw(self.launcher, p, flagged)
            for k in np.flatnonzero(~same):
                self.queue.launch_ahead(int(p.first_index + flagged[k]), fresh.rows(np.array([k])),
                                        self.launcher.starts(fresh.ids[k]))

    def past_holds(self, event: Event, quiet_until: int) -> None:
        """The head waits at change ``event`` for replacements it passed: launch the runs
        the change will call for, worked out on a copy of the algorithm with it applied;
        then, for slow runs, the same for the changes that follow it there (a run whose
        start the copy would move counts as quiet: its replacement is not back), up to
        index ``quiet_until`` (the round's quiet runs). Each change worked out costs the
        driver a few milliseconds and a call per run it launches, and saves up to a run's
        time: not worth it for fast runs (docs/benchmarks.md, "2026-11-26, later morning")."""
        run_s = self.launcher.run_seconds()
        if not self.enabled or run_s is None or run_s < WHAT_IF_RUN_S:
            return
        what_if = self.launcher.algorithm.copy()
        for _ in range(WHAT_IF_CHANGES if run_s >= WHAT_IF_CHAIN_RUN_S else 1):
            what_if.apply(event)
            drawn = self._launch_moved_by(what_if, event.index + 1)
            event = self._next_change(what_if, event.index + 1, drawn, quiet_until)
            if event is None:
                break
        self.queue.send()

    def _launch_moved_by(self, what_if: Algorithm, head: int) -> dict:
        """Launch the runs in flight within the lead of ``head`` whose starts ``what_if``
        moves. Returns what ``what_if`` draws there: batch -> (first row, vertex ids)."""
        end = head + self.lead()
        drawn = {}
        for p in self.pipeline:
            lo, hi = max(p.done(head), head - p.first_index), min(len(p), end - p.first_index)
            if not p.handles or lo >= hi:
                continue
            rows = np.arange(lo, hi)
            fresh = what_if.draw(self.launcher.streams(p.first_index + rows))
            drawn[id(p)] = (lo, fresh.ids)
            for k in np.flatnonzero(fresh.ids != p.draws.ids[rows]):
                start_id = fresh.ids[k : k + 1].copy()
                if self.queue.launch_ahead(int(p.first_index + rows[k]), Draws.unknown(start_id),
                                           what_if.vertices.points[start_id[0]].copy()):
                    self.launched_past_holds += 1
        return drawn

    def _next_change(self, what_if: Algorithm, index: int, drawn: dict, quiet_until: int) -> Event | None:
        """The first run from ``index`` on that changes ``what_if``'s state, among the runs
        back (fetched in order, without waiting) and drawn as ``what_if`` draws them
        (``drawn``); None when the results in end first (or the draws worked out)."""
        while index < quiet_until:
            p = self.pipeline.holding(index)
            if p is None or id(p) not in drawn:
                return None
            chunk = p.chunk_at(index)
            if chunk is None:
                if not self.pipeline.next_ready(p):
                    return None
                self.pipeline.fetch_next(p)
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
                return Event.of_run(chunk.first_index + row, chunk, row, p.starts[k], p.draws.ids[k], rescreen)
            index = chunk.first_index + len(chunk)
        return None
