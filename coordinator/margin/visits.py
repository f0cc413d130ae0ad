"""The states each box's centre run visited, kept until the partition is final: margin
refinement's certification checks that every state a kept box's run visits lies in a
kept box (coordinator/margin/invariance.py), which needs the states, not the boxes they
were in when the run came back (those may split later).

A run's consecutive repeated states (a platoon at a standstill) are kept once; a box
that splits or fails drops its run's states. A resumed campaign starts empty: the boxes
without states are simulated again before the check (a run is a function of its start).
"""

from __future__ import annotations

import numpy as np

from coordinator.buffers import Appendable

COMPACT_SHARE = 0.5  # rewrite the buffer when this share of it belongs to dropped runs


class Visits:
    def __init__(self, n: int):
        self.n = n
        self._states = np.empty((0, n))
        self._size = 0
        self._owner = Appendable(np.int64)  # the box of each kept run, in the buffer's order
        self._start = Appendable(np.int64)  # where its states begin
        self._count = Appendable(np.int64)
        self._run_of: dict[int, int] = {}  # box -> its run's entry
        self._dead = 0  # states of dropped runs still in the buffer

    def __contains__(self, box: int) -> bool:
        return box in self._run_of

    @property
    def nbytes(self) -> int:
        return self._states.nbytes

    def add(self, boxes: np.ndarray, states: np.ndarray, offsets: np.ndarray) -> None:
        """Box ``boxes[r]``'s run visited ``states[offsets[r]:offsets[r+1]]`` (in Sigma)."""
        if len(boxes) == 0:
            return
        run = np.repeat(np.arange(len(boxes)), np.diff(offsets))
        keep = np.ones(len(states), dtype=bool)
        keep[1:] = (states[1:] != states[:-1]).any(axis=1) | (run[1:] != run[:-1])
        states, run = states[keep], run[keep]
        counts = np.bincount(run, minlength=len(boxes))
        self._grow(len(states))
        self._states[self._size : self._size + len(states)] = states
        starts = self._size + np.concatenate([[0], np.cumsum(counts)[:-1]])
        self._size += len(states)
        first = self._owner.size
        self._owner.extend(boxes)
        self._start.extend(starts)
        self._count.extend(counts)
        self._run_of.update(zip(boxes.tolist(), range(first, first + len(boxes))))

    def drop(self, boxes) -> None:
        """Forget the runs of ``boxes`` (split, or failed)."""
        for box in np.asarray(boxes).tolist():
            entry = self._run_of.pop(box, None)
            if entry is not None:
                self._dead += int(self._count.view[entry])
        if self._dead > COMPACT_SHARE * max(self._size, 1):
            self._compact()

    def of(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The visited states of ``boxes`` (each kept): (S, n) states, (len(boxes) + 1,) offsets."""
        entries = np.array([self._run_of[b] for b in boxes.tolist()], dtype=np.int64)
        counts = self._count.view[entries]
        offsets = np.zeros(len(boxes) + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        at = np.repeat(self._start.view[entries] - offsets[:-1], counts) + np.arange(offsets[-1])
        return self._states[at], offsets

    def _grow(self, extra: int) -> None:
        need = self._size + extra
        if need > len(self._states):
            grown = np.empty((max(need, 2 * len(self._states), 1024), self.n))
            grown[: self._size] = self._states[: self._size]
            self._states = grown

    def _compact(self) -> None:
        boxes = np.array(sorted(self._run_of), dtype=np.int64)
        states, offsets = self.of(boxes) if len(boxes) else (np.empty((0, self.n)), np.zeros(1, dtype=np.int64))
        self.__init__(self.n)
        self._states = np.empty((0, self.n))
        self._append_raw(boxes, states, offsets)

    def _append_raw(self, boxes, states, offsets) -> None:
        counts = np.diff(offsets)
        self._grow(len(states))
        self._states[: len(states)] = states
        self._size = len(states)
        self._owner.extend(boxes)
        self._start.extend(offsets[:-1])
        self._count.extend(counts)
        self._run_of.update(zip(boxes.tolist(), range(len(boxes))))
