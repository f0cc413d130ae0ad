"""Membership in a union of boxes at grid points: what a figure rasterizes."""

from __future__ import annotations

import itertools

import numpy as np

from coordinator.spatial import TOLERANCE, PointIndex


def _member(centres: np.ndarray, half_widths, n: int, lower=None, upper=None, distinct: bool = False) -> callable:
    """Membership in the union of boxes centre +- half-width (``half_widths``: one per
    box, or one for all), (G, n) -> (G,) bool: one index per half-width, anchored at
    ``lower`` (default: the lowest centre of that size). With ``upper`` too the index
    uses its dense fast path (Sigma as bounds). ``distinct``: drop repeated boxes."""
    centres = np.asarray(centres, dtype=float).reshape(-1, n)
    widths = np.broadcast_to(np.asarray(half_widths, dtype=float), (len(centres),))
    members = []
    for width in np.unique(widths[widths > 0]):  # an empty size would need a zero cell
        group = centres if (widths == width).all() else centres[widths == width]
        members.append(_Membership(group, float(width), group.min(axis=0) if lower is None else lower, upper,
                                   distinct))
    if len(members) == 1:
        return members[0]
    return _Union(members, n)


class _Union:
    """Membership in boxes of several sizes (or none): one ``_Membership`` per size."""

    def __init__(self, members: list, n: int):
        self.members, self.n = members, n

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        return np.logical_or.reduce([m(pts) for m in self.members] + [np.zeros(len(pts), dtype=bool)])

    def grid(self, grids: dict[int, np.ndarray], fixed: dict[int, float]) -> np.ndarray:
        """As ``_Membership.grid``, over every size."""
        centres = np.concatenate([np.zeros((0, self.n))] + [m.centres for m in self.members])
        radii = np.concatenate([np.zeros(0)] + [np.full(len(m.centres), m.half_width) for m in self.members])
        return _grid(centres, radii, grids, fixed)


def _set_member(scenario, safe_set) -> callable:
    """Membership in a safe set, indexed over Sigma."""
    return _member(safe_set.centres, safe_set.half_widths, scenario.n, scenario.lower, scenario.upper)


class _Membership:
    """Membership in a union of equal boxes, indexing only the boxes a query can meet.

    A figure's query holds some coordinates at one value (a slice holds all but two):
    only boxes within a half-width of those values can contain its points, often a few percent of
    a large set. The index over them is built on first use and kept per held values;
    a full index (one over every box, ~130 bytes per box) is built only for a query that
    holds nothing. Only the index of the last held values is kept: a figure asks each cut
    once, and an index over Sigma's dense grid is large. The answers are those of one
    index over all boxes."""

    def __init__(self, centres: np.ndarray, half_width: float, lower, upper=None, distinct: bool = False):
        self.centres, self.half_width, self.distinct = centres, float(half_width), distinct
        self.lower = np.asarray(lower, float)
        self.bounds = None if upper is None else (self.lower, np.asarray(upper, float))
        self._held: tuple | None = None
        self._index_of_held: PointIndex | None = None

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        pts = np.atleast_2d(np.asarray(pts, dtype=float))
        if not len(pts):
            return np.zeros(0, dtype=bool)
        first = pts[0]
        held = tuple((a, float(first[a])) for a in range(pts.shape[1])
                     if np.isfinite(first[a]) and (pts[:, a] == first[a]).all())
        if held != self._held:
            self._held, self._index_of_held = None, None  # the old index goes before the new one is built
            self._held, self._index_of_held = held, self._index(held)
        index = self._index_of_held
        return index.any_within(pts, self.half_width) if index is not None else np.zeros(len(pts), dtype=bool)

    def grid(self, grids: dict[int, np.ndarray], fixed: dict[int, float]) -> np.ndarray:
        """Membership at every combination of ``grids`` (axis -> monotone values), the
        other coordinates at ``fixed`` (axis -> value; one in neither is in no box), as
        a (len(grids[a]) for a in grids) bool array: what ``self(_points(...))``
        answers, reshaped, without a query per point."""
        return _grid(self.centres, np.full(len(self.centres), self.half_width), grids, fixed)

    def _index(self, held: tuple) -> PointIndex | None:
        near = np.ones(len(self.centres), dtype=bool)
        for axis, value in held:
            near &= np.abs(self.centres[:, axis] - value) <= self.half_width + TOLERANCE
        group = self.centres if near.all() else self.centres[near]
        if self.distinct:
            group = _distinct_rows(group)
        if not len(group):
            return None
        index = PointIndex(group.shape[1], 2 * self.half_width, self.lower, capacity=len(group), bounds=self.bounds)
        index.insert(group)
        return index


def _grid(centres: np.ndarray, half_widths: np.ndarray, grids: dict[int, np.ndarray],
          fixed: dict[int, float]) -> np.ndarray:
    """Membership in the union of boxes ``centres`` +- ``half_widths`` at every point of a
    grid (see ``_Membership.grid``), painted box by box: on each grid axis a box covers
    an interval of the samples, so the grid is the union of a (d-dimensional) block per
    box, summed as +-1 at the blocks' corners and integrated along each axis. A sample
    is in a box as the point indexes decide it: ``|x - c| <= h + TOLERANCE``, per axis,
    in the same floating-point operations."""
    shape = tuple(len(values) for values in grids.values())
    n = centres.shape[1] if centres.ndim == 2 else 0
    if set(grids) | set(fixed) != set(range(n)) or 0 in shape:
        return np.zeros(shape, dtype=bool)  # an unset coordinate is in no box
    radii = np.asarray(half_widths, dtype=float) + TOLERANCE
    near = np.ones(len(centres), dtype=bool)
    for axis, value in fixed.items():  # a cut meets only the boxes near its held values
        near &= np.abs(centres[:, axis] - float(value)) <= radii
    centres, radii = centres[near], radii[near]
    keep = np.ones(len(centres), dtype=bool)
    bounds = []
    for axis, values in grids.items():
        lo, hi = _covered(np.asarray(values, dtype=float), centres[:, axis], radii)
        bounds.append((lo, hi))
        keep &= lo < hi
    if not keep.any():
        return np.zeros(shape, dtype=bool)
    padded = tuple(g + 1 for g in shape)
    flat, signs = [], []
    for corner in itertools.product((0, 1), repeat=len(shape)):
        index = tuple(bounds[k][side][keep] for k, side in enumerate(corner))
        flat.append(np.ravel_multi_index(index, padded))
        signs.append(np.full(int(keep.sum()), (-1.0) ** sum(corner)))
    counts = np.bincount(np.concatenate(flat), np.concatenate(signs), minlength=int(np.prod(padded)))
    counts = counts.reshape(padded)
    for k in range(len(shape)):
        np.cumsum(counts, axis=k, out=counts)
    return counts[tuple(slice(0, g) for g in shape)] > 0.5


def _covered(values: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per box, the samples ``values`` (monotone) within ``radii`` of its centre on this
    axis: [lo, hi) indexes into ``values``. ``|x - c|`` rounds monotonically in x, so
    they are an interval; its ends are found by bisection and settled by the very test
    (a bisection on ``c -+ r`` can land one sample off where that sum rounds)."""
    rising = len(values) < 2 or values[-1] >= values[0]
    ordered = values if rising else values[::-1]
    if np.any(np.diff(ordered) < 0):
        raise ValueError("a grid axis's values must be monotone")
    last = len(ordered) - 1

    def inside(i):
        return np.abs(ordered[np.clip(i, 0, last)] - centres) <= radii

    lo = np.searchsorted(ordered, centres - radii, side="left")
    hi = np.searchsorted(ordered, centres + radii, side="right")
    for _ in range(2):
        lo = np.where((lo > 0) & inside(lo - 1), lo - 1, lo)
        lo = np.where((lo < hi) & ~inside(lo), lo + 1, lo)
        hi = np.where((hi <= last) & inside(hi), hi + 1, hi)
        hi = np.where((hi > lo) & ~inside(hi - 1), hi - 1, hi)
    hi = np.maximum(hi, lo)
    if rising:
        return lo, hi
    return len(values) - hi, len(values) - lo


def _points(scenario, grids: dict[int, np.ndarray], fixed: dict[int, float]) -> np.ndarray:
    """All combinations of ``grids`` (axis -> values, 'ij' order) as rows of states; the
    other coordinates at ``fixed`` (axis -> value)."""
    axes = list(grids)
    mesh = np.meshgrid(*(grids[a] for a in axes), indexing="ij")
    pts = np.full((mesh[0].size, scenario.n), np.nan)  # a coordinate left unset is in no box
    for axis, value in fixed.items():
        pts[:, axis] = value
    for axis, values in zip(axes, mesh):
        pts[:, axis] = values.ravel()
    return pts


def _held(scenario, shown, fixed: dict[int, float] | None = None) -> dict[int, float]:
    """The coordinates a figure does not show -> the value they are held at (``fixed``,
    else mid-range)."""
    fixed = fixed or {}
    mid = (np.asarray(scenario.lower) + np.asarray(scenario.upper)) / 2
    return {a: float(fixed.get(a, mid[a])) for a in range(scenario.n) if a not in shown}


def _samples(lo: float, hi: float, count: int) -> np.ndarray:
    """Pixel centres across [lo, hi]: an image's pixels then sit where they were
    sampled, and no sample lands exactly on a box face of a grid-aligned set (where
    neighbouring boxes touch and a single column would stick out)."""
    return lo + (np.arange(count) + 0.5) * ((hi - lo) / count)


def _axis(scenario, name: str) -> int:
    return list(scenario.state_names).index(name)


def _distinct_rows(points: np.ndarray) -> np.ndarray:
    """The distinct rows of ``points`` (a campaign's starts repeat its vertices): sorted
    on one axis, then duplicates dropped where every coordinate equals the previous row's.
    ``np.unique(axis=0)`` takes 5 s on 3.6 M rows; this, a fraction of a second."""
    if len(points) < 2:
        return points
    points = points[np.lexsort(points.T[::-1])]
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = (points[1:] != points[:-1]).any(axis=1)
    return points[keep]
