"""A closing round's edge (coordinator/spe_certification.py ``_edge_mask``), kept change
by change: per vertex id, is it alive and near the failure-side boundary or a hole.

Computed whole, the membership costs a few array operations over every vertex id after
each change of a closing round, O(vertices) a change, which grows with the dimension. A
change alters it only at the ids it killed or inserted and where it lowered a failure or
hole distance (a facet's nearness never changes for an id): only those are looked at
again, with the same tests, so the membership is the one the whole computation gives.
"""

from __future__ import annotations

import numpy as np


class EdgeMembership:
    def __init__(self, reach: float, radius: float, core: np.ndarray):
        """``core``: (count,) bool, alive and near, computed whole at the round's start.
        ``reach`` and ``radius``: the distances it was computed with (another delta, another
        edge)."""
        self.reach, self.radius = reach, radius
        self._core = core.copy()  # a buffer that doubles: ids are appended between changes
        self.count = len(core)
        self.size = int(np.count_nonzero(core))
        self.touched: list[np.ndarray] = []  # ids killed or inserted since the last update

    def fits(self, reach: float, radius: float) -> bool:
        return reach == self.reach and radius == self.radius

    def candidates(self, count: int, lowered: np.ndarray) -> np.ndarray:
        """The ids whose membership a change may have moved, sorted, once each: those
        touched, those whose distances fell (``lowered``), and the ids new since."""
        ids = np.concatenate([*self.touched, lowered, np.arange(self.count, count)]).astype(np.int64, copy=False)
        self.touched = []
        ids.sort()
        return ids[np.concatenate(([True], ids[1:] != ids[:-1]))] if len(ids) else ids

    def update(self, ids: np.ndarray, member: np.ndarray, count: int) -> np.ndarray:
        """Ids ``ids`` are members where ``member``; the count of ids is ``count`` now.
        Returns those of ``ids`` whose membership changed, in their order."""
        if count > len(self._core):
            grown = np.zeros(max(count, 2 * len(self._core)), dtype=bool)
            grown[: self.count] = self._core[: self.count]
            self._core = grown
        was = self._core[ids]
        moved = was != member
        self._core[ids] = member
        self.size += int(np.count_nonzero(member)) - int(np.count_nonzero(was))
        self.count = count
        return ids[moved]

    def core(self) -> np.ndarray:
        """(count,) bool: the membership now, a view that the next ``update`` writes into
        (a copy per change was O(ids): the mask of one version is asked at that version only)."""
        return self._core[: self.count]
