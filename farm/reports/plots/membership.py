"""Membership in a union of boxes at the points of a grid: what a figure rasterizes."""

from __future__ import annotations

import itertools

import numpy as np

from coordinator.spatial import TOLERANCE


class Boxes:
    """A union of boxes centre +- half-width, as a figure asks about it: at every point
    of a grid (``grid``)."""

    def __init__(self, centres: np.ndarray, half_widths, n: int):
        """``half_widths``: one per box and axis (M, n), one per box (M,), or one for all;
        an empty box (a half-width 0) is left out."""
        centres = np.asarray(centres, dtype=float).reshape(-1, n)
        widths = np.asarray(half_widths, dtype=float)
        if widths.ndim == 1:  # one per box: the same on every axis
            widths = widths[:, None]
        widths = np.broadcast_to(widths, (len(centres), n))
        keep = (widths > 0).all(axis=1)
        if keep.all():  # (no copy of a large set's boxes)
            self.centres, self.half_widths = centres, widths
        else:
            self.centres, self.half_widths = centres[keep], widths[keep]

    def near(self, fixed: dict[int, float]) -> "Boxes":
        """The boxes that hold the values ``fixed`` (axis -> value) on their axes, by
        ``grid``'s test: a cut meets only these."""
        centres, widths = self.centres, self.half_widths
        rows = np.arange(len(centres))
        for axis, value in fixed.items():
            # each axis asks only the boxes the ones before left: most of a large set is
            # cut away by the first
            rows = rows[np.abs(centres[rows, axis] - float(value)) <= widths[rows, axis] + TOLERANCE]
        return Boxes(centres[rows], widths[rows], centres.shape[1])

    def grid(self, grids: dict[int, np.ndarray], fixed: dict[int, float]) -> np.ndarray:
        """Membership at every combination of ``grids`` (axis -> monotone values), the
        other coordinates at ``fixed`` (axis -> value; one in neither is in no box), as
        a (len(grids[a]) for a in grids) bool array in ``grids``' axis order.

        Painted box by box: on each grid axis a box covers an interval of the samples, so
        the grid is the union of a (d-dimensional) block per box, summed as +-1 at the
        blocks' corners and integrated along each axis. A sample is in a box as
        coordinator/spatial.py's point indexes decide it: ``|x - c| <= h + TOLERANCE`` per
        axis, in the same floating-point operations (closed boxes)."""
        shape = tuple(len(values) for values in grids.values())
        if set(grids) | set(fixed) != set(range(self.centres.shape[1])) or 0 in shape:
            return np.zeros(shape, dtype=bool)  # an unset coordinate is in no box
        near = self.near(fixed)
        centres, radii = near.centres, near.half_widths + TOLERANCE
        keep = np.ones(len(centres), dtype=bool)
        bounds = []
        for axis, values in grids.items():
            lo, hi = _covered(np.asarray(values, dtype=float), centres[:, axis], radii[:, axis])
            bounds.append((lo, hi))
            keep &= lo < hi
        if not keep.any():
            return np.zeros(shape, dtype=bool)
        padded = tuple(g + 1 for g in shape)
        size = int(np.prod(padded))
        counts = np.zeros(size, dtype=np.int64)
        for corner in itertools.product((0, 1), repeat=len(shape)):  # one corner at a time: 2^d of them
            index = tuple(bounds[k][side][keep] for k, side in enumerate(corner))
            at = np.bincount(np.ravel_multi_index(index, padded), minlength=size)
            if sum(corner) % 2:
                counts -= at
            else:
                counts += at
        counts = counts.reshape(padded)
        for k in range(len(shape)):
            np.cumsum(counts, axis=k, out=counts)
        return counts[tuple(slice(0, g) for g in shape)] > 0


def _set_member(scenario, safe_set) -> Boxes:
    """The boxes of a safe set."""
    return Boxes(safe_set.centres, safe_set.axis_half_widths, scenario.n)


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
