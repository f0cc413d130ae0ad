"""Integer cells of a grid: flat indexes, and the cells a box's extent covers (what the
spatial indexes, coordinator/spatial.py and coordinator/level_grid.py, and the figures'
painting, farm/reports/plots/membership.py, share)."""

from __future__ import annotations

import functools
import itertools

import numpy as np

SMALL_MATMUL = 1024  # cells up to which a (k, n) integer product beats n 1-D operations
REACH_TABLE = 729  # offsets (3^6) up to which which-offsets-an-extent-reaches is a table


def flat_index(cells: np.ndarray, strides: np.ndarray) -> np.ndarray:
    """(k, n) int64 cells (in the grid) -> (k,) flat indexes: a few as one integer product
    (fewer array operations), many per axis (numpy has no fast integer matmul)."""
    if len(cells) <= SMALL_MATMUL:
        return cells @ strides
    flat = cells[:, 0] * strides[0]
    for axis in range(1, cells.shape[1]):
        flat += cells[:, axis] * strides[axis]
    return flat


def box_cells(lo: np.ndarray, hi: np.ndarray, span: int) -> tuple[np.ndarray, np.ndarray]:
    """The integer cells lo + o of each row (0 <= o < span and lo + o <= hi per axis;
    hi - lo < span): (m,) the row of each, (m, n) the cells, row by row, each row's in
    ``itertools.product`` order of o. Every row has at least its cell lo."""
    offsets, reaches, radix = _offset_tables(span, lo.shape[1])
    if reaches is not None:  # which offsets each row's extent reaches, by the extent's number
        row_of, cell_of = np.nonzero(reaches[(hi - lo) @ radix])
    else:
        row_of, cell_of = np.nonzero((offsets[None] <= (hi - lo)[:, None, :]).all(axis=2))
    return row_of, lo[row_of] + offsets[cell_of]


def box_offsets(span: int, n: int) -> np.ndarray:
    """(span^n, n) int64, read-only: the offsets 0..span-1 per axis in ``box_cells``' order."""
    return _offset_tables(span, n)[0]


@functools.lru_cache(maxsize=64)
def _offset_tables(span: int, n: int) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The offsets 0..span-1 per axis, (span^n, n) int64 in ``itertools.product`` order;
    (span^n, span^n) bool: offset o lies within extent e (o <= e per axis), by e's number
    (None past REACH_TABLE offsets); (n,) int64: an extent's number (e @ radix, e in the
    offsets' order)."""
    offsets = np.array(list(itertools.product(range(span), repeat=n)), dtype=np.int64).reshape(-1, n)
    radix = span ** np.arange(n - 1, -1, -1, dtype=np.int64)
    reaches = None
    if len(offsets) <= REACH_TABLE:
        reaches = (offsets[None, :, :] <= offsets[:, None, :]).all(axis=2)
    for table in (offsets, radix, reaches):
        if table is not None:
            table.flags.writeable = False  # shared by every index
    return offsets, reaches, radix
