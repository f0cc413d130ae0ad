"""d(sigma_i, PhiBar) for every vertex, exact, kept up to date as vertices and failures
are appended (prioritized sampling, paper Sec. 4.4).

A new failure f can lower a vertex's distance only where |v - f| < d(v). Vertices are
grouped into coarse buckets (sorted by bucket, with the box each bucket's vertices span
and the largest distance among them): a bucket whose box lies at least that far from f
is skipped whole; with a ``cap``, only the buckets whose grid cells come within it are
looked at. Vertices added since the last sort are checked directly. New vertices
get their distance from a KD-tree of the failures. Every distance is the same float64
max over axes of |v - f| whichever way it is reached, so the values do not depend on
the bookkeeping.
"""

from __future__ import annotations

import numpy as np

BUCKETS_PER_AXIS = {1: 4096, 2: 64, 3: 16, 4: 8, 5: 6}
BUCKET_NUMBER_BITS = 40  # bucket numbers over the leading axes only, past 4^20: a bucket's box still spans every axis
NEAR_SHARE = 0.25  # the cells a capped failure group reaches are listed if fewer than this share of the buckets
RESORT_SHARE = 0.1  # re-sort when the unsorted tail exceeds this share of the vertices
BRUTE_FORCE_PAIRS = 1 << 16  # vertex-failure pairs up to which new vertices skip the KD-tree
LOWER_GROUP = 64  # new failures whose reach is worked out together (a (F, buckets) gap)


def _linf(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """max over the last axis of |a - b| (broadcast), one axis at a time: a (..., n) max
    over n is several times slower. The same float64 values either way."""
    gap = np.abs(a[..., 0] - b[..., 0])
    for axis in range(1, a.shape[-1]):
        np.maximum(gap, np.abs(a[..., axis] - b[..., axis]), out=gap)
    return gap


class FailureDistances:
    def __init__(self, lower: np.ndarray, upper: np.ndarray, track_lowered: bool = False, cap: float = np.inf):
        """``track_lowered``: keep the ids whose distance fell (``take_lowered``).
        ``cap``: distances are min(d, cap), for a caller that only asks whether d is below
        a radius under ``cap`` (exact there): a new failure then reaches only the buckets
        within ``cap`` of it, not every vertex whose nearest failure is far."""
        self.track_lowered = track_lowered
        self.cap = float(cap)
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        n = len(self.lower)
        self.per_axis = BUCKETS_PER_AXIS.get(n, 4)
        # bucketed axes: no cost exponential in n (the buckets are the vertices' own cells, at most one per vertex)
        self.bucket_axes = min(n, int(BUCKET_NUMBER_BITS // np.log2(self.per_axis)))
        self._side = (self.upper - self.lower)[: self.bucket_axes] / self.per_axis
        self._numbers = np.empty(0, dtype=np.int64)  # the used buckets' numbers, ascending
        self._buffer = np.empty(0)  # distances of vertex ids, with room to grow
        self.seen_vertices = 0
        self.lowered: list[np.ndarray] = []  # ids whose distance fell, until taken (``take_lowered``)
        self.seen_failures = 0
        self._sorted = 0  # vertices [0, _sorted) are in the bucket structure
        self._order = np.empty(0, dtype=np.int64)
        self._starts = np.zeros(1, dtype=np.int64)
        self._box_lo = self._box_hi = np.empty((0, n))
        self._bucket_max = np.empty(0)
        self._tree = None  # a KD-tree of failures [0, _tree_count), kept while few failures follow it
        self._tree_count = 0

    def __getstate__(self) -> dict:
        # a copy (coordinator/driver/speculation.py) builds its own tree when it needs one
        return {**self.__dict__, "_tree": None, "_tree_count": 0}

    def state(self) -> dict[str, np.ndarray]:
        """The capped distances as a checkpoint keeps them: those below the cap (a bit per
        vertex says which) and the counts they cover. Recomputed, they are a KD-tree search
        from every vertex: most of resuming a 9-D campaign of 10 M boxes (docs/benchmarks.md)."""
        if not np.isfinite(self.cap):
            raise ValueError("only capped distances are kept in a checkpoint")
        near = self.dist < self.cap
        return {"cap": np.array(self.cap), "seen": np.array([self.seen_vertices, self.seen_failures], dtype=np.int64),
                "near": np.packbits(near), "values": self.dist[near]}

    @classmethod
    def from_state(cls, lower: np.ndarray, upper: np.ndarray, state: dict[str, np.ndarray],
                   track_lowered: bool = False) -> "FailureDistances":
        """Distances as ``state`` kept them: the same values as computed afresh from the
        same vertices and failures (every id counts as lowered, as from infinity). Raises
        ValueError for arrays that do not fit together."""
        cap = float(state["cap"])
        vertex_count, failure_count = (int(x) for x in np.asarray(state["seen"]).reshape(2))
        bits, values = np.asarray(state["near"], dtype=np.uint8), np.asarray(state["values"], dtype=float)
        fits = np.isfinite(cap) and failure_count >= 1 and 0 <= vertex_count <= 8 * len(bits)
        near = np.unpackbits(bits, count=vertex_count).astype(bool) if fits else None
        if not fits or values.shape != (int(np.count_nonzero(near)),) or not (values < cap).all():
            raise ValueError(f"the kept distances do not fit together ({vertex_count} vertices, {len(values)} "
                             f"values below the cap {cap})")
        out = cls(lower, upper, track_lowered=track_lowered, cap=cap)
        out._buffer = np.full(vertex_count, cap)
        out._buffer[near] = values
        out.seen_vertices, out.seen_failures = vertex_count, failure_count
        if track_lowered:
            out.lowered.append(np.arange(vertex_count))
        return out

    def update(self, points: np.ndarray, vertex_count: int, failures: np.ndarray, failure_count: int) -> np.ndarray:
        """The distances of vertices [0, vertex_count) to failures [0, failure_count)."""
        if failure_count == 0:
            return np.full(vertex_count, np.inf)
        if self.seen_failures == 0:  # nothing known yet: every vertex is new
            self.seen_vertices = self._sorted = 0
            if self.track_lowered:  # every distance fell from infinity
                self.lowered.append(np.arange(vertex_count))
        if failure_count > self.seen_failures and self.seen_vertices:
            fresh = failures[self.seen_failures : failure_count]
            for at in range(0, len(fresh), LOWER_GROUP):
                self._lower_by(points, fresh[at : at + LOWER_GROUP])
        if vertex_count > self.seen_vertices:
            d_new = np.minimum(self._nearest(points[self.seen_vertices : vertex_count], failures[:failure_count]),
                               self.cap)
            if vertex_count > len(self._buffer):  # doubling: a copy per append cost O(vertices)
                grown = np.empty(max(vertex_count, 2 * len(self._buffer)))
                grown[: self.seen_vertices] = self.dist
                self._buffer = grown
            self._buffer[self.seen_vertices : vertex_count] = d_new
        self.seen_vertices, self.seen_failures = vertex_count, failure_count
        if vertex_count - self._sorted > max(RESORT_SHARE * vertex_count, 4096):
            self._sort(points)
        return self.dist

    @property
    def dist(self) -> np.ndarray:
        """The known distances, vertex ids [0, seen_vertices): a view of the buffer made
        when asked (an attribute holding the view would part from the buffer in a copy,
        ``copy.deepcopy`` copying views apart, and lose what ``_lower`` writes)."""
        return self._buffer[: self.seen_vertices]

    def _nearest(self, vertices: np.ndarray, failures: np.ndarray) -> np.ndarray:
        """d(v, failures) for each vertex, or anything above the cap where d exceeds it:
        brute force for few pairs (between two draws a campaign adds a few vertices, too
        few to pay for a KD-tree of every failure), else a KD-tree of the failures, kept
        from call to call (failures only grow: those added since it was built are brute
        force while that is cheap; rebuilt per call, it was most of a 9-D closing round),
        searching no farther than the cap (in 9-D an unbounded search from each of 10 M
        vertices visits most of the tree). Both are the float64 max over axes of |v - f|
        and its min over f: the same values up to the cap."""
        if len(vertices) * len(failures) <= BRUTE_FORCE_PAIRS:
            return _linf(vertices[:, None, :], failures[None, :, :]).min(axis=1)
        from scipy.spatial import cKDTree  # here: scipy.spatial is 0.4 s of every CLI start

        if self._tree is None or not 0 <= len(failures) - self._tree_count <= BRUTE_FORCE_PAIRS // len(vertices):
            self._tree, self._tree_count = cKDTree(failures), len(failures)
        bound = np.nextafter(self.cap, np.inf) if np.isfinite(self.cap) else np.inf  # (the bound is strict)
        d = self._tree.query(vertices, p=np.inf, distance_upper_bound=bound)[0]
        rest = failures[self._tree_count :]
        if len(rest):
            np.minimum(d, _linf(vertices[:, None, :], rest[None, :, :]).min(axis=1), out=d)
        return d

    def _lower_by(self, points: np.ndarray, fs: np.ndarray) -> None:
        """Lower the known distances by failures ``fs`` (F, n), skipping buckets none of
        them can reach: at once, since a prune adds its holes together (a distance is the
        min over failures, and a bucket's largest distance its max: the same values in
        any order)."""
        if self._sorted:
            buckets = self._near_buckets(fs)  # None: every bucket (no copies of the boxes)
            box_lo, box_hi, most = ((self._box_lo, self._box_hi, self._bucket_max) if buckets is None else
                                    (self._box_lo[buckets], self._box_hi[buckets], self._bucket_max[buckets]))
            # per axis: a (F, buckets, n) max over n is several times slower
            gap = np.maximum(box_lo[None, :, 0] - fs[:, None, 0], fs[:, None, 0] - box_hi[None, :, 0])
            for axis in range(1, fs.shape[1]):
                np.maximum(gap, box_lo[None, :, axis] - fs[:, None, axis], out=gap)
                np.maximum(gap, fs[:, None, axis] - box_hi[None, :, axis], out=gap)
            np.maximum(gap, 0.0, out=gap)
            hit = (gap < most).any(axis=0)
            reach = np.flatnonzero(hit) if buckets is None else buckets[hit]
            if len(reach):
                lo, hi = self._starts[reach], self._starts[reach + 1]
                counts = hi - lo
                pos = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(int(counts.sum()))
                ids = self._order[pos]
                self._lower(points, ids, fs)
                new_max = np.maximum.reduceat(self.dist[ids], np.cumsum(counts) - counts)
                self._bucket_max[reach] = new_max
        if self.seen_vertices > self._sorted:
            self._lower(points, np.arange(self._sorted, self.seen_vertices), fs)

    def _near_buckets(self, fs: np.ndarray) -> np.ndarray | None:
        """The buckets failures ``fs`` may lower a distance in: all of them (None), or with
        a ``cap``, those whose box comes within it of the failures' bounding box (a bucket
        farther off is more than ``cap`` from each, and no capped distance exceeds it: the
        exact test would skip it too, after a (F, buckets) gap)."""
        if not np.isfinite(self.cap):
            return None
        lo, hi = fs.min(axis=0) - self.cap, fs.max(axis=0) + self.cap
        listed = self._listed_cells(lo, hi)
        box_lo, box_hi = (self._box_lo, self._box_hi) if listed is None else (self._box_lo[listed], self._box_hi[listed])
        near = (box_hi[:, 0] >= lo[0]) & (box_lo[:, 0] <= hi[0])
        for axis in range(1, fs.shape[1]):
            near &= (box_hi[:, axis] >= lo[axis]) & (box_lo[:, axis] <= hi[axis])
        return np.flatnonzero(near) if listed is None else listed[near]

    def _listed_cells(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
        """The used buckets (ascending) whose grid cells meet the box [lo, hi] on every
        bucketed axis, or None where listing them would cost more than testing every
        bucket. Exact: a vertex's cell is a non-decreasing function of its coordinate, so
        a bucket whose box meets [lo, hi] has its cell between the cells of lo and hi."""
        m, last = self.bucket_axes, self.per_axis - 1
        first_cell = np.clip(np.floor((lo[:m] - self.lower[:m]) / self._side), 0, last).astype(np.int64)
        last_cell = np.clip(np.floor((hi[:m] - self.lower[:m]) / self._side), 0, last).astype(np.int64)
        widths = last_cell - first_cell + 1
        if float(np.prod(widths.astype(float))) > NEAR_SHARE * len(self._numbers):
            return None
        numbers = np.zeros(1, dtype=np.int64)
        for axis in range(m):  # ravel_multi_index's order: ascending, as the used numbers are
            numbers = (numbers[:, None] * self.per_axis + np.arange(first_cell[axis], last_cell[axis] + 1)).ravel()
        at = np.searchsorted(self._numbers, numbers)
        used = at < len(self._numbers)
        used[used] = self._numbers[at[used]] == numbers[used]
        return at[used]

    def _lower(self, points, ids, fs) -> None:
        pts = points[ids]
        gap = _linf(pts, fs[0])
        for f in fs[1:]:
            np.minimum(gap, _linf(pts, f), out=gap)
        before = self.dist[ids]
        fell = gap < before
        self.dist[ids[fell]] = gap[fell]
        if self.track_lowered:
            self.lowered.append(ids[fell])

    def take_lowered(self) -> np.ndarray:
        """The ids whose distance fell since the last call (a sampler's dirty centres)."""
        out = np.concatenate(self.lowered) if self.lowered else np.empty(0, dtype=np.int64)
        self.lowered = []
        return out

    def _sort(self, points: np.ndarray) -> None:
        count = self.seen_vertices
        pts = points[:count]
        m = self.bucket_axes
        cells = np.clip(np.floor((pts[:, :m] - self.lower[:m]) / self._side).astype(np.int64), 0, self.per_axis - 1)
        bucket = np.ravel_multi_index(tuple(cells.T), (self.per_axis,) * m)
        self._order = np.argsort(bucket, kind="stable")
        # keep only the buckets that hold vertices: the boxes they actually span
        sorted_bucket = bucket[self._order]
        at = np.flatnonzero(np.concatenate([[True], sorted_bucket[1:] != sorted_bucket[:-1]]))
        self._numbers = sorted_bucket[at]
        sorted_pts = pts[self._order]
        self._box_lo = np.minimum.reduceat(sorted_pts, at, axis=0)
        self._box_hi = np.maximum.reduceat(sorted_pts, at, axis=0)
        self._bucket_max = np.maximum.reduceat(self.dist[self._order], at)
        self._starts = np.concatenate([at, [count]])
        self._sorted = count
