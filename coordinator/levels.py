"""Alive centres of boxes of mixed half-widths (boundary refinement, issue 36): one
``PointIndex`` per half-width, under one numbering.

``PointIndex`` answers "is a state within r of an alive point" with cells of side 2r,
so every box of a level sits at a cell centre of its own level's index and a query is
mostly one array lookup there. A set refined only near its boundary holds boxes of a
few half-widths (delta0 * gamma^k); a state is covered when it lies in the box of any
alive centre at that centre's own half-width, so ``cover`` asks each level in a fixed
order (coarsest first: the interior holds most of the volume) and names the first
witness found. The order is a function of the changes applied, so a mirror that applies
the same changes names the same witnesses.

Ids are global, in insertion order (as ``PointIndex`` numbers them): ``points``,
``alive`` and ``half_width`` are indexed by them; each level maps its own ids to global
ones. ``resize`` moves boxes to another level (the round end re-tiles the band).
"""

from __future__ import annotations

import numpy as np

from coordinator.level_grid import NestedGrid
from coordinator.spatial import PointIndex
from coordinator.alive_points import AlivePoints
from coordinator.unique import unique_ints


class LeveledIndex(AlivePoints):
    """Points (N, n) with alive flags and a half-width each, one ``PointIndex`` per
    half-width. ``cover`` and ``any_within`` take each box's own half-width (their
    ``radius`` argument is the current one, kept for ``PointIndex``'s signature)."""

    def __init__(self, n: int, cell: float, origin, capacity: int = 1024, bounds=None):
        self.n = n
        self.cell = float(cell)  # of the current level: new points get half-width cell / 2
        self.origin = np.asarray(origin, dtype=float)
        self.bounds = None if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
        capacity = max(16, int(capacity))
        self.points = np.empty((capacity, n))
        self.alive = np.zeros(capacity, dtype=bool)
        self.half_width = np.zeros(capacity)
        self._level = np.full(capacity, -1, dtype=np.int8)
        self._local = np.full(capacity, -1, dtype=np.int64)
        self.count = 0
        self._alive = 0  # alive points, kept by insert and kill (a sum per ask is O(points), per change)
        self._levels: list[tuple[float, PointIndex]] = []  # (half-width, index)
        # per level: local id -> global id, in a buffer grown by doubling (a level of a
        # million points takes thousands of small inserts)
        self._globals: list[np.ndarray] = []
        # per level: (start, largest id before it): global ids increase from local id start on
        self._sorted: list[tuple[int, int]] = []
        self._last: list[int] = []  # per level: the last global id placed
        # what the levels say per finest cell (coordinator/level_grid.py): None when the
        # levels are not nested; rebuilt at the first query after a level is added
        self._grid: NestedGrid | None = None
        self._grid_stale = True
        self._ordered: list[int] = []  # ``_order``'s answer for as many levels

    # -- levels ----------------------------------------------------------------------------
    def _level_of(self, half_width: float) -> int:
        for i, (hw, _) in enumerate(self._levels):
            if abs(hw - half_width) <= 1e-12 * max(1.0, hw):
                return i
        index = PointIndex(self.n, 2 * half_width, self.origin, bounds=self.bounds)
        self._levels.append((float(half_width), index))
        self._globals.append(np.zeros(16, dtype=np.int64))
        self._sorted.append((0, -1))
        self._last.append(-1)
        self._grid, self._grid_stale = None, True
        if len(self._levels) > 127:
            raise OverflowError("leveled index: more than 127 half-widths")
        return len(self._levels) - 1

    def _global(self, level: int) -> np.ndarray:
        return self._globals[level][: self._levels[level][1].count]

    def _order(self) -> list[int]:
        """Levels asked by ``cover``: coarsest first (ties cannot occur: one level per width)."""
        if len(self._ordered) != len(self._levels):
            self._ordered = sorted(range(len(self._levels)), key=lambda i: -self._levels[i][0])
        return self._ordered

    def levels(self) -> list[float]:
        return sorted(hw for hw, _ in self._levels)

    # -- mutation --------------------------------------------------------------------------
    def _grow(self, need: int) -> None:
        if need <= len(self.points):
            return
        cap = max(2 * len(self.points), need)
        self.points = np.resize(self.points, (cap, self.n))
        for name, fill in (("alive", False), ("half_width", 0.0), ("_level", -1), ("_local", -1)):
            old = getattr(self, name)
            setattr(self, name, np.concatenate([old, np.full(cap - len(old), fill, dtype=old.dtype)]))

    def _place(self, ids: np.ndarray, half_width: float) -> None:
        """Put points ``ids`` (alive) into the level of ``half_width``."""
        level = self._level_of(half_width)
        _, index = self._levels[level]
        start = index.count
        local = index.insert(self.points[ids])
        buffer = self._globals[level]
        if index.count > len(buffer):
            buffer = self._globals[level] = np.resize(buffer, max(2 * len(buffer), index.count))
        buffer[start : index.count] = ids
        if len(ids) and (ids[0] <= self._last[level] or np.any(np.diff(ids) <= 0)):
            self._sorted[level] = (start + len(ids), max(self._last[level], int(ids.max())))
        if len(ids):
            self._last[level] = max(self._last[level], int(ids.max()))
        self._level[ids] = level
        self._local[ids] = local
        self.half_width[ids] = half_width
        if self._grid is not None:
            cells = index._centre_cell[local]
            self._grid.centres_changed(level, cells[cells >= 0])
            self._grid.reached(level, local[cells < 0])

    def insert(self, pts: np.ndarray, half_width=None) -> np.ndarray:
        """New alive points (ids continue the count), of half-width ``half_width`` (one
        value or one per point; default: the current level's, cell / 2)."""
        pts = np.atleast_2d(np.asarray(pts, dtype=float))
        k = len(pts)
        if self.count + k >= 2**31:
            raise OverflowError("spatial index: 2^31 points or more")
        self._grow(self.count + k)
        ids = np.arange(self.count, self.count + k)
        self.points[ids] = pts
        self.alive[ids] = True
        self.count += k
        self._alive += k
        if k == 0:
            return ids
        if half_width is None or np.ndim(half_width) == 0:
            self._place(ids, float(self.cell / 2 if half_width is None else half_width))
            return ids
        widths = np.broadcast_to(np.asarray(half_width, float), (k,))
        for hw in np.unique(widths):  # sorted: the same levels in the same order on every mirror
            self._place(ids[widths == hw], float(hw))
        return ids

    def _unplace(self, ids: np.ndarray) -> None:
        """Take alive points ``ids`` out of their levels."""
        for level in np.unique(self._level[ids]):
            mine = ids[self._level[ids] == level]
            index = self._levels[level][1]
            local = self._local[mine]
            index.kill(local)
            if self._grid is not None:
                cells = index._centre_cell[local]
                self._grid.centres_changed(level, cells[cells >= 0])

    def kill(self, ids) -> None:
        ids = unique_ints(np.asarray(ids, dtype=np.int64))
        ids = ids[self.alive[ids]]
        self._unplace(ids)
        self.alive[ids] = False
        self._alive -= len(ids)

    @property
    def alive_count(self) -> int:
        return self._alive

    def resize(self, ids, half_width: float) -> None:
        """Alive points ``ids`` become boxes of ``half_width`` (same ids)."""
        ids = unique_ints(np.asarray(ids, dtype=np.int64))
        ids = ids[self.alive[ids]]
        self._unplace(ids)
        if len(ids):
            self._place(ids, float(half_width))

    def recell(self, cell: float) -> None:
        """A new round: new points get half-width cell / 2; the boxes keep theirs."""
        self.cell = float(cell)

    # -- queries ---------------------------------------------------------------------------
    def any_within(self, queries: np.ndarray, radius: float | None = None) -> np.ndarray:
        """(B, n) -> (B,) bool: does some alive box (at its own half-width) hold each query?"""
        return self.cover(queries, radius) >= 0

    def cover(self, queries: np.ndarray, radius: float | None = None) -> np.ndarray:
        """(B, n) -> (B,) int64: the id of an alive box holding each query, or -1."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        if self._grid_stale:
            self._grid = NestedGrid.build(self._levels, self._globals, self._order())
            self._grid_stale = False
        if self._grid is None or len(q) == 0:
            found = np.full(len(q), -1, dtype=np.int64)
            todo = np.arange(len(q))
            levels = None
        else:  # the first step, and the levels worth a search, from the finest grid
            found, levels, outside = self._grid.lookup(q)
            todo = np.flatnonzero(outside)
        # first every level's home cell (one lookup each: most states lie in a lattice
        # box of some level), then the full search for the rest, level by level
        for level in self._order():
            if len(todo) == 0:
                break
            local = self._levels[level][1].home_cover(q[todo])
            if local is None:
                continue
            hit = local >= 0
            found[todo[hit]] = self._global(level)[local[hit]]
            todo = todo[~hit]
        if levels is not None:
            todo = np.flatnonzero((found < 0) & (levels != 0))
        for level in self._order():
            if len(todo) == 0:
                break
            hw, index = self._levels[level]
            rows = todo if levels is None else todo[(levels[todo] & (1 << level)) != 0]
            if len(rows) == 0:
                continue
            # no level has a centre point at these rows' home cells (the grid, or the
            # first step above, found none): only the cells around are searched
            local = index.cover_away(q[rows], hw)
            hit = local >= 0
            found[rows[hit]] = self._global(level)[local[hit]]
            todo = todo[found[todo] < 0]
        return found

    def covered_by_since(self, queries: np.ndarray, radius: float | None, first: int) -> np.ndarray | None:
        """(B, n) -> (B,) bool: does an alive box with id >= ``first`` hold each query (by
        the rule ``cover`` applies)? None when a level holds an older point after one of
        those (a resize moved it there): ask ``cover``."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        out = np.zeros(len(q), dtype=bool)
        for level in self._order():
            hw, index = self._levels[level]
            glob = self._global(level)
            start, before = self._sorted[level]
            if before >= first:  # a point placed out of order has an id >= first
                return None
            local_first = start + int(np.searchsorted(glob[start:], first))
            if local_first < index.count:
                out |= index.covered_by_since(q, hw, local_first)
        return out

    # -- persistence (plain arrays, no pickle) -----------------------------------------------
    def state(self) -> dict:
        out = self._snapshot()
        out.update({"half_width": self.half_width[: self.count].copy(),
                    "levels": np.array([hw for hw, _ in self._levels]),
                    "level": self._level[: self.count].copy(), "local": self._local[: self.count].copy()})
        # each level's points in its own insertion order: the witnesses a mirror names
        for i in range(len(self._levels)):
            out[f"level{i}"] = self._global(i).copy()
        return out

    @classmethod
    def from_state(cls, state: dict) -> "LeveledIndex":
        pts = state["points"]
        idx = cls._empty_for(state)
        idx._grow(len(pts))
        idx.points[: len(pts)] = pts
        idx.count = len(pts)
        idx.half_width[: len(pts)] = state["half_width"]
        for i, hw in enumerate(np.asarray(state["levels"], dtype=float)):
            ids = np.asarray(state[f"level{i}"], dtype=np.int64)
            idx.alive[ids] = True  # placed alive, in order; the dead are killed below
            idx._place(ids, float(hw))
        # a resized point was placed in every level it passed through: its own is recorded
        idx._level[: len(pts)] = state["level"]
        idx._local[: len(pts)] = state["local"]
        for i in range(len(idx._levels)):
            glob = idx._global(i)
            own = (idx._level[glob] == i) & (idx._local[glob] == np.arange(len(glob)))
            idx._levels[i][1].kill(np.flatnonzero(~own))
        idx.alive[: len(pts)] = True
        idx._alive = len(pts)
        idx.kill(np.flatnonzero(~np.asarray(state["alive"], dtype=bool)))
        return idx
