"""A partition of Sigma into boxes with a half-width per axis, refined by splitting a box
along some of its axes: the state of margin refinement (coordinator/margin/refinement.py).

The roots tile Sigma exactly: per axis ``ceil(extent / (2 delta0))`` equal cells, so no
box overhangs Sigma and every centre lies inside it. A split halves a box along the axes
it names (``2^k`` children for k axes, never all ``2^n`` unless asked), or cuts it at a
given point along one axis (where its margin crosses zero); children are
stored contiguously, so ``locate`` walks from a point's root down by one comparison per
split axis and level: its cost is linear in n and in the depth, whatever the number of
boxes. Every box ever made keeps its id (a split box becomes an inner node); leaves are
the partition.
"""

from __future__ import annotations

import numpy as np

FACE_NUDGE = 1e-9  # a neighbour is found a relative 1e-9 of Sigma's extent past a face
LOCATE_BLOCK = 1 << 20  # points located at once: a walk's temporaries are about ten (block, n) arrays


class Rows:
    """A 2-D array that grows by appended rows (doubling)."""

    def __init__(self, width: int, dtype=float, fill=0):
        self.data = np.full((1024, width), fill, dtype=dtype)
        self.fill = fill
        self.size = 0

    def extend(self, rows: np.ndarray) -> np.ndarray:
        need = self.size + len(rows)
        if need > len(self.data):
            grown = np.full((max(need, 2 * len(self.data)), self.data.shape[1]), self.fill, dtype=self.data.dtype)
            grown[: self.size] = self.data[: self.size]
            self.data = grown
        ids = np.arange(self.size, need)
        self.data[self.size : need] = rows
        self.size = need
        return ids

    @property
    def view(self) -> np.ndarray:
        return self.data[: self.size]


class Partition:
    """Boxes ``lo`` / ``hi`` (closed) that tile Sigma = [lower, upper]: the leaves."""

    def __init__(self, lower, upper, delta0: float):
        self.lower, self.upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        self.n = len(self.lower)
        extent = self.upper - self.lower
        self.counts = np.maximum(1, np.ceil(extent / (2 * delta0) - 1e-9)).astype(np.int64)
        self.root_width = extent / self.counts
        self.nudge = FACE_NUDGE * extent
        self._lo, self._hi = Rows(self.n), Rows(self.n)
        self._child = Rows(1, np.int64, -1)  # first child of an inner node; -1: a leaf
        self._mask = Rows(1, np.int64, 0)  # the axes it was split along (bits)
        self._at = Rows(self.n)  # where along each of them (the centre, unless cut elsewhere)
        grid = np.stack(np.meshgrid(*[np.arange(c) for c in self.counts], indexing="ij"), -1).reshape(-1, self.n)
        lo = self.lower + grid * self.root_width
        hi = np.where(grid + 1 == self.counts, self.upper, lo + self.root_width)
        self._lo.extend(lo)
        self._hi.extend(hi)
        self._child.extend(np.full((len(lo), 1), -1))
        self._mask.extend(np.zeros((len(lo), 1), dtype=np.int64))
        self._at.extend(0.5 * (lo + hi))
        self.roots = len(lo)
        self._strides = np.cumprod(np.concatenate([self.counts[1:], [1]])[::-1])[::-1].astype(np.int64)

    # -- what it holds ----------------------------------------------------------------------
    @property
    def size(self) -> int:
        """Boxes ever made (leaves and inner nodes)."""
        return self._lo.size

    @property
    def lo(self) -> np.ndarray:
        return self._lo.view

    @property
    def hi(self) -> np.ndarray:
        return self._hi.view

    def is_leaf(self, ids) -> np.ndarray:
        return self._child.view[ids, 0] < 0

    def leaves(self) -> np.ndarray:
        return np.flatnonzero(self._child.view[:, 0] < 0)

    def centres(self, ids) -> np.ndarray:
        return 0.5 * (self.lo[ids] + self.hi[ids])

    def half_widths(self, ids) -> np.ndarray:
        return 0.5 * (self.hi[ids] - self.lo[ids])

    # -- finding the leaf of a point -----------------------------------------------------------
    def locate(self, points: np.ndarray) -> np.ndarray:
        """(P, n) points in Sigma -> (P,) the leaf holding each (a point on a face: the
        leaf on its upper side, but at Sigma's upper bound). In blocks: certification
        locates every state of every run (tens of millions), and at once the walk's
        temporaries were most of a 5-D campaign's peak memory."""
        points = np.asarray(points, dtype=float)
        if len(points) <= LOCATE_BLOCK:
            return self._locate(points)
        return np.concatenate([self._locate(points[lo : lo + LOCATE_BLOCK])
                               for lo in range(0, len(points), LOCATE_BLOCK)])

    def _locate(self, points: np.ndarray) -> np.ndarray:
        k = np.clip(np.floor((points - self.lower) / self.root_width).astype(np.int64), 0, self.counts - 1)
        node = k @ self._strides
        child, mask, cut = self._child.view[:, 0], self._mask.view[:, 0], self._at.view
        rows = np.flatnonzero(child[node] >= 0)
        while len(rows):
            at = node[rows]
            m = mask[at]
            plane = cut[at]
            code = np.zeros(len(rows), dtype=np.int64)
            rank = np.zeros(len(rows), dtype=np.int64)
            for axis in range(self.n):
                split = (m >> axis) & 1
                code |= (split & (points[rows, axis] >= plane[:, axis])) << rank
                rank += split
            node[rows] = child[at] + code
            rows = rows[child[node[rows]] >= 0]
        return node

    def neighbours(self, ids: np.ndarray, axis: int, side: int) -> np.ndarray:
        """(len(ids),) the leaf just past each box's face along ``axis`` (side -1: lower
        face, +1: upper), found at the face's centre; -1 where that face is Sigma's."""
        lo, hi = self.lo[ids], self.hi[ids]
        q = 0.5 * (lo + hi)
        q[:, axis] = hi[:, axis] + self.nudge[axis] if side > 0 else lo[:, axis] - self.nudge[axis]
        inside = (q[:, axis] >= self.lower[axis]) & (q[:, axis] <= self.upper[axis])
        out = np.full(len(ids), -1, dtype=np.int64)
        out[inside] = self.locate(q[inside])
        return out

    # -- refining -----------------------------------------------------------------------------
    def split(self, ids: np.ndarray, masks: np.ndarray, planes: np.ndarray | None = None) -> np.ndarray:
        """Split leaves ``ids`` along the axes of their ``masks`` (bit a: axis a), in half
        or at ``planes`` (len(ids), n) where given; -> the children's ids, parent by
        parent, children in the order ``locate`` codes them."""
        planes = self.centres(ids) if planes is None else np.asarray(planes, dtype=float)
        out = []
        counts = np.array([bin(int(m)).count("1") for m in masks], dtype=np.int64)
        for k in np.unique(counts[counts > 0]):
            group, gmask = ids[counts == k], masks[counts == k]
            bits = ((gmask[:, None] >> np.arange(self.n)) & 1).astype(bool)
            axes = np.nonzero(bits)[1].reshape(len(group), k)  # each box's split axes, ascending
            codes = np.arange(1 << k)
            lo = np.repeat(self.lo[group], len(codes), axis=0)
            hi = np.repeat(self.hi[group], len(codes), axis=0)
            mid = np.repeat(planes[counts == k], len(codes), axis=0)
            rows = np.arange(len(lo))
            for j in range(k):
                axis = np.repeat(axes[:, j], len(codes))
                upper = ((np.tile(codes, len(group)) >> j) & 1).astype(bool)
                lo[rows[upper], axis[upper]] = mid[rows[upper], axis[upper]]
                hi[rows[~upper], axis[~upper]] = mid[rows[~upper], axis[~upper]]
            first = self._lo.extend(lo)[:: len(codes)]
            self._hi.extend(hi)
            self._child.extend(np.full((len(lo), 1), -1))
            self._mask.extend(np.zeros((len(lo), 1), dtype=np.int64))
            self._at.extend(0.5 * (lo + hi))
            self._child.view[group, 0] = first
            self._mask.view[group, 0] = gmask
            self._at.view[group] = planes[counts == k]
            out.append(first[:, None] + codes[None, :])
        return np.concatenate([c.ravel() for c in out]) if out else np.zeros(0, dtype=np.int64)

    # -- persistence --------------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        return {"part.lo": self.lo.copy(), "part.hi": self.hi.copy(), "part.child": self._child.view[:, 0].copy(),
                "part.mask": self._mask.view[:, 0].copy(), "part.at": self._at.view.copy()}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        lo, hi = state["part.lo"], state["part.hi"]
        if lo.shape != hi.shape or lo.ndim != 2 or lo.shape[1] != self.n or len(lo) < self.roots:
            raise ValueError(f"part.lo: shape {lo.shape}, expected (>= {self.roots}, {self.n})")
        for rows, value in ((self._lo, lo), (self._hi, hi), (self._child, state["part.child"][:, None]),
                            (self._mask, state["part.mask"][:, None]), (self._at, state["part.at"])):
            rows.size = 0
            rows.extend(value)
