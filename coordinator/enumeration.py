"""Deterministic certification's passes over the final set (VAL^delta: every centre once):
which centres run next, and when every alive centre holds a certificate.

A pass draws the alive centres that are not certified and not yet drawn in it, in id
order; when none is left, a new pass starts (centres in flight or invalidated by a
prune are drawn again). The answers are those of scanning every centre at each batch,
but a batch costs O(its runs), not O(centres): a scan of every centre per batch and per
committed chunk dominates a fine campaign (docs/benchmarks.md).

- ``next``: a cursor; every centre the pass could still draw is at or after it or among
  the centres reopened (certificate lost) below it, which ``reopened`` is told of.
- ``record``: whether the chunk's fresh checks reach the last uncertified centre
  needs that count only when it can be reached: a lower bound (the exact count at its
  last computation, minus checks gained and uncertified centres killed since;
  reopened and new centres only raise the true count) settles most chunks.
"""

from __future__ import annotations

import numpy as np

from coordinator.algorithm import EmptySetError
from coordinator.checked_centres import CheckedCentres
from coordinator.spatial import PointIndex
from coordinator.unique import unique_ints

SCAN_WINDOW = 4096  # centres looked at per step of the cursor (at least 4 x the runs wanted)


class Enumeration:
    def __init__(self, drawn: np.ndarray | None = None):
        self.drawn = np.zeros(0, dtype=bool) if drawn is None else drawn  # drawn in this pass
        self._cursor = 0
        self._reopened: list[np.ndarray] = []
        self._missing_bound: int | None = None  # <= alive centres without a certificate

    def next(self, vertices: PointIndex, checked: CheckedCentres, k: int) -> np.ndarray:
        """Up to ``k`` alive, uncertified centres not drawn in this pass, in id order;
        fewer left means a short batch, not repeats: a deterministic centre run twice in
        one batch only wastes the second run (with repeats the lead-follow idm example
        cost 21,759 runs, without 10,295; drawing those nearest PhiBar first did not
        help: 10,417)."""
        count = vertices.count
        if len(self.drawn) < count:
            self.drawn = np.concatenate([self.drawn, np.zeros(count - len(self.drawn), dtype=bool)])
        below = self._pending_reopened(vertices, checked)
        chosen = [below[:k]]
        self._reopened = [below[k:]] if len(below) > k else []
        need = k - len(chosen[0])
        while need > 0 and self._cursor < count:
            lo = self._cursor
            hi = min(count, lo + max(4 * need, SCAN_WINDOW))
            open_ = vertices.alive[lo:hi] & ~checked.certified_range(lo, hi) & ~self.drawn[lo:hi]
            found = np.flatnonzero(open_)[:need] + lo
            chosen.append(found)
            need -= len(found)
            self._cursor = int(found[-1]) + 1 if need == 0 else hi
        out = np.concatenate(chosen)
        if len(out) == 0:
            out = self._new_pass(vertices, checked, k)
        self.drawn[out] = True
        return out

    def _pending_reopened(self, vertices: PointIndex, checked: CheckedCentres) -> np.ndarray:
        if not self._reopened:
            return np.zeros(0, dtype=np.int64)
        ids = unique_ints(np.concatenate(self._reopened))
        # the others are dead, certified again or drawn; losing a certificate again tells us anew
        return ids[vertices.alive[ids] & ~checked.certified_at(ids) & ~self.drawn[ids]]

    def _new_pass(self, vertices: PointIndex, checked: CheckedCentres, k: int) -> np.ndarray:
        """Nothing left to draw in this pass: draw again from the first uncertified centre
        (from the first alive one if all are certified: runs in flight decide the end)."""
        alive = vertices.alive_ids()
        if len(alive) == 0:
            raise EmptySetError("the safe set is empty: every centre was pruned")
        self.drawn[:] = False
        open_ = ~checked.certified_at(alive)
        pending = alive[open_] if open_.any() else alive
        chosen = pending[:k]
        self._cursor, self._reopened = int(chosen[-1]) + 1, []
        return chosen

    def reopened(self, ids: np.ndarray) -> None:
        """Centres that lost their last certificate (a prune killed a witness)."""
        ids = ids[ids < self._cursor]
        if len(ids):
            self._reopened.append(ids)

    def before_prune(self, vertices: PointIndex, checked: CheckedCentres, ids: np.ndarray) -> None:
        """Centres ``ids`` are about to be killed: the uncertified alive ones leave the count."""
        if self._missing_bound is not None and len(ids):
            ids = unique_ints(ids)
            self._missing_bound -= int(np.count_nonzero(vertices.alive[ids] & ~checked.certified_at(ids)))

    def record(self, vertices: PointIndex, checked: CheckedCentres, starts: np.ndarray, offsets: np.ndarray,
               witnesses: np.ndarray) -> int:
        """CheckedCentres for alive centres ``starts`` (one per quiet run, in commit order,
        witnesses in CSR form). Returns the position in ``starts`` at which the last
        uncertified alive centre got one (every alive centre is then certified), or -1."""
        first = np.unique(starts, return_index=True)[1]
        fresh = np.zeros(len(starts), dtype=bool)
        fresh[first] = ~checked.certified_at(starts[first])
        gained = int(np.count_nonzero(fresh))
        missing = None
        if self._missing_bound is None or self._missing_bound <= gained:
            alive = vertices.alive[: vertices.count]
            missing = int(np.count_nonzero(alive & ~checked.certified_range(0, vertices.count)))
        checked.add(starts, offsets, witnesses)
        if missing is None:  # more are missing than this chunk certifies
            self._missing_bound -= gained
            return -1
        self._missing_bound = missing - gained
        reached = np.flatnonzero(np.cumsum(fresh) >= missing) if missing else np.array([0])
        return int(reached[0]) if len(reached) else -1
