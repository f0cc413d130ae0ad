"""Volumes of a quantified set: the union of equal l-inf boxes centre +- h.

``union_volume`` is exact. Space is cut into cells of side 2h aligned with the boxes'
most common lattice; a cell equal to one box is full, every other cell is resolved by
coordinate compression over the few box pieces that reach into it (an equal box always
meets at most 2^n cells, and pieces in one cell share most of their coordinates).

``hull_volume`` is the volume of the convex hull of the union (the paper's
"cardinality"): conv(union) = conv(centres) + cube, so only the centres on their own
hull matter.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import ConvexHull, QhullError


def _origin(centres: np.ndarray, h: float) -> np.ndarray:
    """The alignment shared by most boxes (their lower corners modulo 2h)."""
    residue = np.round(np.mod(centres - h, 2 * h) / (2 * h) * 1e6).astype(np.int64)
    origin = np.empty(centres.shape[1])
    for axis in range(centres.shape[1]):
        values, counts = np.unique(residue[:, axis], return_counts=True)
        origin[axis] = values[np.argmax(counts)] / 1e6 * 2 * h
    return origin


def union_volume(centres: np.ndarray, h: float, origin=None, bounds=None) -> float:
    """Exact volume of the union of boxes centre +- h, clipped to ``bounds`` (lo, hi)
    when given: the safe set lives in Sigma, boxes may overhang it."""
    centres = np.asarray(centres, dtype=float)
    if len(centres) == 0:
        return 0.0
    n = centres.shape[1]
    side = 2 * h
    origin = _origin(centres, h) if origin is None else np.asarray(origin, dtype=float)
    lo, hi = centres - h, centres + h
    rel = (lo - origin) / side
    base = np.floor(rel + 1e-9).astype(np.int64)
    aligned = (np.abs(rel - np.round(rel)) < 1e-9).all(axis=1)
    if bounds is not None:
        blo, bhi = (np.asarray(b, dtype=float) for b in bounds)
        aligned &= ((lo >= blo - 1e-12) & (hi <= bhi + 1e-12)).all(axis=1)  # only unclipped boxes fill a cell
        lo, hi = np.maximum(lo, blo), np.minimum(hi, bhi)
        keep = (hi - lo > 1e-12).all(axis=1)
        lo, hi, base, aligned, rel = lo[keep], hi[keep], base[keep], aligned[keep], rel[keep]
    full_cells = {tuple(c) for c in np.round(rel[aligned]).astype(np.int64)}
    # every (box, cell) piece with the cell not full
    pieces: dict[tuple, list[int]] = {}
    for offset in itertools.product((0, 1), repeat=n):
        cells = base + np.array(offset)
        cell_lo = origin + cells * side
        inter = (np.minimum(hi, cell_lo + side) - np.maximum(lo, cell_lo) > 1e-12).all(axis=1)
        for box, cell in zip(np.nonzero(inter)[0], map(tuple, cells[inter])):
            if cell not in full_cells:
                pieces.setdefault(cell, []).append(box)
    total = len(full_cells) * side**n
    for cell, boxes in pieces.items():
        cell_lo = origin + np.array(cell) * side
        plo = np.maximum(lo[boxes], cell_lo)
        phi = np.minimum(hi[boxes], cell_lo + side)
        total += _compressed_union(plo, phi)
    return float(total)


def _compressed_union(lo: np.ndarray, hi: np.ndarray) -> float:
    """Exact union volume of a few boxes by coordinate compression."""
    n = lo.shape[1]
    coords = [np.unique(np.concatenate([lo[:, a], hi[:, a]])) for a in range(n)]
    covered = np.zeros([len(c) - 1 for c in coords], dtype=bool)
    for box_lo, box_hi in zip(lo, hi):
        sl = tuple(slice(np.searchsorted(c, l), np.searchsorted(c, u)) for c, l, u in zip(coords, box_lo, box_hi))
        covered[sl] = True
    widths = [np.diff(c) for c in coords]
    cell_volume = widths[0]
    for w in widths[1:]:
        cell_volume = np.multiply.outer(cell_volume, w)
    return float((cell_volume * covered).sum())


def hull_volume(centres: np.ndarray, h: float, bounds=None) -> float:
    """Convex-hull volume of the union of boxes (clipped to ``bounds`` when given). Only
    boxes centred on the hull of the centres, or clipped by the bounds, can contribute
    hull vertices, so only their corners are handed to qhull."""
    centres = np.asarray(centres, dtype=float)
    if len(centres) == 0:
        return 0.0
    n = centres.shape[1]
    try:
        on_hull = np.zeros(len(centres), dtype=bool)
        on_hull[ConvexHull(centres).vertices if len(centres) > n else slice(None)] = True
    except QhullError:  # flat set of centres: every centre may be on the hull
        on_hull = np.ones(len(centres), dtype=bool)
    corners = np.array(list(itertools.product((-h, h), repeat=n)))
    if bounds is not None:
        blo, bhi = (np.asarray(b, dtype=float) for b in bounds)
        on_hull |= ((centres - h < blo) | (centres + h > bhi)).any(axis=1)
        points = (centres[on_hull][:, None, :] + corners[None, :, :]).reshape(-1, n)
        points = np.unique(np.clip(points, blo, bhi), axis=0)
    else:
        points = (centres[on_hull][:, None, :] + corners[None, :, :]).reshape(-1, n)
    return float(ConvexHull(points).volume)


def raster_iou(a: tuple[np.ndarray, float], b: tuple[np.ndarray, float], lower, upper, points_per_axis: int = 60):
    """IoU of two unions of boxes, measured on a regular grid of cell midpoints over
    [lower, upper] (exact membership at each point)."""
    from coordinator.spatial import PointIndex

    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    axes = [lo + (hi - lo) * (np.arange(points_per_axis) + 0.5) / points_per_axis for lo, hi in zip(lower, upper)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lower))
    inside = []
    for centres, h in (a, b):
        index = PointIndex(len(lower), 2 * h, lower)
        index.insert(centres)
        inside.append(index.any_within(grid, h))
    union = (inside[0] | inside[1]).sum()
    return float((inside[0] & inside[1]).sum() / union) if union else 1.0
