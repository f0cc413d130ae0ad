"""Re-deciding the runs of a screened chunk at a later state of the coverage, without their
trajectories where the screening's witnesses and explore states suffice
(coordinator/coverage.py says why that is exact)."""

from __future__ import annotations

import dataclasses

import numpy as np

from coordinator.coverage import QUIET, Coverage, Screening
from scenarios.base import FAILURE


class Rescreen:
    """Re-decides the runs of one screened chunk at the coverage's current state,
    lazily: only as far as the next run that changes the state (the runs after it are
    decided again after that change anyway). A run found not to change the state is not
    asked again until the coverage changes (the head asks from many places in a chunk)."""

    def __init__(self, coverage: Coverage, screening: Screening, outcomes: np.ndarray, visited):
        if screening.epoch != coverage.epoch and coverage.descends(screening.epoch, screening.seq):
            screening = dataclasses.replace(screening, epoch=coverage.epoch)  # screened before a fork
        self.coverage, self.screening, self.outcomes = coverage, screening, outcomes
        self.visited = visited  # () -> (states, offsets): the chunk's visited states, fetched on demand
        self._full = np.zeros(len(screening), dtype=bool)  # rows to re-screen from all their states
        self._checked_kills = -2  # kill seq up to which the witnesses were checked ...
        self._checked_from = 0  # ... from this row on (a replacement's row may be asked below it)
        self._known: tuple | None = None  # (row, epoch, seq, uncovered, near) of the last event found
        self._cleared = np.zeros(len(screening), dtype=bool)  # rows found quiet at ``_cleared_at``
        self._cleared_at: tuple | None = None  # the coverage's (epoch, seq) they were found quiet at

    def changes(self, row: int) -> bool:
        """Does run ``row`` change the state now (asked of that run alone: a replacement's)?"""
        return self.next_event(row, end=row + 1) == row

    def next_event(self, lo: int, allowed: np.ndarray | None = None, end: int | None = None) -> int:
        """The first run at or after ``lo`` (and before ``end``) that changes the state now
        (the chunk's length if none). ``allowed`` (k,) bool: runs that can change it at all."""
        cov, sc = self.coverage, self.screening
        k = len(sc)
        hi = k if end is None else min(end, k)
        if lo >= hi:
            return k
        if sc.epoch == cov.epoch and sc.seq == cov.seq:
            changes = sc.event[lo:hi] != QUIET
            if allowed is not None:
                changes &= allowed[lo:hi]
            return lo + int(np.argmax(changes)) if changes.any() else k
        if sc.epoch != cov.epoch or sc.seq > cov.seq:
            # vertex ids of another covering: witnesses mean nothing; or screened at changes
            # this coverage has not had (a hold judged at the state the head passed it,
            # coordinator/driver/speculation.py): its new states are not this coverage's
            self._full[lo:] = True
        elif cov.kill_seq > max(sc.seq, self._checked_kills) or lo < self._checked_from:
            self._mark_dead_witnesses(lo)  # only a Kill can uncover a state
        now = (cov.epoch, cov.seq)
        if self._cleared_at != now:
            self._cleared[:] = False
            self._cleared_at = now
        candidates = np.flatnonzero(((sc.event[lo:hi] != QUIET) | self._full[lo:hi]) & ~self._cleared[lo:hi]) + lo
        if allowed is not None:
            candidates = candidates[allowed[candidates]]
        at, block = 0, 1
        while at < len(candidates):  # in growing blocks: the first candidate usually is one
            rows = candidates[at : at + block]
            if self._known is not None and self._known[:3] == (int(rows[0]), *now):
                return int(rows[0])  # found by an earlier ask at this coverage
            changes, classified = self._changes(rows)
            if changes.any():
                first = int(np.argmax(changes))
                self._cleared[rows[:first]] = True
                return self._found(rows, first, classified)
            self._cleared[rows] = True
            at, block = at + block, min(4 * block, 256)
        return k

    def trusted(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows),) bool: the screening's witnesses of these runs are current and
        complete: not re-screened in full, and quiet when screened (a run whose explore
        states were covered by later inserts is quiet now, but has no witness for them),
        and no centre inserted since: a state's witness is its newest covering centre, so
        after an insert (boundary refinement splits boxes while it certifies) the answer
        would depend on when the chunk was screened, that is, on the executor."""
        sc = self.screening
        cov = self.coverage
        if sc.epoch != cov.epoch or cov.insert_seq > sc.seq:
            return np.zeros(len(rows), dtype=bool)
        return ~self._full[rows] & (sc.event[rows] == QUIET) & ~sc.escaped[rows]

    def witnesses(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The alive centres that cover the states of runs ``rows`` (quiet now) at the
        current coverage: (len(rows) + 1,) offsets and the ids, run by run. From the
        screening where its witnesses are current (``trusted``); the other runs are screened
        again from their visited states, so the answer does not depend on the coverage the
        runs were screened at (that is, on the executor)."""
        sc = self.screening
        trusted = self.trusted(rows)
        counts = np.zeros(len(rows), dtype=np.int64)
        counts[trusted] = sc.witness_offsets[rows[trusted] + 1] - sc.witness_offsets[rows[trusted]]
        again = rows[~trusted]
        if len(again):
            states, offsets = self.visited()
            lengths = offsets[again + 1] - offsets[again]
            run = np.repeat(np.arange(len(again)), lengths)
            within = np.arange(int(lengths.sum())) - np.repeat(np.cumsum(lengths) - lengths, lengths)
            sub_offsets = np.zeros(len(again) + 1, dtype=np.int64)
            np.cumsum(lengths, out=sub_offsets[1:])
            fresh = self.coverage.screen(states[offsets[again][run] + within], sub_offsets, self.outcomes[again])
            counts[~trusted] = np.diff(fresh.witness_offsets)
        out_offsets = np.zeros(len(rows) + 1, dtype=np.int64)
        np.cumsum(counts, out=out_offsets[1:])
        out = np.empty(int(out_offsets[-1]), dtype=np.int32)
        for mask, source, source_offsets, source_rows in (
                (trusted, sc.witnesses, sc.witness_offsets, rows[trusted]),
                (~trusted, fresh.witnesses if len(again) else None,
                 fresh.witness_offsets if len(again) else None, np.arange(len(again)))):
            if not mask.any():
                continue
            c = counts[mask]
            run = np.repeat(np.arange(len(c)), c)
            within = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
            out[out_offsets[:-1][mask][run] + within] = source[source_offsets[source_rows][run] + within]
        return out_offsets, out

    def candidates(self, row: int) -> np.ndarray:
        """The states of run ``row`` that can be new at the current version, in time
        order: its explore states, or all its visited states if it is re-screened in full."""
        if self._full[row] or self.screening.epoch != self.coverage.epoch:
            states, offsets = self.visited()
            return states[offsets[row] : offsets[row + 1]]
        sc = self.screening
        return sc.explore_states[sc.explore_offsets[row] : sc.explore_offsets[row + 1]]

    def classification(self, row: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(uncovered, near_failure) of ``candidates(row)`` now, as ``Event`` takes them,
        when the screening already knows them: the event was just found by classifying
        them, or the chunk was screened at the current state (its explore states are
        uncovered and not near a failure there). (None, None) otherwise; near_failure is
        None in strict mode (the screening does not excuse a state near a failure)."""
        cov, sc = self.coverage, self.screening
        strict = cov.strict
        if self._known is not None and self._known[:3] == (row, cov.epoch, cov.seq):
            return self._known[3], None if strict else self._known[4]
        if sc.epoch == cov.epoch and sc.seq == cov.seq and not self._full[row]:
            m = int(sc.explore_offsets[row + 1] - sc.explore_offsets[row])
            return np.ones(m, dtype=bool), None if strict else np.zeros(m, dtype=bool)
        return None, None

    def _mark_dead_witnesses(self, lo: int) -> None:
        sc = self.screening
        offsets = sc.witness_offsets[lo:]
        dead = ~self.coverage.vertices.alive[sc.witnesses[offsets[0] : offsets[-1]]]
        dead_before = np.zeros(len(dead) + 1, dtype=np.int64)
        np.cumsum(dead, out=dead_before[1:])
        rel = offsets - offsets[0]
        self._full[lo:] |= dead_before[rel[1:]] > dead_before[rel[:-1]]
        if self.coverage.kill_seq != self._checked_kills:
            self._checked_kills, self._checked_from = self.coverage.kill_seq, lo
        else:  # the same kills, asked below the rows checked
            self._checked_from = min(self._checked_from, lo)

    def _changes(self, rows: np.ndarray) -> tuple[np.ndarray, tuple | None]:
        """(len(rows),) bool: these runs change the state now (one classification), and
        that classification: (uncovered, near, offsets of each row's states), or None."""
        failed = self.outcomes[rows] == FAILURE
        if len(rows) == 1:  # most calls (the first block is one row): no per-row bookkeeping
            if failed[0]:
                return failed, None
            states = self.candidates(int(rows[0]))
            if len(states) == 0:
                return failed, None
            uncovered, near = self._classify(states, rows)
            new = uncovered & ~near
            return new.any(keepdims=True), (uncovered, near, np.array([0, len(states)]))
        parts = [self.candidates(int(r)) if not f else np.empty((0, self.coverage.n))
                 for r, f in zip(rows, failed)]
        states = np.concatenate(parts)
        if len(states) == 0:
            return failed, None
        uncovered, near = self._classify(states, rows)
        new = uncovered & ~near
        lengths = [len(p) for p in parts]
        run = np.repeat(np.arange(len(rows)), lengths)
        changes = failed | (np.bincount(run[new], minlength=len(rows)) > 0)
        return changes, (uncovered, near, np.concatenate([[0], np.cumsum(lengths)]))

    def _classify(self, states: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(uncovered, near) of the candidate states of ``rows`` now."""
        if not self._full[rows].any() and self.screening.epoch == self.coverage.epoch:
            known = self.coverage.classify_since(states, self.screening.seq)  # states new at screening
            if known is not None:
                return known
        witness, near = self.coverage.classify_states(states)
        return witness < 0, near

    def _found(self, rows: np.ndarray, at: int, classified: tuple | None) -> int:
        """Run ``rows[at]`` changes the state: keep what its classification found."""
        row, cov = int(rows[at]), self.coverage
        self._known = None
        if classified is not None and self.outcomes[row] != FAILURE:  # a failure's states were not classified
            uncovered, near, offsets = classified
            sl = slice(offsets[at], offsets[at + 1])
            self._known = (row, cov.epoch, cov.seq, uncovered[sl], near[sl])
        return row
