"""coordinator/unique.py: numpy's distinct values and rows, in numpy's order."""

import numpy as np

from coordinator.unique import unique_ints, unique_rows


def test_unique_ints_are_numpys_for_ids_cells_and_edge_cases():
    rng = np.random.default_rng(2)
    cases = [rng.integers(0, 2**40, 20_000), rng.integers(-50, 50, 20_000), rng.integers(0, 2**30, 5000).astype(np.int32),
             np.sort(rng.integers(0, 100, 300)), rng.integers(0, 9, (40, 7)), np.array([5]), np.zeros(0, dtype=np.int64),
             np.full(10, 3, dtype=np.int64)]
    for values in cases:
        got, want = unique_ints(values), np.unique(values)
        np.testing.assert_array_equal(got, want)
        assert got.dtype == want.dtype and got.ndim == 1
    values = rng.integers(0, 10, 100)
    before = values.copy()
    unique_ints(values)
    np.testing.assert_array_equal(values, before)  # the input is not sorted in place


def test_unique_rows_are_numpys_rows_in_numpys_order():
    """The children's deduplication: one int64 key per row, the same rows and order as
    ``np.unique(axis=0)``; negative indices; a range too wide for one key falls back."""
    rng = np.random.default_rng(3)
    for n, low, high in ((1, -5, 5), (3, -3, 4), (9, -2, 9), (4, -(2**40), 2**40)):
        rows = rng.integers(low, high, (5000, n))
        rows = np.concatenate([rows, rows[:1000]])  # duplicates
        got = unique_rows(rows)
        np.testing.assert_array_equal(got, np.unique(rows, axis=0))
        assert got.dtype == np.int64 and len(got) < len(rows)
    assert unique_rows(np.zeros((0, 3), dtype=np.int64)).shape == (0, 3)
