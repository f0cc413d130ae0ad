"""Prioritized sampling's cumulative weights, updated from the first vertex that changed.

SPE draws start states over the alive centres with probability alpha(d* - d_i), d_i =
d(sigma_i, PhiBar) (paper Sec. 4.4): an inverse-CDF pick on the cumulative weights over
the alive ids in id order. The state changes between nearly every batch, and recomputing
gather, max and cumulative sum over 1e6 centres per batch was half of a delta_min = 0.125
campaign's time.

Every change has a smallest vertex id it touches: a kill (its ids), a lowered distance
(a new failure), an appended vertex (ids only grow). Entries before that id keep their
id, distance and weight, so only the tail is recomputed. The cumulative sum of the tail
continues from the kept prefix's last value: ``cumsum([C_{k-1} + w_k, w_{k+1}, ...])``
adds in the same order as one ``cumsum`` over everything (numpy accumulates left to
right), so the values, and every draw, are bit-identical to a full recomputation. When
d* itself changes, every weight changes and the weights are recomputed whole (the
distances and ids still only from the tail).
"""

from __future__ import annotations

import numpy as np

_NONE = np.iinfo(np.int64).max


class PrioritizedCDF:
    def __init__(self, alpha):
        self.alpha = alpha  # in-place alpha on d* - d_i
        self.size = 0  # alive ids held
        self.count = 0  # vertex count when last computed (ids below it were seen)
        self.dmax = None
        self.dirty = 0  # smallest vertex id changed since; 0: recompute everything
        self._ids = np.empty(0, dtype=np.int64)
        self._dist = np.empty(0)  # d_i gathered in id order
        self._prefix_max = np.empty(0)
        self._weights = np.empty(0)
        self._cdf = np.empty(0)

    def touched(self, lowest_id: int) -> None:
        """A change at vertex ``lowest_id`` or above (kill, lowered distance)."""
        self.dirty = min(self.dirty, int(lowest_id))

    def reset(self) -> None:
        """Everything may have changed (a new delta, a loaded checkpoint)."""
        self.dirty = 0

    def update(self, alive: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(ids, cumulative weights or None for uniform) over the alive vertices;
        ``alive`` (count,) bool, ``dist`` (count,) d_i."""
        count = len(alive)
        first = min(self.dirty, self.count)  # vertices appended since are changes too
        pos = int(np.searchsorted(self._ids[: self.size], first))
        tail = np.flatnonzero(alive[first:]) + first
        size = pos + len(tail)
        self._reserve(pos, size)
        ids, d = self._ids[:size], self._dist[:size]
        ids[pos:] = tail
        np.take(dist, tail, out=d[pos:])
        pm = self._prefix_max[:size]
        if size > pos:
            np.maximum.accumulate(d[pos:], out=pm[pos:])
            if pos:
                np.maximum(pm[pos:], pm[pos - 1], out=pm[pos:])
        self.size, self.count, self.dirty = size, count, _NONE
        if size == 0:
            return ids, None
        dmax = pm[size - 1]
        start = pos if dmax == self.dmax else 0  # a new d* changes every weight
        self.dmax = dmax
        w, cdf = self._weights[:size], self._cdf[:size]
        np.subtract(dmax, d[start:], out=w[start:])
        self.alpha(w[start:])
        if start < size:
            part = w[start:].copy()
            if start:
                part[0] += cdf[start - 1]  # continue the running sum exactly where it stood
            np.cumsum(part, out=cdf[start:])
        # all weights are >= 0: the total is 0 only if all are, i.e. all equidistant (uniform)
        return ids, (cdf if cdf[size - 1] > 0 else None)

    def _reserve(self, keep: int, size: int) -> None:
        if size <= len(self._ids):
            return
        cap = max(size, 2 * len(self._ids), 1024)
        for name in ("_ids", "_dist", "_prefix_max", "_weights", "_cdf"):
            old = getattr(self, name)
            new = np.empty(cap, dtype=old.dtype)
            new[:keep] = old[:keep]
            setattr(self, name, new)
