"""Batched l-infinity proximity queries over a growing point set: a hashed cell grid.

Points live in cells of side ``cell`` (anchored at ``origin``); a chained hash table maps
a cell to the points in it. "Is there an alive point within r of q" (r <= cell/2) looks
at most 2 cells per axis, and since lattice centres sit at cell centres, almost every
query is settled by its home cell. Hash collisions only lengthen chains: every candidate
is checked by its true distance, so answers are exact.

Everything is vectorized over query batches; insertion is vectorized over point batches;
removal is a flag (chains are rebuilt when the table grows or the cell size changes).

Fast path: when the index is given ``bounds`` and the cells over them number at most
``DENSE_LIMIT``, a dense array names one alive point sitting exactly at each cell's
centre (and counts them). Such a point covers its whole cell, so a query in that cell
is answered by one array lookup, which also names the witness. A query whose home cell
has none checks the 2^n cells its ball touches (3^n for a query within the tolerance of
a cell centre): their centre points by true distance, and their off-centre points, which
are chained per dense cell. The hash chains serve indices without a dense grid.
"""

from __future__ import annotations

import numpy as np

from coordinator.alive_points import AlivePoints
from coordinator.cell_grid import SMALL_MATMUL, box_cells, box_offsets, flat_index
from coordinator.unique import unique_ints

_P = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
               0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53,
               0x2545F4914F6CDD1D, 0x9FB21C651E98DF25], dtype=np.uint64)


def _multipliers(n: int) -> np.ndarray:
    """(n,) odd 64-bit multipliers of the cell hash: ``_P`` (whose buckets every result so
    far was computed with), extended for n > 8 by splitmix64 from a fixed seed."""
    if n <= len(_P):
        return _P[:n]
    extra, state = [], 0x243F6A8885A308D3
    for _ in range(n - len(_P)):
        state = (state + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
        extra.append((z ^ (z >> 31)) | 1)
    return np.concatenate([_P, np.array(extra, dtype=np.uint64)])
TOLERANCE = 1e-9  # closed boxes, decided as exact arithmetic would on grid boundaries
# ``any_within`` may ask a KD-tree from this dimension on, for a batch of at least this many
# queries, when its misses times 2^n exceed this many times the points: a tree costs its
# build, the cells at least 2^n per miss
TREE_DIMENSION = 5
TREE_QUERIES = 4096
TREE_WORK = 4
DENSE_LIMIT = 1 << 25  # cells; 32 Mi int32 counters = 128 MiB at most
SMALL_PUSH = 8  # points pushed one by one: ~12 array operations cost more below this
MISS_BLOCK = 1 << 15  # queries whose touched cells are enumerated at once (2^n cells each)
ORDERED_CELLS = 1 << 14  # query-cell pairs tried at once where each query's cells are tried in order
ORDERED_QUERIES = ORDERED_CELLS  # ... by blocks up to this many queries, cell by cell past it (docs/benchmarks.md)
CENTRE_SLACK = 2e-9  # [cells] how far from its cell's centre a centre point may sit (1e-9), and rounding
SMALL_ROWS = 256  # point-query pairs up to which (k, n) comparisons beat n 1-D ones
# point ids and dense cell numbers in the chains and the dense grid: both < 2^31 (a dense
# grid has at most DENSE_LIMIT cells; ``insert`` refuses the 2^31st point). Half of int64:
# ~0.1 GB at delta_min 0.125 (1.8 M points, 7 M dense cells, in the centres' and the
# failures' index alike). Queries still answer int64 ids.
LINK = np.int32


def point_tree(points: np.ndarray):
    """A KD-tree of ``points`` (N, n) for ``tree_within``. Unbalanced, uncompacted nodes:
    a third of the build time of scipy's default, and queries no slower (docs/benchmarks.md)."""
    from scipy.spatial import cKDTree  # here: scipy.spatial is 0.4 s of every CLI start

    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def tree_within(tree, q: np.ndarray, radius: float, workers: int = 1) -> np.ndarray:
    """(B, n) -> (B,) bool: is a point of ``tree`` (``point_tree``) within l-inf distance
    ``radius`` of each query, max over axes of |p - q| <= radius + the tolerance (what
    ``cover``'s rules come to, the same float64 maximum). ``workers``: threads of the
    query (scipy's; -1: every core), the answer the same whatever their number."""
    if len(q) == 0 or tree.n == 0:
        return np.zeros(len(q), dtype=bool)
    r = radius + TOLERANCE
    d, _ = tree.query(q, k=1, p=np.inf, distance_upper_bound=np.nextafter(r, np.inf), workers=workers)
    return d <= r


class PointIndex(AlivePoints):
    """Points (N, n) with alive flags, hashed by cell. ``cell`` must be >= 2 * radius of
    every ``any_within`` query."""

    def __init__(self, n: int, cell: float, origin, capacity: int = 1024, bounds=None):
        self.n = n
        self.cell = float(cell)
        self.origin = np.asarray(origin, dtype=float)
        capacity = max(16, int(capacity))
        self.points = np.empty((capacity, n))
        self.alive = np.zeros(capacity, dtype=bool)
        self.next = np.full(capacity, -1, dtype=LINK)
        self.count = 0
        self._alive = 0  # alive points, kept by insert and kill (``alive_count``: a sum per ask was O(points))
        self._heads = np.full(64, -1, dtype=LINK)
        self._buckets = 64  # the hash table's size once the deferred chain work is done
        self._chain_work: list[tuple] = []  # ("rehash", buckets, count) / ("link", lo, hi), in order
        self.bounds = None if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
        self._dense = None
        self._centre_cell = np.full(capacity, -1, dtype=LINK)  # flat dense cell if at a centre
        self._off_next = np.full(capacity, -1, dtype=LINK)  # off-centre chains (dense)
        self._build_dense()

    # -- dense fast path --------------------------------------------------------------------
    def _build_dense(self) -> None:
        self._dense = None
        if self.bounds is None:
            return
        # one empty cell of margin on each side: a query outside is clipped into the
        # margin (count 0) and falls through to the exact chain walk
        shape = np.floor((self.bounds[1] - self.origin) / self.cell).astype(np.int64) + 3
        if np.any(shape <= 2) or np.prod(shape.astype(float)) > DENSE_LIMIT:
            return
        self._shape = shape
        self._last_cell = shape - 1
        self._strides = np.cumprod(np.concatenate([shape[1:], [1]])[::-1])[::-1].astype(np.int64)
        self._dense = np.zeros(int(np.prod(shape)), dtype=np.int32)
        # the id of one alive centre point per cell (-1: none), so that a hit names its
        # witness
        self._centre_point = np.full(int(np.prod(shape)), -1, dtype=LINK)
        self._others = np.zeros(int(np.prod(shape)), dtype=np.int32)  # off-centre points per cell
        self._off_head = np.full(int(np.prod(shape)), -1, dtype=LINK)  # their chains
        ids = np.arange(self.count)
        centre_cells, flat = self._dense_cells(self.points[: self.count])
        self._centre_cell[: self.count] = centre_cells
        live = ids[self.alive[: self.count] & (centre_cells >= 0)]
        np.add.at(self._dense, centre_cells[live], 1)
        self._centre_point[centre_cells[live]] = live
        off = ids[self.alive[: self.count] & (centre_cells < 0)]
        np.add.at(self._others, flat[off], 1)
        self._off_alive = len(off)  # alive off-centre points: without any, no chain is walked
        self._push(off, flat[off], self._off_head, self._off_next)

    def _flat(self, cells: np.ndarray) -> np.ndarray:
        """Flat dense index of integer cells (clipped into the margin when outside). A
        few cells as one (k, n) product (most calls: fewer array operations); many per
        axis with 1-D operations (numpy has no fast integer matmul)."""
        if len(cells) <= SMALL_MATMUL:
            part = cells + 1
            np.maximum(part, 0, out=part)
            np.minimum(part, self._last_cell, out=part)
            return flat_index(part, self._strides)
        flat = self._axis_flat(cells[:, 0], 0)
        for axis in range(1, self.n):
            flat += self._axis_flat(cells[:, axis], axis)
        return flat

    def _axis_flat(self, cells: np.ndarray, axis: int) -> np.ndarray:
        """One axis's part of the flat dense index (the cell clipped into the margin)."""
        part = cells + 1
        np.minimum(np.maximum(part, 0, out=part), self._shape[axis] - 1, out=part)
        part *= self._strides[axis]
        return part

    def _dense_cells(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(flat dense cell if at a cell centre else -1, flat dense cell) of each point:
        the second is ``_flat(_cells(pts))`` (the same floor of the same quotient)."""
        rel = (pts - self.origin) / self.cell
        cells = np.floor(rel).astype(np.int64)
        at_centre = (np.abs(rel - cells - 0.5) <= 1e-9).all(axis=1)
        at_centre &= ((cells >= 0) & (cells + 1 < self._shape - 1)).all(axis=1)
        flat = self._flat(cells)
        return np.where(at_centre, flat, -1), flat

    # -- hashing ----------------------------------------------------------------------
    def _cells(self, pts: np.ndarray) -> np.ndarray:
        return np.floor((pts - self.origin) / self.cell).astype(np.int64)

    def _bucket(self, cells: np.ndarray) -> np.ndarray:
        with np.errstate(over="ignore"):
            h = (cells.astype(np.uint64) * _multipliers(cells.shape[1])).sum(axis=1, dtype=np.uint64)
            h ^= h >> np.uint64(31)
            h *= np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(29)
        return (h & np.uint64(len(self._heads) - 1)).astype(np.int64)

    def _link(self, ids: np.ndarray) -> None:
        """Push points ``ids`` onto the chains of their hash buckets."""
        if len(ids):
            self._push(ids, self._bucket(self._cells(self.points[ids])), self._heads, self.next)

    @staticmethod
    def _push(ids: np.ndarray, keys: np.ndarray, heads: np.ndarray, links: np.ndarray) -> None:
        """Push points ``ids`` onto the chains ``heads[keys]`` (vectorized; a few points
        one by one, in the given order, which links them exactly as the grouped form)."""
        if len(ids) == 0:
            return
        if len(ids) <= SMALL_PUSH:
            for point, key in zip(ids.tolist(), keys.tolist()):
                links[point] = heads[key]
                heads[key] = point
            return
        order = np.argsort(keys, kind="stable")
        ids, keys = ids[order], keys[order]
        first = np.ones(len(ids), dtype=bool)
        first[1:] = keys[1:] != keys[:-1]
        # within a key group, each point links to the previous one; the first links
        # to the old head; the last becomes the new head
        prev = np.empty(len(ids), dtype=np.int64)
        prev[1:] = ids[:-1]
        prev[first] = heads[keys[first]]
        links[ids] = prev
        last = np.ones(len(ids), dtype=bool)
        last[:-1] = keys[:-1] != keys[1:]
        heads[keys[last]] = ids[last]

    def _rehash(self, buckets: int, count: int) -> None:
        """Hash chains of a table of ``buckets`` over the alive points among the first
        ``count``."""
        self._heads = np.full(buckets, -1, dtype=LINK)
        self.next[:count] = -1
        self._link(np.nonzero(self.alive[:count])[0])

    def _chains(self, work: tuple) -> None:
        """The hash chains' share of an insert (or a recell): done now without a dense
        grid, else kept until a query walks the chains (``_sync_chains``). With a dense
        grid no query at radius cell/2, i.e. none a campaign makes, walks them, and
        linking cost an insert of a few points ~40% of its time."""
        if work[0] == "rehash":  # it relinks every alive point: the earlier work is moot
            self._chain_work = [work]
        else:
            self._chain_work.append(work)
        if self._dense is None:
            self._sync_chains()

    def _sync_chains(self) -> None:
        """Do the deferred chain work, in order. A rehash done late leaves out the points
        killed since it was due; they would only have been skipped (walks check
        ``alive``), and the alive points keep their order in every chain (newest
        first), so every walk finds what it found with the work done at once."""
        for work in self._chain_work:
            if work[0] == "rehash":
                self._rehash(work[1], work[2])
            else:
                self._link(np.arange(work[1], work[2]))
        self._chain_work = []

    # -- mutation -----------------------------------------------------------------------
    def insert(self, pts: np.ndarray) -> np.ndarray:
        pts = np.atleast_2d(np.asarray(pts, dtype=float))
        k = len(pts)
        if self.count + k >= 2**31:
            raise OverflowError("spatial index: 2^31 points or more")
        if self.count + k > len(self.points):
            cap = max(2 * len(self.points), self.count + k)
            self.points = np.resize(self.points, (cap, self.n))
            self.alive = np.concatenate([self.alive, np.zeros(cap - len(self.alive), dtype=bool)])
            self.next = np.concatenate([self.next, np.full(cap - len(self.next), -1, dtype=LINK)])
            self._centre_cell = np.concatenate([self._centre_cell, np.full(cap - len(self._centre_cell), -1,
                                                                            dtype=LINK)])
            self._off_next = np.concatenate([self._off_next, np.full(cap - len(self._off_next), -1, dtype=LINK)])
        ids = np.arange(self.count, self.count + k)
        self.points[ids] = pts
        self.alive[ids] = True
        self.count += k
        self._alive += k
        if self._dense is not None:
            cells, flat = self._dense_cells(pts)
            self._centre_cell[ids] = cells
            centred = cells >= 0
            if centred.any():
                np.add.at(self._dense, cells[centred], 1)
                self._centre_point[cells[centred]] = ids[centred]
            if not centred.all():
                off = ~centred
                np.add.at(self._others, flat[off], 1)
                self._off_alive += int(np.count_nonzero(off))
                self._push(ids[off], flat[off], self._off_head, self._off_next)
        if self.count > self._buckets // 2:
            self._buckets = 1 << int(np.ceil(np.log2(4 * self.count)))
            self._chains(("rehash", self._buckets, self.count))
        else:
            self._chains(("link", self.count - k, self.count))
        return ids

    @property
    def alive_count(self) -> int:
        return self._alive

    def kill(self, ids) -> None:
        ids = unique_ints(np.asarray(ids, dtype=np.int64))
        was = self.alive[ids]
        self._alive -= int(np.count_nonzero(was))
        if self._dense is not None:
            dying = ids[was]
            centred = self._centre_cell[dying] >= 0
            cells = self._centre_cell[dying[centred]]
            np.subtract.at(self._dense, cells, 1)
            known = self._centre_point[cells] == dying[centred]
            self._centre_point[cells[known]] = -1
            self.alive[ids] = False
            orphaned = unique_ints(cells[known])
            self._rename(orphaned[self._dense[orphaned] > 0])
            np.subtract.at(self._others, self._flat(self._cells(self.points[dying[~centred]])), 1)
            self._off_alive -= int(np.count_nonzero(~centred))
        self.alive[ids] = False

    def _rename(self, cells: np.ndarray) -> None:
        """Name another alive centre point for cells whose named one was killed (rare:
        two points at one cell centre). Cells in insertion order of their points."""
        if len(cells) == 0:
            return
        ids = np.flatnonzero(self.alive[: self.count] & np.isin(self._centre_cell[: self.count], cells))
        self._centre_point[self._centre_cell[ids]] = ids

    def recell(self, cell: float) -> None:
        """Change the cell size (when delta shrinks) and rebuild the chains."""
        self.cell = float(cell)
        self._build_dense()
        self._chains(("rehash", self._buckets, self.count))

    # -- queries ------------------------------------------------------------------------
    def any_within(self, queries: np.ndarray, radius: float) -> np.ndarray:
        """(B, n) -> (B,) bool: is some alive point within l-inf distance ``radius``? In a
        high dimension the queries the home cell does not settle are asked of a KD-tree
        of the alive points when there are many of them (``_tree_within``): each checks the
        2^n to 3^n cells its ball touches (a round end's children in 7-D: docs/benchmarks.md),
        a tree costs its build once."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        if self.n < TREE_DIMENSION or len(q) < TREE_QUERIES or self.count == 0:
            return self.cover(q, radius) >= 0
        home = self.home_cover(q) if radius >= self.cell / 2 - 1e-12 else None  # a centre point covers its cell
        inside = np.zeros(len(q), dtype=bool) if home is None else home >= 0
        misses = np.flatnonzero(~inside)
        if len(misses) * 2**self.n > TREE_WORK * self.count:
            inside[misses] = self._tree_within(q[misses], radius)
        elif len(misses):
            inside[misses] = self.cover(q[misses], radius) >= 0
        return inside

    def _tree_within(self, q: np.ndarray, radius: float) -> np.ndarray:
        """``any_within`` by the true distance alone, max over axes of |p - q| <= radius +
        the tolerance, which is what ``cover``'s rules come to (a centre point covers its
        cell because it lies within cell/2 of all of it): a KD-tree's nearest alive point
        within that bound, the same float64 maximum."""
        points = self.alive_points()
        if len(points) == 0 or len(q) == 0:
            return np.zeros(len(q), dtype=bool)
        return tree_within(point_tree(points), q, radius)

    def cover(self, queries: np.ndarray, radius: float) -> np.ndarray:
        """(B, n) -> (B,) int64: the id of an alive point within l-inf distance
        ``radius`` of each query (a witness), or -1 if there is none."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        found = np.full(len(q), -1, dtype=np.int64)
        if self.count == 0 or len(q) == 0:
            return found
        r = radius + TOLERANCE
        rel = q - self.origin
        rel *= 1.0 / self.cell
        home = np.floor(rel).astype(np.int64)
        todo = None
        if self._dense is not None and abs(radius - self.cell / 2) <= 1e-12:
            # a centre point covers its whole cell; a miss checks every cell its ball
            # touches (in blocks: 2^n cells per query)
            found = self._centre_point[self._flat(home)].astype(np.int64)
            misses = np.flatnonzero(found < 0)
            if len(misses) == len(q):
                self._cover_away(q, rel, r, found)
            elif len(misses):
                sub = np.full(len(misses), -1, dtype=np.int64)
                self._cover_away(q[misses], rel[misses], r, sub)
                found[misses] = sub
            return found
        elif self._dense is not None and radius > self.cell / 2:
            found = self._centre_point[self._flat(home)].astype(np.int64)
            todo = np.flatnonzero(found < 0)
            if len(todo) == 0:
                return found
        if todo is None:
            todo = np.arange(len(q))
        self._scan(q, home[todo], todo, r, found)
        todo = todo[found[todo] < 0]
        if len(todo) == 0:
            return found
        lo = np.floor(rel[todo] - r / self.cell).astype(np.int64)
        hi = np.floor(rel[todo] + r / self.cell).astype(np.int64)
        home_t = home[todo]
        # The other cells the query ball touches: per axis the home cell and, where the
        # ball reaches over a face, the neighbour beyond it (both, for a query at a cell
        # centre when r exceeds cell/2 by the tolerance).
        reach_down, reach_up = lo < home_t, hi > home_t
        both = (reach_down & reach_up).any(axis=1)
        # regular queries: one neighbour per axis, on the side the ball crosses (tried in
        # ``itertools.product`` order of (home, side) per axis, axis 0 first)
        side = np.where(reach_down, lo, hi)
        crosses = side != home_t
        regular = np.flatnonzero(~both & crosses.any(axis=1))
        if len(regular):
            choices = np.stack([np.zeros_like(side[regular]), (side - home_t)[regular]], axis=2)
            allowed = np.stack([np.ones_like(crosses[regular]), crosses[regular]], axis=2)
            self._scan_in_order(q, todo[regular], home_t[regular], choices, allowed, r, found)
        # queries at a cell centre reach both neighbours of an axis (r = cell/2 + tolerance):
        # offsets -1, 0, 1 per axis in ``itertools.product`` order
        centred = np.flatnonzero(both)
        if len(centred):
            choices = np.broadcast_to(np.array([-1, 0, 1], dtype=np.int64), (len(centred), self.n, 3))
            allowed = np.stack([reach_down[centred], np.ones((len(centred), self.n), dtype=bool), reach_up[centred]],
                               axis=2)
            self._scan_in_order(q, todo[centred], home_t[centred], choices, allowed, r, found)
        return found

    def _scan_in_order(self, q, rows, home, choices, allowed, r, found) -> None:
        """The cells around queries ``rows``, each query's tried in order until one holds an
        alive point within ``r`` (the first such point of that cell's chain is its
        witness), as one ``_scan`` per cell would find them. Cell k of a query is home +
        choices[:, a, digit_a(k)] on each axis a, the digits of k in base ``choices.shape[2]``
        with axis 0 first (``itertools.product`` order), where every digit is ``allowed``;
        the home cell itself (every offset 0) is skipped (it was scanned). A few queries
        take blocks of cells at once (one array pass per cell is 19,683 passes for 3^9
        cells in 9-D); many take one cell index at a time, each pass spanning them all."""
        n, base = self.n, choices.shape[2]
        total = base**n
        radix = base ** np.arange(n - 1, -1, -1, dtype=np.int64)
        self._sync_chains()
        if len(rows) > ORDERED_QUERIES:
            self._scan_cell_by_cell(q, rows, home, choices, allowed, r, found, radix)
            return
        axes = np.arange(n)[None, None, :]
        left, k0 = np.arange(len(rows)), 0
        while k0 < total:
            left = left[found[rows[left]] < 0]
            if len(left) == 0:
                return
            k1 = min(total, k0 + max(1, ORDERED_CELLS // len(left)))
            digits = ((np.arange(k0, k1, dtype=np.int64)[:, None] // radix) % base)[None]  # (1, B, n)
            k0 = k1
            at_rows = left[:, None, None]
            offsets = choices[at_rows, axes, digits]  # (L, B, n), gathered at once (no (L, n, base) copy per block)
            ok = allowed[at_rows, axes, digits].all(axis=2) & (offsets != 0).any(axis=2)
            at, cell = np.nonzero(ok)  # query by query, each one's cells in order
            if len(at) == 0:
                continue
            sel = rows[left[at]]
            pair_found = np.full(len(at), -1, dtype=np.int64)
            cells = home[left[at]] + offsets[at, cell]
            self._walk(q[sel], np.arange(len(at)), self._heads[self._bucket(cells)], r, pair_found, self.next)
            hit = np.flatnonzero(pair_found >= 0)
            if len(hit):
                hit_at, first = np.unique(at[hit], return_index=True)  # each query's first cell with a witness
                found[rows[left[hit_at]]] = pair_found[hit[first]]

    def _scan_cell_by_cell(self, q, rows, home, choices, allowed, r, found, radix) -> None:
        """``_scan_in_order`` one cell index at a time: for many queries, where a pass is
        large anyway and blocks would only add gathers. Only the axes whose digit some
        query does not allow are tested."""
        n, base = self.n, choices.shape[2]
        every = allowed.all(axis=0)  # (n, base): digits every query allows
        still = (choices == 0).all(axis=0)  # (n, base): digits that move no query
        axes, left = np.arange(n), np.arange(len(rows))
        for k in range(base**n):
            digits = (k // radix) % base
            if still[axes, digits].all():
                continue  # the home cell
            left = left[found[rows[left]] < 0]  # a pass spans the queries still without a witness
            if len(left) == 0:
                return
            sel = left
            for axis in np.flatnonzero(~every[axes, digits]):
                sel = sel[allowed[sel, axis, digits[axis]]]
            if len(sel):
                self._scan(q, home[sel] + choices[sel[:, None], axes, digits], rows[sel], r, found)

    def cover_away(self, queries: np.ndarray, radius: float) -> np.ndarray:
        """``cover`` of queries known to have no centre point at their home cell (a
        leveled index's grid says so): the search of the cells around, without asking
        the home cell again. Any query, where the index has no dense grid or ``radius``
        is not cell/2."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        if self._dense is None or abs(radius - self.cell / 2) > 1e-12:
            return self.cover(q, radius)
        found = np.full(len(q), -1, dtype=np.int64)
        if self.count and len(q):
            rel = q - self.origin
            rel *= 1.0 / self.cell
            self._cover_away(q, rel, radius + TOLERANCE, found)
        return found

    def _cover_away(self, q, rel, r, found) -> None:
        """``_cover_cells`` in blocks of MISS_BLOCK queries (their temporaries: 3^n cells
        each), each writing its slice of ``found``."""
        for at in range(0, len(q), MISS_BLOCK):
            block = slice(at, at + MISS_BLOCK)
            self._cover_cells(q[block], rel[block], r, found[block])

    def home_cover(self, queries: np.ndarray) -> np.ndarray | None:
        """(B, n) -> (B,) int64: the centre point naming each query's home cell (it covers
        the query at radius cell/2), or -1; None without a dense grid. The first, cheap
        half of ``cover`` at radius cell/2: a -1 may still be covered from elsewhere."""
        if self._dense is None:
            return None
        rel = np.atleast_2d(np.asarray(queries, dtype=float)) - self.origin
        rel *= 1.0 / self.cell
        return self._centre_point[self._flat(np.floor(rel).astype(np.int64))].astype(np.int64)

    def covered_by_since(self, queries: np.ndarray, radius: float, first: int) -> np.ndarray:
        """(B, n) -> (B,) bool: is an alive point with id >= ``first`` within ``radius`` of
        each query, by the rule ``cover`` applies (true distance with the tolerance, or,
        on the dense grid, a centre point of the query's home cell)? By brute force over
        those points: for re-deciding a few states against the points inserted since."""
        q = np.atleast_2d(np.asarray(queries, dtype=float))
        ids = np.flatnonzero(self.alive[first : self.count]) + first
        if len(ids) == 0 or len(q) == 0:
            return np.zeros(len(q), dtype=bool)
        r = radius + TOLERANCE
        near = np.ones((len(q), len(ids)), dtype=bool)
        for axis in range(self.n):  # the same per-axis comparison as ``_walk``
            near &= np.abs(self.points[ids, axis][None, :] - q[:, axis, None]) <= r
        if self._dense is not None and (abs(radius - self.cell / 2) <= 1e-12 or radius > self.cell / 2):
            rel = q - self.origin
            rel *= 1.0 / self.cell
            home = self._flat(np.floor(rel).astype(np.int64))
            centred = self._centre_cell[ids]
            near |= (centred[None, :] == home[:, None]) & (centred >= 0)[None, :]
        return near.any(axis=1)

    def _cover_cells(self, q, rel, r, found) -> None:
        """Queries at radius = cell/2 whose home cell has no centre point: check by its true
        distance the centre point of each cell the ball touches whose centre can be near,
        and, if the index has off-centre points, walk the chains of every cell it touches
        (~20 array operations). A ball touches at most two cells per axis, three for a
        query within the tolerance of a cell centre (those are enumerated apart); the
        cells whose centre can be near are mostly one per axis, so a query costs O(n), not
        2^n, unless off-centre points make the chains worth walking. Cells beyond the grid
        are clipped into its margin, whose chains hold every point beyond the bounds, so
        nothing is missed."""
        reach = r / self.cell
        lo = np.floor(rel - reach).astype(np.int64)
        hi = np.floor(rel + reach).astype(np.int64)
        centred = (hi - lo >= 2).any(axis=1)
        # a centre point within r of a query lies in a cell whose centre is within reach on
        # every axis (up to CENTRE_SLACK: a centre point sits within 1e-9 cells of its cell's
        # centre): per axis a contiguous range within lo..hi, mostly the home cell alone,
        # so not the 2^n cells the ball touches. The same cells in the same order, less those
        # that cannot hold a witness: the same witnesses.
        centres_at = rel - 0.5  # cell k's centre lies within reach where |k - centres_at| <= reach
        clo = np.maximum(lo, np.ceil(centres_at - reach - CENTRE_SLACK).astype(np.int64))
        chi = np.maximum(clo, np.minimum(hi, np.floor(centres_at + reach + CENTRE_SLACK).astype(np.int64)))
        if not centred.any():  # most calls: no query within the tolerance of a cell centre
            self._check_cells(q, lo, hi, clo, chi, np.arange(len(q)), 2, r, found)
            return
        for rows, span in (((~centred).nonzero()[0], 2), (centred.nonzero()[0], 3)):
            if len(rows):
                self._check_cells(q, lo[rows], hi[rows], clo[rows], chi[rows], rows, span, r, found)

    def _check_cells(self, q, lo, hi, clo, chi, rows, span, r, found) -> None:
        """Cells lo + o (o < span, lo + o <= hi per axis) of queries ``rows``, each row's
        cells in ``itertools.product`` order of o (a later witness overwrites an earlier):
        their centre points, of which only cells clo..chi can name a witness, then, if the
        index has off-centre points, the chains of every cell for queries still without
        a witness."""
        if self._alive > self._off_alive:  # some centre point is alive
            row_of, cells = box_cells(clo, chi, span)
            row = rows[row_of]
            centre = self._centre_point[self._flat(cells)]
            named = (centre >= 0).nonzero()[0]
            if len(named):
                points, queries = centre[named], row[named]
                near = self._within(points, q, queries, r)
                found[queries[near]] = points[near]
        if self._off_alive == 0:
            return
        left = (found[rows] < 0).nonzero()[0]
        if len(left) == 0:
            return
        row_of, flat = self._touched(lo[left], hi[left], span)
        row = rows[left][row_of]
        chained = (self._others[flat] > 0).nonzero()[0]
        if len(chained):
            self._walk(q, row[chained], self._off_head[flat[chained]], r, found, self._off_next)

    def _touched(self, lo: np.ndarray, hi: np.ndarray, span: int) -> tuple[np.ndarray, np.ndarray]:
        """The cells lo..hi of each row (hi - lo < span per axis) as flat dense indexes,
        clipped into the margin as ``_flat`` clips them, each row's in ``box_cells``' order:
        (m,) the row of each, (m,) the cells. Rows inside the grid are grouped by their
        extent hi - lo (a few kinds): each is its first cell's index plus the flat steps of
        the offsets its extent allows, one (rows, cells) sum instead of (rows, span^n, n)
        arrays. Each row's cells stay together and in order, so a chain walk over them
        names the same witnesses."""
        extent = hi - lo
        inside = (lo >= -1).all(axis=1) & (hi + 1 <= self._last_cell).all(axis=1)  # nothing clipped
        rows, flats = [], []
        offsets = box_offsets(span, self.n)
        kinds = extent @ (span ** np.arange(self.n - 1, -1, -1, dtype=np.int64))
        inner = inside.nonzero()[0]
        for kind in np.unique(kinds[inner]):
            group = inner[kinds[inner] == kind]
            steps = offsets[(offsets <= extent[group[0]]).all(axis=1)] @ self._strides
            rows.append(np.repeat(group, len(steps)))
            flats.append((self._flat(lo[group])[:, None] + steps[None, :]).ravel())
        rest = (~inside).nonzero()[0]
        if len(rest):
            row_of, cells = box_cells(lo[rest], hi[rest], span)
            rows.append(rest[row_of])
            flats.append(self._flat(cells))
        if len(rows) == 1:
            return rows[0], flats[0]
        if not rows:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        return np.concatenate(rows), np.concatenate(flats)

    def _within(self, ids, q, sel, r) -> np.ndarray:
        """(k,) bool: point ``ids[i]`` lies within l-inf ``r`` of query ``q[sel[i]]``. A few
        as (k, n) arrays (fewer array operations); many per axis (reducing over n is slow)."""
        if len(ids) <= SMALL_ROWS:
            return (np.abs(self.points[ids] - q[sel]) <= r).all(axis=1)
        near = np.abs(self.points[ids, 0] - q[sel, 0]) <= r
        for axis in range(1, self.n):
            near &= np.abs(self.points[ids, axis] - q[sel, axis]) <= r
        return near

    def _scan(self, q, cells, sel, r, found) -> None:
        """Walk the hash chains of ``cells`` (row i: the cell for query ``sel[i]``), setting ``found``."""
        self._sync_chains()
        self._walk(q, sel, self._heads[self._bucket(cells)], r, found, self.next)

    def _walk(self, q, sel, cur, r, found, links) -> None:
        """Walk chains from points ``cur`` (row i for query ``sel[i]``) along ``links``,
        setting ``found`` (the point's id) where an alive point lies within ``r``."""
        live = cur >= 0
        sel, cur = sel[live], cur[live]
        while len(sel):
            near = self.alive[cur] & self._within(cur, q, sel, r)
            if near.any():
                found[sel[near]] = cur[near]
            cur = links[cur]
            keep = (cur >= 0) & (found[sel] < 0)  # a query found through another cell stops walking too
            sel, cur = sel[keep], cur[keep]

    # -- persistence (plain arrays, no pickle) -------------------------------------------
    def state(self) -> dict:
        return self._snapshot()

    @classmethod
    def from_state(cls, state: dict) -> "PointIndex":
        pts = state["points"]
        idx = cls._empty_for(state)
        if len(pts):
            idx.insert(pts)
            idx.kill(np.nonzero(~state["alive"])[0])
        return idx
