"""Membership in a union of boxes at grid points: what a figure rasterizes."""

from __future__ import annotations

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
    return lambda pts: np.logical_or.reduce([m(pts) for m in members] + [np.zeros(len(pts), dtype=bool)])


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
