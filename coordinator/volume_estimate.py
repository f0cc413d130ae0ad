"""Volumes of a box set where the exact computation is exponential in the dimension.

coordinator/volume.py's exact union cuts space into cells of the finest box and its
hull hands 2^n corners per hull box to qhull: right for the paper's 3-D and 5-D sets,
out of reach at 7-9 dimensions (a 7-D result phase outgrew 13 GB). Here, linear in the
boxes whatever n:

- a set of disjoint boxes (a partition's leaves) has the exact volume of their sum;
- any union: a Monte-Carlo estimate, uniform points over the set's bounding box, with a
  Wilson interval on the share inside (``VolumeEstimate``);
- the convex hull: the volume of the polytope cut out by the set's support function in
  ``DIRECTIONS`` directions (the axes, their diagonals and random ones; the support of a
  box is closed-form, no corners), itself estimated by Monte Carlo. That polytope holds
  the hull, so the figure is an upper estimate that tightens with the directions.

Every estimate draws from a seed the caller gives (the set's hash), so a result file is
the same each time it is written.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# uniform points per estimate: a share's 95 % interval is ~0.5 % wide at 1/2. Each point
# costs a lookup among the boxes (the union) or DIRECTIONS half-spaces (the hull), so 8x
# the points for an interval 0.2 % wide would cost most of a 9-D set's result phase
SAMPLES = 1 << 17
DIRECTIONS = 1024  # half-spaces of the outer polytope of the hull
BLOCK = 1 << 16  # points tested at once
SUPPORT_BLOCK = 1024  # boxes whose support is computed at once (docs/benchmarks.md)
DIRECTION_BLOCK = 128  # half-spaces tested at once: (BLOCK, 128) floats, 64 MB, whatever DIRECTIONS is
Z95 = 1.959963984540054


@dataclass(frozen=True)
class VolumeEstimate:
    value: float
    low: float  # a 95 % interval (equal to value when exact)
    high: float
    exact: bool
    method: str  # how it was computed, in words (summary.json says it)

    def to_json(self) -> dict:
        return {"value": self.value, "low": self.low, "high": self.high, "exact": self.exact, "method": self.method}


def clipped(lo: np.ndarray, hi: np.ndarray, bounds) -> tuple[np.ndarray, np.ndarray]:
    if bounds is None:
        return lo, hi
    return np.maximum(lo, bounds[0]), np.minimum(hi, bounds[1])


def disjoint_volume(lo: np.ndarray, hi: np.ndarray, bounds=None) -> VolumeEstimate:
    """Boxes that meet only on faces: the union's volume is their sum (exact)."""
    lo, hi = clipped(lo, hi, bounds)
    total = float(np.prod(np.maximum(hi - lo, 0.0), axis=1).sum())
    return VolumeEstimate(total, total, total, True, "the sum of the boxes' volumes (the boxes are disjoint)")


def wilson(inside: int, samples: int) -> tuple[float, float]:
    """A 95 % Wilson interval on a share ``inside / samples``."""
    if samples == 0:
        return 0.0, 1.0
    p = inside / samples
    z2 = Z95 * Z95
    centre = (p + z2 / (2 * samples)) / (1 + z2 / samples)
    half = Z95 * np.sqrt(p * (1 - p) / samples + z2 / (4 * samples * samples)) / (1 + z2 / samples)
    return max(0.0, centre - half), min(1.0, centre + half)


def _monte_carlo(contains, box_lo: np.ndarray, box_hi: np.ndarray, seed: int, samples: int) -> tuple[int, float]:
    """(points inside, the box's volume): ``samples`` uniform points in [box_lo, box_hi]."""
    rng = np.random.default_rng(seed)
    inside = 0
    for at in range(0, samples, BLOCK):
        points = rng.uniform(box_lo, box_hi, size=(min(BLOCK, samples - at), len(box_lo)))
        inside += int(np.count_nonzero(contains(points)))
    return inside, float(np.prod(box_hi - box_lo))


def union_volume_estimate(contains, lo: np.ndarray, hi: np.ndarray, bounds=None, seed: int = 0,
                          samples: int = SAMPLES) -> VolumeEstimate:
    """The union of boxes ``lo``/``hi`` (``contains(points)``: membership in it), by
    Monte Carlo over its bounding box."""
    lo, hi = clipped(lo, hi, bounds)
    if len(lo) == 0:
        return VolumeEstimate(0.0, 0.0, 0.0, True, "empty")
    box_lo, box_hi = lo.min(axis=0), hi.max(axis=0)
    inside, box = _monte_carlo(contains, box_lo, box_hi, seed, samples)
    low, high = wilson(inside, samples)
    return VolumeEstimate(box * inside / samples, box * low, box * high, False,
                          f"a Monte-Carlo estimate from {samples:,} uniform points in the set's bounding box "
                          f"(95 % Wilson interval)")


def hull_volume_estimate(lo: np.ndarray, hi: np.ndarray, bounds=None, seed: int = 0, samples: int = SAMPLES,
                         directions: int = DIRECTIONS) -> VolumeEstimate:
    """The convex hull of the union of boxes, from outside: the polytope of the set's
    support function in ``directions`` directions, its volume by Monte Carlo."""
    lo, hi = clipped(lo, hi, bounds)
    if len(lo) == 0:
        return VolumeEstimate(0.0, 0.0, 0.0, True, "empty")
    n = lo.shape[1]
    rng = np.random.default_rng(seed)
    axes = np.concatenate([np.eye(n), -np.eye(n)])
    random = rng.normal(size=(max(directions - len(axes), 0), n))
    u = np.concatenate([axes, random / np.linalg.norm(random, axis=1, keepdims=True)])
    # h(u) = max over boxes of u . c + |u| . h: no corners; one product of (c, h) rows with
    # (u, |u|) columns, in blocks whose (SUPPORT_BLOCK, directions) product stays in cache
    both = np.ascontiguousarray(np.concatenate([u, np.abs(u)], axis=1).T)
    support = np.full(len(u), -np.inf)
    for at in range(0, len(lo), SUPPORT_BLOCK):
        l, h = lo[at : at + SUPPORT_BLOCK], hi[at : at + SUPPORT_BLOCK]
        np.maximum(support, (np.concatenate([0.5 * (l + h), 0.5 * (h - l)], axis=1) @ both).max(axis=0), out=support)

    def inside(points: np.ndarray) -> np.ndarray:
        # a block of half-spaces at a time, on the points still inside: most points of the
        # bounding box outside the hull are cut off by the first random directions
        keep = np.ones(len(points), dtype=bool)
        for at in range(0, len(u), DIRECTION_BLOCK):
            alive = np.flatnonzero(keep)
            if not len(alive):
                break
            block = slice(at, at + DIRECTION_BLOCK)
            keep[alive] = (points[alive] @ u[block].T <= support[block] + 1e-12).all(axis=1)
        return keep

    box_lo, box_hi = lo.min(axis=0), hi.max(axis=0)
    count, box = _monte_carlo(inside, box_lo, box_hi, seed + 1, samples)
    low, high = wilson(count, samples)
    return VolumeEstimate(box * count / samples, box * low, box * high, False,
                          f"an outer estimate: the polytope of the set's support function in {len(u):,} directions, "
                          f"its volume from {samples:,} uniform points (95 % Wilson interval)")
