"""The replacements the head commits past before they are back (holds), and what it did
past them (shared/spec/scaling.md; coordinator/driver/campaign.py drives them).

The head does not wait for a replacement that is due but not back (a *hold*): it commits
on, past it, the runs a one-run-at-a-time campaign would commit next *if the replacement
leaves the state as it is* (most do). Nothing the head does past a hold changes the
state: it stops at the next run that would change it, and at the streak's end, until the
holds before it are applied. What it does do is undone if a held replacement changes the
state, so ``Held`` keeps, per hold, the counters as they stood when the head passed its
index, and holds back the effects of every later commit (ledger rows, experience replay,
the adversary's counts) until the holds before them are applied:

- applied and quiet: the counters (and the later holds' records of them) gain its quiet
  run, and the effects held up to the next hold take place, in index order;
- applied and changing the state: the head goes back to just after its index (the
  counters as recorded, every later effect and hold dropped), the change is applied, and
  the runs after it are committed again at the new state.

The committed sequence is therefore the one-run-at-a-time campaign's, whatever the
workers' timing: the hold only hides the replacement's latency.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

# the counters a hold records, and restores if its replacement changes the state
HELD_COUNTS = ("committed", "quiet", "escaped_in_streak", "runs_discarded", "runs_replaced")
STREAK_COUNTS = ("quiet", "escaped_in_streak")  # of the streak: a change starts them again


@dataclass
class Hold:
    """A due replacement the head passed before its run was back."""

    replacement: Any  # a coordinator.driver.replacements.Replacement
    counts: dict  # HELD_COUNTS as they stood when the head passed its due index (``Held.counts`` adds since)
    queue: list  # the replacements queued then (not yet due)
    effects: int  # held effects that come before its own (counted from the first ever held)
    seq: int  # quiet applications recorded before it (``Held.counts`` adds the later ones)


@dataclass
class Held:
    """The holds, oldest first, and the effects of the commits made past the first.

    A hold applied quiet adds its run to the counts of every later hold. With hundreds of
    holds outstanding, adding it to each at once cost a walk over all of them per
    application; instead each application is recorded once (``_gains``) and a hold's
    counts fold in those after its own when they are asked for (``counts``)."""

    holds: deque = field(default_factory=deque)
    effects: deque = field(default_factory=deque)
    passed: int = 0  # replacements the head passed before they were back (a statistic)
    rewound: int = 0  # held replacements that changed the state (the head went back)
    _done: int = 0  # effects taken off ``effects`` so far (applied or dropped)
    _gains: list = field(default_factory=list)  # per quiet application: (gained, streak_until or None)
    _gains_from: int = 0  # the seq of ``_gains[0]``

    def __bool__(self) -> bool:
        return bool(self.holds)

    @property
    def first(self) -> Hold:
        return self.holds[0]

    def hold(self, replacement, counters, queue) -> None:
        """The head passes ``replacement`` (due, not back)."""
        counts = {name: getattr(counters, name) for name in HELD_COUNTS}
        self.holds.append(Hold(replacement, counts, list(queue), self._done + len(self.effects),
                               self._gains_from + len(self._gains)))
        self.passed += 1

    def counts(self, hold: Hold) -> dict:
        """``hold``'s counters: as they stood when the head passed it, plus what each hold
        applied quiet since added (streak counts only from applications of its streak)."""
        out = dict(hold.counts)
        for gained, streak_until in self._gains[hold.seq - self._gains_from :]:
            same_streak = streak_until is None or hold.replacement.due < streak_until
            for name, amount in gained.items():
                if same_streak or name not in STREAK_COUNTS:
                    out[name] += amount
        return out

    def effect(self, apply: Callable[[], None]) -> None:
        """A commit's effect: now, or held until the holds before it are applied."""
        if self.holds:
            self.effects.append(apply)
        else:
            apply()

    def applied_quiet(self, gained: dict, streak_until: int | None = None) -> None:
        """The first hold's replacement was applied and left the state as it was: the later
        holds' records gain what it added (``gained``: counter -> amount), and the effects
        up to the next hold take place. ``streak_until``: a change at that index was
        applied past the hold (coordinator/driver/speculation.py): holds due from there on are of
        a later streak, whose counts it does not add to."""
        self.holds.popleft()
        if self.holds:
            self._gains.append((gained, streak_until))
        else:  # no hold left to add them to
            self._gains_from += len(self._gains)
            self._gains.clear()
        upto = self.holds[0].effects if self.holds else self._done + len(self.effects)
        ready = [self.effects.popleft() for _ in range(upto - self._done)]
        self._done = upto
        for apply in ready:
            apply()

    def rewind(self, counters) -> tuple[Hold, list]:
        """The first hold's replacement changes the state: the counters go back to how they
        stood when the head passed it, every later effect and hold is dropped. Returns the
        hold and the replacements of the later holds (drawn for indices the head will
        commit again)."""
        first = self.holds[0]
        for name, value in self.counts(first).items():
            setattr(counters, name, value)
        later = [h.replacement for h in list(self.holds)[1:]]
        self.clear()  # the first hold's effects position is the first held: every one came after it
        self.rewound += 1
        return first, later

    def clear(self) -> None:
        self.holds.clear()
        self._done += len(self.effects)
        self.effects.clear()
        self._gains_from += len(self._gains)
        self._gains.clear()
