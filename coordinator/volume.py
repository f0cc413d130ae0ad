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
        # the smallest most common residue (residues lie in [0, 1e6])
        origin[axis] = np.argmax(np.bincount(residue[:, axis])) / 1e6 * 2 * h
    return origin


CHUNK = 1 << 18  # boxes per pass: temporaries stay ~50 MB however large the set


def union_volume(centres: np.ndarray, h: float, origin=None, bounds=None) -> float:
    """Exact volume of the union of boxes centre +- h, clipped to ``bounds`` (lo, hi)
    when given: the safe set lives in Sigma, boxes may overhang it."""
    centres = np.asarray(centres, dtype=float)
    if len(centres) == 0:
        return 0.0
    n = centres.shape[1]
    side = 2 * h
    origin = _origin(centres, h) if origin is None else np.asarray(origin, dtype=float)
    blo, bhi = (None, None) if bounds is None else (np.asarray(b, dtype=float) for b in bounds)
    keys = _CellKeys(np.floor((centres.min(axis=0) - h - origin) / side).astype(np.int64) - 1,
                     np.floor((centres.max(axis=0) - h - origin) / side).astype(np.int64) + 2)
    # an aligned, unclipped box is exactly its cell: the cell is full, and it reaches
    # into no other cell with positive volume; the other ("ragged") boxes are cut into
    # pieces, one per cell they reach into
    full_keys, ragged = [], []
    for first in range(0, len(centres), CHUNK):
        lo = centres[first : first + CHUNK] - h
        rel = (lo - origin) / side
        aligned = (np.abs(rel - np.round(rel)) < 1e-9).all(axis=1)
        if bounds is not None:  # only unclipped boxes fill a cell
            aligned &= ((lo >= blo - 1e-12) & (lo + side <= bhi + 1e-12)).all(axis=1)
        full_keys.append(keys(np.round(rel[aligned]).astype(np.int64)))
        ragged.append(first + np.flatnonzero(~aligned))
    full_keys = np.sort(np.concatenate(full_keys))
    full_keys = full_keys[np.r_[True, full_keys[1:] != full_keys[:-1]]] if len(full_keys) else full_keys
    ragged = np.concatenate(ragged)
    lo, hi = centres[ragged] - h, centres[ragged] + h
    base = np.floor((lo - origin) / side + 1e-9).astype(np.int64)
    if bounds is not None:
        lo, hi = np.maximum(lo, blo), np.minimum(hi, bhi)
        keep = (hi - lo > 1e-12).all(axis=1)
        lo, hi, base = lo[keep], hi[keep], base[keep]
    # every (box, cell) piece of a ragged box in a cell that is not full
    piece_box, piece_key, piece_cell = [], [], []
    for shift in itertools.product((0, 1), repeat=n):
        cells = base + np.array(shift)
        cell_lo = origin + cells * side
        inter = (np.minimum(hi, cell_lo + side) - np.maximum(lo, cell_lo) > 1e-12).all(axis=1)
        k = keys(cells[inter])
        pos = np.minimum(np.searchsorted(full_keys, k), max(len(full_keys) - 1, 0))
        open_ = ~(full_keys[pos] == k) if len(full_keys) else np.ones(len(k), dtype=bool)
        piece_box.append(np.flatnonzero(inter)[open_])
        piece_key.append(k[open_])
        piece_cell.append(cells[inter][open_])
    piece_box, piece_key, piece_cell = (np.concatenate(a) for a in (piece_box, piece_key, piece_cell))
    order = np.argsort(piece_key, kind="stable")
    piece_box, piece_key, piece_cell = piece_box[order], piece_key[order], piece_cell[order]
    starts = np.flatnonzero(np.r_[True, piece_key[1:] != piece_key[:-1]]) if len(piece_key) else np.empty(0, int)
    total = len(full_keys) * side**n
    for first, end in zip(starts, np.r_[starts[1:], len(piece_key)]):
        boxes = piece_box[first:end]
        cell_lo = origin + piece_cell[first] * side
        total += _compressed_union(np.maximum(lo[boxes], cell_lo), np.minimum(hi[boxes], cell_lo + side))
    return float(total)


class _CellKeys:
    """Integer cell coordinates (k, n) in [lowest, highest] -> one int64 key each."""

    def __init__(self, lowest: np.ndarray, highest: np.ndarray):
        self.lowest = lowest
        span = highest - lowest + 1
        if np.prod([float(s) for s in span]) >= 2.0**62:
            raise ValueError("union_volume: more cells than int64 keys can name")
        self.stride = np.cumprod(np.r_[1, span[:0:-1]])[::-1].astype(np.int64)

    def __call__(self, cells: np.ndarray) -> np.ndarray:
        return (cells - self.lowest) @ self.stride


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
