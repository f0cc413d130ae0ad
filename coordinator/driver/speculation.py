"""Changes applied before the holds ahead of them are back.

Under sequential counting a run that changes the state waits for the replacements the
head passed before it (holds, coordinator/driver/holds.py): one of them may change the
state first. With slow runs these waits chain: a change moves a draw a few indices on,
its replacement is a whole run, and the next change waits for it (docs/benchmarks.md
measures what that costs on many workers). Instead the driver keeps a copy of the
algorithm from before the change and applies the change at once. A hold that comes back
is judged at the state its index had: the copy's, since nothing changed between the hold
and the change. Only if it changes the state does the algorithm go back to the copy
(``Algorithm.restore``) and the head to the hold, as it goes back for a hold that changes
the state anyway. Most holds come back quiet, so most changes wait for nothing. Results
never depend on it: the committed sequence is the one-run-at-a-time campaign's.

A change applied so is a ``Speculation``: its index, the copy, and the counters the holds
do not keep (coordinator/driver/holds.py ``HELD_COUNTS`` has the others). They are kept in
index order; the first is dropped once no hold before its change is left. A checkpoint
taken meanwhile is the state as the head passed the first hold: the first copy's.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from coordinator.algorithm import Algorithm
from coordinator.driver.holds import Held

RUN_S = 0.08  # [s] runs at least this long (as measured): a copy costs the driver milliseconds
# (below it the copies cost about what they save; docs/benchmarks.md, "2026-11-26, late")
# changes applied past holds at once, a copy of the algorithm each: more cost the driver
# more than they save (docs/benchmarks.md)
MAX_OUTSTANDING = 4
MAX_VERTICES = 500_000  # no copies of larger states (a copy holds the whole state)


@dataclass
class Speculation:
    """A change applied while holds before it were out: the state before it."""

    index: int  # the change's sample index (every hold before it has its due index below)
    algorithm: Algorithm  # a copy of the algorithm before the change
    changes: int  # counters as they stood then
    streak_start: int
    recorded: int


class Speculations:
    """The changes applied past holds, oldest first."""

    def __init__(self, enabled: bool = True):
        self.enabled = enabled  # (CampaignSettings.speculate: off, changes wait for their holds)
        self._items: deque[Speculation] = deque()
        self.applied = 0  # changes applied past holds (a statistic)
        self.restored = 0  # ... of which a hold before them changed the state (the algorithm went back)

    def __bool__(self) -> bool:
        return bool(self._items)

    @property
    def first(self) -> Speculation:
        return self._items[0]

    def allowed(self, algorithm: Algorithm, run_s: float | None, lag: int, settled: bool) -> bool:
        """May a change be applied past holds now? Only under sequential counting (lag 0),
        for slow runs, an algorithm that can go back, a state small enough to copy, and not
        while the set is ``settled`` (certification enumerates or checks: a change there
        ends the check, coordinator/driver/phase.py)."""
        return (self.enabled and lag == 0 and algorithm.restorable and run_s is not None and run_s >= RUN_S
                and len(self._items) < MAX_OUTSTANDING and algorithm.vertices.count <= MAX_VERTICES
                and not settled)

    def take(self, index: int, algorithm: Algorithm, counters) -> None:
        """The change at ``index`` is applied next, with holds before it out."""
        self._items.append(Speculation(index, algorithm.copy(), counters.changes, counters.streak_start,
                                       counters.recorded))
        self.applied += 1

    def settle(self, held: Held) -> None:
        """Drop the speculations no hold is left before."""
        while self._items and (not held or held.first.replacement.due > self._items[0].index):
            self._items.popleft()

    def committed(self, algorithm: Algorithm) -> Algorithm:
        """The algorithm as the head passed the first hold (what a checkpoint keeps)."""
        return self._items[0].algorithm if self._items else algorithm

    def committed_counts(self) -> dict:
        """The counters the holds do not keep, as the head passed the first hold ({}: none applied past)."""
        s = self._items[0] if self._items else None
        return {} if s is None else {"changes": s.changes, "streak_start": s.streak_start, "recorded": s.recorded}

    def undo(self, algorithm: Algorithm, counters) -> Speculation:
        """The first hold changes the state: ``algorithm`` and ``counters`` go back to how
        they stood before the first change applied past it; every speculation is dropped."""
        first = self._items[0]
        algorithm.restore(first.algorithm)
        counters.changes, counters.streak_start, counters.recorded = first.changes, first.streak_start, first.recorded
        self._items.clear()
        self.restored += 1
        return first

    def clear(self) -> None:
        self._items.clear()
