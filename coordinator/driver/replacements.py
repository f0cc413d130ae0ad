"""Replacement runs under coupled counting (shared/spec/scaling.md): every run that
stands in for a mispredicted one, from its launch to the head's use of it.

A mispredicted run is discarded unseen and replaced: the current draw, the same index and
streams (``Replacement``), applied before the head commits index ``due`` + 1. Replacements
sent together travel as one executor batch (``ReplacementGroup``). The queue keeps them
in due order; a due one that is not back is *held* (coordinator/driver/holds.py) and the
head commits on past it; runs launched before a misprediction is known (the look-ahead,
coordinator/driver/lookahead.py) wait in ``ahead`` until the head asks for their index.
The queue hands the driver what to apply; it never applies anything itself.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

import numpy as np

from coordinator.driver.exact import drawn_now
from coordinator.driver.holds import Held
from coordinator.executor import Chunk
from coordinator.stable_sampler import Draws


class ReplacementGroup:
    """Replacements submitted together, as one batch: the chunks they travel in (in the
    batch's order), fetched on demand."""

    def __init__(self, handles: list):
        self.handles = list(handles)  # not fetched yet, in order
        self.chunks: list[Chunk] = []
        self.ends: list[int] = []  # positions in the batch after each fetched chunk

    def fetched(self, chunk: Chunk) -> None:
        self.chunks.append(chunk)
        self.ends.append((self.ends[-1] if self.ends else 0) + len(chunk))

    def find(self, position: int) -> tuple[Chunk, int] | None:
        """The chunk and row of the batch's ``position``-th run, if fetched."""
        at = bisect.bisect_right(self.ends, position)
        if at == len(self.chunks):
            return None
        return self.chunks[at], position - (self.ends[at - 1] if at else 0)


@dataclass
class Replacement:
    """The run that replaces a mispredicted one: index ``index``, drawn as ``draws``
    (one draw), applied before the head commits index ``due`` + 1."""

    index: int
    draws: Draws
    start: np.ndarray
    due: int
    group: ReplacementGroup | None = None
    position: int = 0  # its row in its group's batch


class ReplacementQueue:
    """Replacements launched, sent, fetched and queued in due order (then index order:
    one drawn again keeps its place); the holds the head passed; the runs launched ahead."""

    def __init__(self, launcher, counters, lag: int, restored=()):
        self.launcher = launcher  # coordinator/driver/launcher.py
        self.counters = counters
        self.lag = lag  # indices after the head at which a replacement is applied
        self.queue: deque[Replacement] = deque(restored)
        self.unsent: list[Replacement] = list(restored)  # read back ones are simulated again
        self.held = Held()
        self.ahead: dict[int, Replacement] = {}  # runs launched ahead, by index

    def __bool__(self) -> bool:
        return bool(self.queue)

    def __iter__(self):
        return iter(self.queue)

    @property
    def first(self) -> Replacement:
        return self.queue[0]

    # -- launching ----------------------------------------------------------------------------
    def replace(self, index: int, current: Draws | None = None) -> None:
        """Run ``index`` is discarded unseen: launch its replacement from its stream's
        current draw (``current`` if the caller knows it at this state), due ``lag``
        indices after the head (a run launched ahead for that draw is taken)."""
        due = max(index, self.counters.committed - 1) + self.lag
        ahead = self.ahead.pop(index, None)
        now = drawn_now(self.launcher, ahead) if ahead is not None else current
        if ahead is not None and now is None:  # the run launched ahead is still its draw
            ahead.due = due
            self._insert(ahead)
        else:
            draws = now if now is not None else self.launcher.draw([index])
            replacement = Replacement(index, draws, self.launcher.starts(draws.ids[0]), due)
            self._insert(replacement)
            self.unsent.append(replacement)
        self.counters.runs_discarded += 1

    def launch_ahead(self, index: int, draws: Draws, start: np.ndarray) -> bool:
        """Launch a run ahead for index ``index`` from ``start`` (its draw ``draws``),
        unless one from that start is launched already. True if launched."""
        known = self.ahead.get(index)
        if known is not None and known.draws.ids[0] == draws.ids[0] and np.array_equal(known.start, start):
            return False
        self.ahead[index] = r = Replacement(index, draws, start, index)
        self.unsent.append(r)
        return True

    def forget_ahead_before(self, head: int) -> None:
        """The head passed these indices without needing their runs."""
        for index in [i for i in self.ahead if i < head]:
            del self.ahead[index]

    def send(self) -> None:
        """Submit the replacements launched since the last call, as one batch: a call per
        pass, not per misprediction, since a chunk costs the driver and its worker about the
        same whatever its runs."""
        if not self.unsent:
            return
        batch, self.unsent = self.unsent, []
        indices = np.array([r.index for r in batch], dtype=np.int64)
        group = ReplacementGroup(self.launcher.submit(int(indices[0]), np.stack([r.start for r in batch]),
                                                      indices=indices))
        for position, r in enumerate(batch):
            r.group, r.position = group, position

    def _insert(self, r: Replacement) -> None:
        at = len(self.queue)
        while at and (self.queue[at - 1].due, self.queue[at - 1].index) > (r.due, r.index):
            at -= 1
        self.queue.insert(at, r)

    # -- fetching -----------------------------------------------------------------------------
    def _take(self, group: ReplacementGroup) -> None:
        """Fetch the next chunk of ``group`` (its handle is dropped only once it is read:
        a stop while waiting leaves the group as it was)."""
        chunk = self.launcher.fetch(group.handles[0])
        group.handles.pop(0)
        group.fetched(chunk)

    def fetch(self, r: Replacement) -> tuple[Chunk, int]:
        """Wait for replacement ``r``'s run: its chunk and row."""
        if r.group is None:
            self.send()
        found = r.group.find(r.position)
        while found is None:
            self._take(r.group)
            found = r.group.find(r.position)
        return found

    def back(self, r: Replacement) -> bool:
        """Is replacement ``r``'s run back (fetched without waiting for a worker)? On a
        concurrent executor one not sent yet is not: it goes out with the pass's others
        at the next fill (a call per misprediction cost the driver more than its runs)."""
        if r.group is None:
            if self.launcher.concurrent:
                return False
            self.send()
        group = r.group
        while group.find(r.position) is None:
            if not group.handles or not self.launcher.ready(group.handles[0]):
                return False
            self._take(group)
        return True

    # -- what the head applies --------------------------------------------------------------
    def next_due(self) -> Replacement | None:
        """The first replacement due before the head that the head applies now (back, no
        hold before it); on the way, one a change moved is replaced again (unseen) and
        one not back is held (the head commits on past it)."""
        c = self.counters
        while self.queue and self.queue[0].due < c.committed:
            r = self.queue[0]
            if (current := drawn_now(self.launcher, r)) is not None:
                self.queue.popleft()
                self.replace(r.index, current)
            elif self.held or not self.back(r):
                self.queue.popleft()
                self.held.hold(r, c, self.queue)
            else:
                return r
        return None

    def first_from(self, index: int) -> Replacement | None:
        """The first queued replacement of an index from ``index`` on (due order)."""
        return next((r for r in self.queue if r.index >= index), None)

    def take(self, r: Replacement) -> tuple[Chunk, int] | None:
        """Queued replacement ``r`` off the queue with its run (waiting for it) if it is
        still what its stream draws now; else None, and it is replaced again (unseen)."""
        if (current := drawn_now(self.launcher, r)) is not None:
            self.queue.remove(r)
            self.replace(r.index, current)
            return None
        found = self.fetch(r)  # a stop while waiting leaves it queued
        self.queue.remove(r)
        return found

    def rewind(self) -> None:
        """The first hold's replacement changes the state: the counters and the queue go
        back to how they stood when the head passed it; the replacements dropped so are
        kept as runs launched ahead (drawn for indices the head commits again)."""
        hold, later = self.held.rewind(self.counters)
        head = self.counters.committed
        kept = {id(r) for r in hold.queue}
        dropped = later + [r for r in self.queue if id(r) not in kept]
        self.queue = deque(hold.queue)
        for r in dropped:
            if r.index >= head and r.index not in self.ahead:
                self.ahead[r.index] = r

    def committed_for_good(self) -> tuple[dict, list[Replacement]]:
        """The counters a hold recorded and the replacements queued as the head passed the
        first hold ({} and the queue when none is held): what a checkpoint keeps."""
        if not self.held:
            return {}, list(self.queue)
        hold = self.held.first
        return self.held.counts(hold), [hold.replacement, *hold.queue]

    def drop(self) -> None:
        """Cancel and forget every replacement, hold and run launched ahead (a round end)."""
        groups = {id(r.group): r.group for r in [*self.queue, *self.ahead.values()] if r.group is not None}
        for group in groups.values():
            for handle in group.handles:
                self.launcher.cancel(handle)
        self.queue.clear()
        self.held.clear()
        self.unsent = []
        self.ahead.clear()
