"""Volumes of a quantified set: the union of l-inf boxes centre +- half-width, each box
with its own half-width.

``union_volume`` is exact. Space is cut into cells of side 2f, f the smallest
half-width, aligned with the boxes' most common lattice; a box whose faces lie on cell
faces fills whole cells (one cell for a box of half-width f, k^n for one of k f), every
other cell is resolved by coordinate compression over the few box pieces that reach into
it (a box of half-width w meets at most (ceil(w / f) + 1)^n cells, and pieces in one
cell share most of their coordinates). A box clipped by the bounds fills whole cells too
when its clipped faces lie on cell faces.

``hull_volume`` is the volume of the convex hull of the union (the paper's
"cardinality"): for boxes of one size conv(union) = conv(centres) + cube, so only the
centres on their own hull matter, size by size.
"""

from __future__ import annotations

import itertools

import numpy as np


def _origin(lower: np.ndarray, side: float) -> np.ndarray:
    """The alignment shared by most boxes (their lower corners modulo ``side``)."""
    residue = np.round(np.mod(lower, side) / side * 1e6).astype(np.int64)
    origin = np.empty(lower.shape[1])
    for axis in range(lower.shape[1]):
        # the smallest most common residue (residues lie in [0, 1e6])
        origin[axis] = np.argmax(np.bincount(residue[:, axis])) / 1e6 * side
    return origin


CHUNK = 1 << 18  # boxes (or cells of boxes) per pass: temporaries stay ~50 MB however large the set
COMPRESSED_LIMIT = 1 << 22  # boxes x compressed cells marked at once in a cell (above: box by box)
GROUP_LIMIT = 1 << 12  # boxes x compressed cells of a cell computed in a group of cells (above: alone)


def _widths(centres: np.ndarray, half_widths) -> np.ndarray:
    """(M,) half-widths from a scalar or one per box."""
    return np.broadcast_to(np.asarray(half_widths, dtype=float), (len(centres),))


def union_volume(centres: np.ndarray, half_widths, origin=None, bounds=None) -> float:
    """Exact volume of the union of boxes centre +- half-width (``half_widths``: one
    per box, or one for all), clipped to ``bounds`` (lo, hi) when given: the safe set
    lives in Sigma, boxes may overhang it."""
    centres = np.asarray(centres, dtype=float)
    if len(centres) == 0:
        return 0.0
    n = centres.shape[1]
    widths = _widths(centres, half_widths)
    finest = float(widths.min())
    uniform = float(widths.max()) == finest  # every box one cell: no sizes to tell apart
    side = 2 * finest
    # a box spans ratio = w / f cells per axis when its faces are on cell faces
    ratio = widths / finest
    whole = np.round(ratio).astype(np.int64)
    integral = None if uniform else np.abs(ratio - whole) < 1e-9
    lower = centres - widths[:, None]
    origin = _origin(lower, side) if origin is None else np.asarray(origin, dtype=float)
    blo, bhi = (None, None) if bounds is None else (np.asarray(b, dtype=float) for b in bounds)
    reach = int(np.ceil(ratio.max() - 1e-9))
    keys = _CellKeys(np.floor((lower.min(axis=0) - origin) / side).astype(np.int64) - 1,
                     np.floor((lower.max(axis=0) - origin) / side).astype(np.int64) + 1 + reach)
    # an aligned, unclipped box is exactly its cells: they are full, and it reaches into
    # no other cell with positive volume; the other ("ragged") boxes are cut into
    # pieces, one per cell they reach into
    full_keys, ragged = [], []
    for first in range(0, len(centres), CHUNK):
        lo = lower[first : first + CHUNK]
        rel = (lo - origin) / side
        aligned = (np.abs(rel - np.round(rel)) < 1e-9).all(axis=1)
        if not uniform:
            aligned &= integral[first : first + CHUNK]
        if bounds is not None:  # an unclipped aligned box fills its cells
            hi_box = lo + 2 * widths[first : first + CHUNK, None]
            clipped = ~((lo >= blo - 1e-12) & (hi_box <= bhi + 1e-12)).all(axis=1)
            aligned &= ~clipped
            # a clipped box whose clipped faces lie on cell faces fills its cells too
            # (a coarse box overhanging Sigma would otherwise be cut into thousands of pieces)
            clip_lo, clip_hi = np.maximum(lo, blo), np.minimum(hi_box, bhi)
            filled = clipped & _on_cell_faces(clip_lo, clip_hi, origin, side)
            full_keys += _filled_keys(keys, clip_lo[filled], clip_hi[filled], origin, side)
        else:
            filled = np.zeros(len(lo), dtype=bool)
        cells = np.round(rel[aligned]).astype(np.int64)
        if uniform:
            full_keys.append(keys(cells))
        else:
            k = whole[first : first + CHUNK][aligned]
            for size in np.unique(k):
                full_keys += _spanned_keys(keys, cells[k == size], int(size))
        ragged.append(first + np.flatnonzero(~aligned & ~filled))
    full_keys = np.sort(np.concatenate(full_keys)) if full_keys else np.zeros(0, dtype=np.int64)
    full_keys = full_keys[np.r_[True, full_keys[1:] != full_keys[:-1]]] if len(full_keys) else full_keys
    ragged = np.concatenate(ragged)
    lo, hi = lower[ragged], centres[ragged] + widths[ragged, None]
    base = np.floor((lo - origin) / side + 1e-9).astype(np.int64)
    spans = np.ceil(ratio[ragged] - 1e-9).astype(np.int64) + 1  # cells a box can meet per axis
    if bounds is not None:
        lo, hi = np.maximum(lo, blo), np.minimum(hi, bhi)
        keep = (hi - lo > 1e-12).all(axis=1)
        lo, hi, base, spans = lo[keep], hi[keep], base[keep], spans[keep]
    # every (box, cell) piece of a ragged box in a cell that is not full
    piece_box, piece_key, piece_cell = [], [], []
    for span in np.unique(spans):
        of_span = np.flatnonzero(spans == span)
        for shift in itertools.product(range(int(span)), repeat=n):
            cells = base[of_span] + np.array(shift)
            cell_lo = origin + cells * side
            inter = (np.minimum(hi[of_span], cell_lo + side) - np.maximum(lo[of_span], cell_lo) > 1e-12).all(axis=1)
            k = keys(cells[inter])
            pos = np.minimum(np.searchsorted(full_keys, k), max(len(full_keys) - 1, 0))
            open_ = ~(full_keys[pos] == k) if len(full_keys) else np.ones(len(k), dtype=bool)
            piece_box.append(of_span[inter][open_])
            piece_key.append(k[open_])
            piece_cell.append(cells[inter][open_])
    if not piece_box:
        piece_box, piece_key, piece_cell = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros((0, n), np.int64)]
    piece_box, piece_key, piece_cell = (np.concatenate(a) for a in (piece_box, piece_key, piece_cell))
    order = np.argsort(piece_key, kind="stable")
    piece_box, piece_key, piece_cell = piece_box[order], piece_key[order], piece_cell[order]
    starts = np.flatnonzero(np.r_[True, piece_key[1:] != piece_key[:-1]]) if len(piece_key) else np.empty(0, int)
    total = len(full_keys) * side**n
    cell_lo = origin + piece_cell * side
    cut_lo, cut_hi = np.maximum(lo[piece_box], cell_lo), np.minimum(hi[piece_box], cell_lo + side)
    for volume in _ragged_volumes(cut_lo, cut_hi, starts).tolist():  # in key order, as cell by cell
        total += volume
    return float(total)


def _ragged_volumes(lo: np.ndarray, hi: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(C,) the union volume in each ragged cell, whose pieces (cut to the cell) are
    rows ``starts[c]:starts[c + 1]`` of (lo, hi), each by coordinate compression.

    Cells are taken in groups of the same compressed shape (unique coordinates per
    axis), all of a group's boxes marked at once, so that a set of many small cells
    costs a few dozen array operations per group rather than per cell; each cell's
    volume is the sum ``_compressed_union`` forms (the same products, summed in the same
    order). Cells with many boxes or compressed cells go through ``_compressed_union``."""
    cells, n = len(starts), lo.shape[1]
    if cells == 0:
        return np.zeros(0)
    k = np.diff(np.r_[starts, len(lo)])
    cell = np.repeat(np.arange(cells), k)
    # per axis: each cell's unique coordinates (flattened, cell by cell) and the rank of
    # every piece's faces among them
    coords, first, rank_lo, rank_hi = [], [], np.empty((len(lo), n), np.int64), np.empty((len(lo), n), np.int64)
    for a in range(n):
        values = np.concatenate([lo[:, a], hi[:, a]])
        owner = np.concatenate([cell, cell])
        order = np.lexsort((values, owner))
        v, o = values[order], owner[order]
        new = np.ones(len(v), dtype=bool)
        new[1:] = (o[1:] != o[:-1]) | (v[1:] != v[:-1])
        unique_id = np.cumsum(new) - 1
        start = np.searchsorted(o[new], np.arange(cells))
        rank = np.empty(len(v), np.int64)
        rank[order] = unique_id - start[o]
        rank_lo[:, a], rank_hi[:, a] = rank[: len(lo)], rank[len(lo) :]
        coords.append(v[new])
        first.append(start)
    shape = np.stack([np.diff(np.r_[f, len(c)]) - 1 for f, c in zip(first, coords)], axis=1)  # (C, n)
    size = np.prod(shape.astype(float), axis=1)
    out = np.empty(cells)
    small = np.flatnonzero(k * size <= GROUP_LIMIT)
    for c in np.setdiff1d(np.arange(cells), small):
        rows = slice(starts[c], starts[c] + k[c])
        out[c] = _compressed_union(lo[rows], hi[rows])
    if len(small) == 0:
        return out
    key = np.ravel_multi_index(shape[small].T, shape[small].max(axis=0) + 1)
    order = np.argsort(key, kind="stable")
    bounds = np.flatnonzero(np.r_[True, key[order][1:] != key[order][:-1], True])
    for g0, g1 in zip(bounds[:-1], bounds[1:]):
        group = small[order[g0:g1]]
        dims = [int(d) for d in shape[group[0]]]
        kmax = int(k[group].max())
        # the boxes' compressed spans, (G, kmax, n); a missing box spans nothing
        take = starts[group][:, None] + np.arange(kmax)
        real = np.arange(kmax) < k[group][:, None]
        take = np.where(real, take, 0)
        span_lo = np.where(real[..., None], rank_lo[take], 0)
        span_hi = np.where(real[..., None], rank_hi[take], 0)
        covered = np.zeros([len(group)] + dims, dtype=bool)
        for j in range(kmax):
            box = np.ones([len(group)] + [1] * n, dtype=bool)
            for a in range(n):
                i = np.arange(dims[a])
                inside = (i >= span_lo[:, j, a, None]) & (i < span_hi[:, j, a, None])
                box = box & inside.reshape([len(group)] + [1] * a + [dims[a]] + [1] * (n - a - 1))
            covered |= box
        cell_volume = None
        for a in range(n):
            at = first[a][group][:, None] + np.arange(dims[a])
            widths = coords[a][at + 1] - coords[a][at]  # np.diff of the cell's coordinates
            if cell_volume is None:
                cell_volume = widths
            else:  # np.multiply.outer's products, in its order
                cell_volume = cell_volume[..., None] * widths.reshape([len(group)] + [1] * a + [dims[a]])
        out[group] = (cell_volume * covered).reshape(len(group), -1).sum(axis=1)
    return out


def _spanned_keys(keys: "_CellKeys", corners: np.ndarray, size: int) -> list[np.ndarray]:
    """Keys of the cells of aligned boxes ``size`` cells wide whose lowest cells are
    ``corners`` (k, n), in passes of at most CHUNK cells."""
    if size == 1:
        return [keys(corners)]
    offsets = np.array(list(itertools.product(range(size), repeat=corners.shape[1])), dtype=np.int64)
    step = max(1, CHUNK // len(offsets))
    return [keys((corners[at : at + step, None, :] + offsets[None]).reshape(-1, corners.shape[1]))
            for at in range(0, len(corners), step)]


def _on_cell_faces(lo: np.ndarray, hi: np.ndarray, origin: np.ndarray, side: float) -> np.ndarray:
    """(k,) bool: do the boxes [lo, hi] have every face on a cell face, and volume?"""
    rel_lo, rel_hi = (lo - origin) / side, (hi - origin) / side
    on_faces = (np.abs(rel_lo - np.round(rel_lo)) < 1e-9) & (np.abs(rel_hi - np.round(rel_hi)) < 1e-9)
    return on_faces.all(axis=1) & (np.round(rel_hi) > np.round(rel_lo)).all(axis=1)


def _filled_keys(keys: "_CellKeys", lo: np.ndarray, hi: np.ndarray, origin: np.ndarray,
                 side: float) -> list[np.ndarray]:
    """Keys of the cells filled by boxes [lo, hi] (k, n) whose faces lie on cell faces,
    each its own number of cells per axis, in passes of at most CHUNK cells."""
    first = np.round((lo - origin) / side).astype(np.int64)
    spans = np.round((hi - origin) / side).astype(np.int64) - first
    out = []
    for span in np.unique(spans, axis=0):
        corners = first[(spans == span).all(axis=1)]
        offsets = np.stack(np.meshgrid(*[np.arange(s) for s in span], indexing="ij"), -1).reshape(-1, len(span))
        step = max(1, CHUNK // len(offsets))
        out += [keys((corners[at : at + step, None, :] + offsets[None]).reshape(-1, len(span)))
                for at in range(0, len(corners), step)]
    return out


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
    cells = [len(c) - 1 for c in coords]
    if len(lo) * np.prod(cells, dtype=float) <= COMPRESSED_LIMIT:
        # each box's span of compressed intervals per axis, all boxes at once
        covered = np.ones((len(lo),) + (1,) * n, dtype=bool)
        for a, c in enumerate(coords):
            i = np.arange(cells[a])
            inside = (i >= np.searchsorted(c, lo[:, a])[:, None]) & (i < np.searchsorted(c, hi[:, a])[:, None])
            covered = covered & inside.reshape((len(lo),) + (1,) * a + (cells[a],) + (1,) * (n - a - 1))
        covered = covered.any(axis=0)
    else:
        covered = np.zeros(cells, dtype=bool)
        for box_lo, box_hi in zip(lo, hi):
            sl = tuple(slice(np.searchsorted(c, l), np.searchsorted(c, u)) for c, l, u in zip(coords, box_lo, box_hi))
            covered[sl] = True
    widths = [np.diff(c) for c in coords]
    cell_volume = widths[0]
    for w in widths[1:]:
        cell_volume = np.multiply.outer(cell_volume, w)
    return float((cell_volume * covered).sum())


def hull_volume(centres: np.ndarray, half_widths, bounds=None) -> float:
    """Convex-hull volume of the union of boxes (clipped to ``bounds`` when given). Of
    the boxes of one half-width only those centred on the hull of their centres, or
    clipped by the bounds, can contribute hull vertices, so only their corners are
    handed to qhull."""
    centres = np.asarray(centres, dtype=float)
    if len(centres) == 0:
        return 0.0
    n = centres.shape[1]
    widths = _widths(centres, half_widths)
    from scipy.spatial import ConvexHull, QhullError  # here: scipy.spatial is 0.4 s of every CLI start

    on_hull = np.zeros(len(centres), dtype=bool)
    for width in np.unique(widths):
        group = np.flatnonzero(widths == width)
        try:
            on_hull[group[ConvexHull(centres[group]).vertices] if len(group) > n else group] = True
        except QhullError:  # flat set of centres: every centre may be on the hull
            on_hull[group] = True
    unit = np.array(list(itertools.product((-1.0, 1.0), repeat=n)))
    if bounds is not None:
        blo, bhi = (np.asarray(b, dtype=float) for b in bounds)
        on_hull |= ((centres - widths[:, None] < blo) | (centres + widths[:, None] > bhi)).any(axis=1)
    points = (centres[on_hull][:, None, :] + widths[on_hull][:, None, None] * unit[None, :, :]).reshape(-1, n)
    if bounds is not None:
        points = np.unique(np.clip(points, blo, bhi), axis=0)
    return float(ConvexHull(points).volume)


def corner_hull_volume(lower: np.ndarray, upper: np.ndarray, bounds=None) -> float:
    """Convex-hull volume of boxes [lower, upper] with a half-width per axis, from every
    corner (2^n per box: for low dimensions only)."""
    from scipy.spatial import ConvexHull  # here: scipy.spatial is 0.4 s of every CLI start

    if len(lower) == 0:
        return 0.0
    if bounds is not None:
        lower, upper = np.maximum(lower, bounds[0]), np.minimum(upper, bounds[1])
    n = lower.shape[1]
    pick = np.array(list(itertools.product((False, True), repeat=n)))
    points = np.where(pick[None, :, :], upper[:, None, :], lower[:, None, :]).reshape(-1, n)
    return float(ConvexHull(np.unique(points, axis=0)).volume)


def raster_iou(a, b, lower, upper, points_per_axis: int = 60) -> float:
    """IoU of two safe sets (``coordinator.safe_set.SafeSet``), measured on a regular
    grid of cell midpoints over [lower, upper] (exact membership at each point)."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    axes = [lo + (hi - lo) * (np.arange(points_per_axis) + 0.5) / points_per_axis for lo, hi in zip(lower, upper)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lower))
    inside = [a.contains(grid), b.contains(grid)]
    union = (inside[0] | inside[1]).sum()
    return float((inside[0] & inside[1]).sum() / union) if union else 1.0
