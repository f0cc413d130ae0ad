"""Which of M closed axis-aligned boxes hold a point: a k-d tree over the boxes.

For sets whose boxes have a half-width per axis (margin refinement) the cell grids of
coordinator/spatial.py do not fit: a box may span many cells on one axis and a fraction
of one on another. Here the boxes are split recursively by a plane through a box face
(the median lower face along the axis where the boxes spread most): boxes below it go
left, above it right, and the few that straddle it both ways. A query then walks one
path (two where it lies on a plane), all queries at once, level by level: memory and
build time about linear in M, a query's cost linear in n and log M, in any dimension.
"""

from __future__ import annotations

import numpy as np

LEAF_SIZE = 8
TOLERANCE = 1e-9  # closed boxes, decided as exact arithmetic would on shared faces
QUERY_BLOCK = 1 << 17  # points walked down at once
MAX_STRADDLE = 0.3  # a plane that more than this share of a node's boxes straddle makes a leaf


class BoxIndex:
    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        """``lo``, ``hi`` (M, n): the boxes' lower and upper corners."""
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        axis_of, plane, left, right, members = [], [], [], [], []
        stack = [(np.arange(len(self.lo)), -1, 0)]  # (boxes, parent, 0: left / 1: right)
        while stack:
            rows, parent, side = stack.pop()
            node = len(axis_of)
            if parent >= 0:
                (left if side == 0 else right)[parent] = node
            axis_of.append(-1)
            plane.append(0.0)
            left.append(-1)
            right.append(-1)
            members.append(rows)
            cut = self._cut(rows) if len(rows) > LEAF_SIZE else None
            if cut is not None:
                axis, at, below, above = cut
                axis_of[node], plane[node] = axis, at
                members[node] = None
                stack.append((rows[above], node, 1))
                stack.append((rows[below], node, 0))
        self.axis, self.plane = np.array(axis_of, dtype=np.int64), np.array(plane)
        self.left, self.right = np.array(left, dtype=np.int64), np.array(right, dtype=np.int64)
        counts = np.array([0 if m is None else len(m) for m in members], dtype=np.int64)
        self.first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self.count = counts
        self.boxes = np.concatenate([m for m in members if m is not None] or [np.zeros(0, np.int64)])

    def _cut(self, rows: np.ndarray):
        """(axis, plane, below, above) for the boxes ``rows``, or None (a leaf)."""
        lo, hi = self.lo[rows], self.hi[rows]
        spread = hi.max(axis=0) - lo.min(axis=0)
        for axis in np.argsort(-spread):
            faces = lo[:, axis]
            at = float(np.partition(faces, len(faces) // 2)[len(faces) // 2])
            below = hi[:, axis] <= at + TOLERANCE
            above = lo[:, axis] >= at - TOLERANCE
            straddle = ~below & ~above
            below |= straddle
            above |= straddle
            if below.all() or above.all() or straddle.mean() > MAX_STRADDLE:
                continue
            return int(axis), at, below, above
        return None

    def __len__(self) -> int:
        return len(self.lo)

    def locate(self, points: np.ndarray, first_found: bool = False) -> np.ndarray:
        """(P, n) -> (P,) a box holding each point (the lowest id among those found), or -1.
        ``first_found``: any box holding it instead, a point leaving the walk at its first box
        found, which keeps heavily overlapping boxes (a covering widened past its boxes)
        cheap for the points inside them."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        out = np.full(len(points), -1, dtype=np.int64)
        if len(self.lo) == 0:
            return out
        for lo in range(0, len(points), QUERY_BLOCK):
            out[lo : lo + QUERY_BLOCK] = self._locate(points[lo : lo + QUERY_BLOCK], first_found)
        return out

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(P, n) -> (P,) bool: in some box."""
        return self.locate(points, first_found=True) >= 0

    def _locate(self, points: np.ndarray, first_found: bool = False) -> np.ndarray:
        none = np.iinfo(np.int64).max
        out = np.full(len(points), none)
        query = np.arange(len(points))
        node = np.zeros(len(points), dtype=np.int64)
        while len(query):
            leaf = self.axis[node] < 0
            self._check_leaves(points, query[leaf], node[leaf], out, first_found)
            query, node = query[~leaf], node[~leaf]
            if first_found:  # a point found on one path needs no other
                open_ = out[query] == none
                query, node = query[open_], node[open_]
            x = points[query, self.axis[node]]
            at = self.plane[node]
            go_left = x <= at + TOLERANCE
            go_right = x >= at - TOLERANCE
            query = np.concatenate([query[go_left], query[go_right]])
            node = np.concatenate([self.left[node[go_left]], self.right[node[go_right]]])
        return np.where(out == none, -1, out)

    def _check_leaves(self, points, query, node, out, first_found: bool = False) -> None:
        """Each (query, leaf) pair against the leaf's boxes, one box rank j at a time; with
        ``first_found`` a pair is dropped at its first hit."""
        count = self.count[node]
        for j in range(int(count.max()) if len(query) else 0):
            has = count > j
            if not has.all():
                query, node, count = query[has], node[has], count[has]
            if len(query) == 0:
                return
            box = self.boxes[self.first[node] + j]
            p = points[query]
            hit = ((p >= self.lo[box] - TOLERANCE) & (p <= self.hi[box] + TOLERANCE)).all(axis=1)
            np.minimum.at(out, query[hit], box[hit])
            if first_found and hit.any():
                query, node, count = query[~hit], node[~hit], count[~hit]
