"""What the levels of a ``LeveledIndex`` say about each cell of its finest grid, so that
``cover`` settles most queries with one lookup instead of asking every level.

``LeveledIndex.cover`` asks the levels in a fixed order (coarsest first): first for a
centre point at the query's home cell of each level (a centre point covers its whole
cell), then with a full search, level by level. When every level's cell is the finest
level's cell times a power of two, on the same origin (the half-widths delta0 *
gamma^k of gamma = 1/2), every finest cell lies in exactly one cell of each level, and
one array over the finest grid holds, per cell:

- ``witness``: the id the first step names for any query in that cell (the centre
  point of the first level, in order, whose cell holds one), or -1;
- ``reach``: one bit per level: an off-centre point of that level comes within its
  half-width (plus the tolerance) of the cell, or came (bits are set as points come,
  and cleared only by a rebuild).

A query in the grid's interior whose cell has a witness gets it. One whose cell has no
witness can be covered only by an off-centre point (the levels whose ``reach`` bit is
set) or, when it lies within ``face`` of a cell face, by the centre point of a cell
across that face (a centre point covers its own cell and, within the tolerance, no
more: ``centred``, a bit per level, says which levels have one there); only those
levels are searched, each exactly as before. Queries outside the interior ask every
level. Answers are the ones the levels give, so the witnesses named do not change.

The arrays follow every change the index makes (``centres_changed``, ``reached``);
a new level (a finer one changes the grid) marks them stale and the next query rebuilds
them. Arrays are laid out as the finest level's dense grid (coordinator/spatial.py).
"""

from __future__ import annotations

import itertools

import numpy as np

from coordinator.cell_grid import box_cells, flat_index
from coordinator.spatial import LINK, TOLERANCE, PointIndex

MAX_LEVELS = 8  # the bits of ``reach`` (uint8)
SLAB = 1 << 20  # finest cells recomputed per pass: temporaries stay ~50 MB
EDGE = 1e-6  # cells (in cell units) that a point's reach touches are widened by this


class NestedGrid:
    """Per finest cell: the first-step witness and the levels within reach (see above)."""

    def __init__(self, levels: list[tuple[float, PointIndex]], globals_: list[np.ndarray], order: list[int]):
        """``levels``: (half-width, index) per level id; ``globals_[level]``: its local ->
        global ids (the index's own list, read at each use: its buffers grow); ``order``:
        the level ids in the order ``cover`` asks them. Nothing here refers back to the
        index, so the index is freed as soon as it is dropped (no reference cycle)."""
        self.levels, self.globals_, self.order = levels, globals_, order
        finest = min(range(len(levels)), key=lambda i: levels[i][0])
        self.finest = levels[finest][1]
        self.cell = self.finest.cell
        self.origin = self.finest.origin
        self.shift = [int(round(np.log2(hw / levels[finest][0]))) for hw, _ in levels]
        self.interior = self.finest._shape - 2  # finest cells inside the bounds, per axis
        self.strides = self.finest._strides
        coarsest = max(index.cell for _, index in levels)
        # a centre point lies within 1e-9 cells of its cell's centre (spatial.py) and covers
        # its box plus the tolerance: beyond FACE from every face no other cell's reaches
        self.face = 4 * (TOLERANCE + 1e-9 * coarsest)
        size = len(self.finest._centre_point)
        self.witness = np.full(size, -1, dtype=LINK)
        self.reach = np.zeros(size, dtype=np.uint8)
        self.centred = np.zeros(size, dtype=np.uint8)  # bit per level: its cell there has a centre point
        self._offsets: dict[int, np.ndarray] = {}  # finest cells in a cell of 2^shift per axis
        self._fill()

    @classmethod
    def build(cls, levels, globals_, order) -> "NestedGrid | None":
        """The grid of ``levels``, or None when they are not nested powers of two of the
        finest on one origin, one of them has no dense grid, or they are too many."""
        if not levels or len(levels) > MAX_LEVELS:
            return None
        hw_min = min(hw for hw, _ in levels)
        finest = next(index for hw, index in levels if hw == hw_min)
        for hw, index in levels:
            k = np.log2(hw / hw_min)
            if (index._dense is None or abs(k - round(k)) > 1e-9 or hw != hw_min * 2.0 ** round(k)
                    or not np.array_equal(index.origin, finest.origin) or index.cell != 2 * hw):
                return None
        return cls(levels, globals_, order)

    # -- building ------------------------------------------------------------------------------
    def _parent_flat(self, level: int, cells: np.ndarray) -> np.ndarray:
        """(k, n) interior finest cells -> flat cells of ``level``'s dense grid holding them."""
        index = self.levels[level][1]
        return flat_index((cells >> self.shift[level]) + 1, index._strides)

    def _refresh(self, cells: np.ndarray) -> None:
        """Recompute ``witness`` and ``centred`` of interior finest cells ``cells`` (k, n)."""
        if len(cells) == 0:
            return
        out = np.full(len(cells), -1, dtype=np.int64)
        bits = np.zeros(len(cells), dtype=np.uint8)
        for level in reversed(self.order):  # the first level in order is written last: it wins
            centre = self.levels[level][1]._centre_point[self._parent_flat(level, cells)]
            hit = centre >= 0
            out[hit] = self.globals_[level][centre[hit]]
            bits[hit] |= np.uint8(1 << level)
        flat = flat_index(cells + 1, self.strides)
        self.witness[flat] = out
        self.centred[flat] = bits

    def _fill(self) -> None:
        """Every interior cell's witness and reach bits, in slabs along the first axis."""
        rest = self.interior[1:]
        per = max(1, SLAB // max(1, int(np.prod(rest))))
        tail = np.stack(np.meshgrid(*[np.arange(s) for s in rest], indexing="ij"), -1).reshape(-1, len(rest))
        for at in range(0, int(self.interior[0]), per):
            first = np.arange(at, min(at + per, int(self.interior[0])))
            cells = np.column_stack([np.repeat(first, len(tail)), np.tile(tail, (len(first), 1))])
            self._refresh(cells)
        for level, (_, index) in enumerate(self.levels):
            off = np.flatnonzero(index.alive[: index.count] & (index._centre_cell[: index.count] < 0))
            self.reached(level, off)

    # -- changes ---------------------------------------------------------------------------------
    def _finest_of(self, level: int, flat: np.ndarray):
        """(k,) flat cells of ``level``'s dense grid -> the interior finest cells in them,
        (m, n) per pass of at most ~SLAB."""
        index = self.levels[level][1]
        coords = (flat[:, None] // index._strides) % index._shape - 1  # the margin is -1
        side = 1 << self.shift[level]
        offsets = self._offsets.get(side)
        if offsets is None:
            offsets = np.array(list(itertools.product(range(side), repeat=len(self.interior))), dtype=np.int64)
            self._offsets[side] = offsets
        step = max(1, SLAB // len(offsets))
        for at in range(0, len(coords), step):
            cells = (coords[at : at + step, None, :] * side + offsets[None]).reshape(-1, len(self.interior))
            yield cells[((cells >= 0) & (cells < self.interior)).all(axis=1)]

    def centres_changed(self, level: int, flat: np.ndarray) -> None:
        """The centre points of ``level``'s cells ``flat`` (its dense grid) changed."""
        if len(flat):
            for cells in self._finest_of(level, np.unique(flat)):
                self._refresh(cells)

    def reached(self, level: int, local: np.ndarray) -> None:
        """Off-centre points ``local`` of ``level`` came: set the level's bit in the
        interior finest cells their boxes reach (half-width plus the tolerance, widened
        by EDGE). A point that goes leaves its bits set: a bit may only send a query to
        a search that finds nothing, and the next new level rebuilds them."""
        if len(local) == 0:
            return
        hw, index = self.levels[level]
        n = len(self.interior)
        reach = (hw + TOLERANCE) / self.cell + EDGE
        span = int(np.ceil(2 * reach)) + 1  # finest cells a box reaches per axis, at most
        step = max(1, SLAB // span**n)
        bit = np.uint8(1 << level)
        for at in range(0, len(local), step):
            rel = (index.points[local[at : at + step]] - self.origin) / self.cell
            lo = np.maximum(np.floor(rel - reach).astype(np.int64), 0)
            hi = np.minimum(np.floor(rel + reach).astype(np.int64), self.interior - 1)
            # the cells lo..hi per axis, enumerated as spatial.py's _check_cells does
            k = len(rel)
            flat = np.zeros((k, 1), dtype=np.int64)
            valid = np.ones((k, 1), dtype=bool)
            for axis in range(n):
                cells = lo[:, axis, None] + np.arange(span)
                ok = cells <= hi[:, axis, None]
                parts = (cells + 1) * self.strides[axis]
                flat = (flat[:, :, None] + parts[:, None, :]).reshape(k, -1)
                valid = (valid[:, :, None] & ok[:, None, :]).reshape(k, -1)
            self.reach[flat[valid]] |= bit

    # -- queries --------------------------------------------------------------------------------
    def lookup(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B, n) -> witness (B,) int64 (the first step's, -1: none; outside the interior
        always -1), levels (B,) uint8 (the bits of the levels that may cover it by a full
        search; 0xFF: every level) and outside (B,) bool (outside the interior: the first
        step is to be asked of the levels)."""
        rel = q - self.origin
        rel *= 1.0 / self.cell
        home = np.floor(rel).astype(np.int64)
        # a query outside the interior lands in the margin, whose cells name no witness
        clipped = np.minimum(np.maximum(home, -1), self.interior)
        witness = self.witness[flat_index(clipped + 1, self.strides)].astype(np.int64)
        levels = np.zeros(len(q), dtype=np.uint8)
        outside = np.zeros(len(q), dtype=bool)
        miss = np.flatnonzero(witness < 0)  # most queries have a witness: the rest is for the few
        if len(miss) == 0:
            return witness, levels, outside
        home, rel = home[miss], rel[miss]
        out = ((home < 0) | (home >= self.interior)).any(axis=1)
        outside[miss[out]] = True
        frac = rel - home
        near_lo = frac <= self.face / self.cell
        near_hi = frac >= 1.0 - self.face / self.cell
        inside = np.flatnonzero(~out)
        levels[miss[out]] = 0xFF
        levels[miss[inside]] = self.reach[flat_index(home[inside] + 1, self.strides)]
        near = inside[(near_lo[inside] | near_hi[inside]).any(axis=1)]
        if len(near):
            levels[miss[near]] |= self._across_faces(home[near], near_lo[near], near_hi[near])
        return witness, levels, outside

    def _across_faces(self, home: np.ndarray, near_lo: np.ndarray, near_hi: np.ndarray) -> np.ndarray:
        """(k,) uint8: the levels with a centre point in a finest cell across a face that
        each query (in ``home``) lies near: a centre point covers its cell within the
        tolerance, so only those can cover the query from a cell other than its own
        (0xFF when such a cell is outside the interior: every level is asked)."""
        lo, hi = home - near_lo, home + near_hi
        beyond = ((lo < 0) | (hi >= self.interior)).any(axis=1)
        row_of, cells = box_cells(lo, hi, 2)
        bits = self.centred[flat_index(np.minimum(np.maximum(cells, -1), self.interior) + 1, self.strides)]
        # each row's cells are consecutive, its own (lo) first
        out = np.bitwise_or.reduceat(bits, np.flatnonzero(np.r_[True, row_of[1:] != row_of[:-1]]))
        out[beyond] = 0xFF
        return out
