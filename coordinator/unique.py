"""Sorted distinct values of integer arrays (ids, cells, lattice indices).

numpy 2.4's ``np.unique`` hashes an integer array before it sorts the result: with many
distinct values that is several times slower than a sort and a mask (docs/benchmarks.md),
and a 9-D round end asks it about millions of lattice indices. These give numpy's arrays,
in numpy's order.
"""

from __future__ import annotations

import numpy as np


def unique_ints(values) -> np.ndarray:
    """``np.unique(values)`` of an integer array: its distinct values, ascending (flattened,
    dtype kept)."""
    out = np.sort(np.ravel(values))
    if len(out) < 2:
        return out
    keep = np.empty(len(out), dtype=bool)
    keep[0] = True
    np.not_equal(out[1:], out[:-1], out=keep[1:])
    return out[keep]


def unique_rows(rows: np.ndarray) -> np.ndarray:
    """``np.unique(rows, axis=0)`` of integer rows: the same rows in the same (lexicographic)
    order, sorted as one int64 key per row where the rows' ranges allow it (a 9-D round
    end's children: millions of rows, which ``np.unique`` sorts as row views)."""
    if len(rows) == 0:
        return np.unique(rows, axis=0)
    low = rows.min(axis=0)
    span = rows.max(axis=0) - low + 1
    if float(np.prod(span.astype(float))) >= 2.0**62:
        return np.unique(rows, axis=0)
    strides = np.concatenate([np.cumprod(span[::-1])[::-1][1:], [1]]).astype(np.int64)
    keys = (rows[:, 0] - low[0]) * strides[0]
    for axis in range(1, rows.shape[1]):  # axis 0 the most significant digit: lexicographic order
        keys += (rows[:, axis] - low[axis]) * strides[axis]
    keys = unique_ints(keys)
    return np.stack([keys // strides[axis] % span[axis] + low[axis] for axis in range(rows.shape[1])], axis=1)
