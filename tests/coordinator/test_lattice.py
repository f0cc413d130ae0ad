import numpy as np
import pytest

from coordinator.lattice import Lattice


def test_tiling_covers_the_box_with_centres_inside_it():
    lo, hi = np.array([0.0, 5.0]), np.array([20.0, 25.0])
    lat = Lattice.tiling(lo, hi, 1.5)
    c = lat.box_centres(1.5)
    assert (c >= lo).all() and (c <= hi).all()
    pts = lo + (hi - lo) * np.random.default_rng(0).random((20000, 2))
    d = np.abs(pts[:, None, :] - c[None, :, :]).max(axis=2).min(axis=1)
    assert d.max() <= 1.5 + 1e-9
    assert len(c) == 7 * 7  # ceil(20 / 3) per axis


def test_halving_delta_splits_each_box_into_its_2n_children():
    lat = Lattice.tiling([0, 0, 0], [20, 20, 70], 2.0)
    parent = lat.box_centres(2.0)[:1]
    kids = lat.children(parent, 2.0, 1.0)
    assert len(kids) == 8
    assert np.abs(kids - parent).max() == pytest.approx(1.0)


def test_unique_rows_are_numpys_rows_in_numpys_order():
    """The children's deduplication: one int64 key per row, the same rows and order as
    ``np.unique(axis=0)``; negative indices; a range too wide for one key falls back."""
    from coordinator.lattice import unique_rows

    rng = np.random.default_rng(3)
    for n, low, high in ((1, -5, 5), (3, -3, 4), (9, -2, 9), (4, -(2**40), 2**40)):
        rows = rng.integers(low, high, (5000, n))
        rows = np.concatenate([rows, rows[:1000]])  # duplicates
        got = unique_rows(rows)
        np.testing.assert_array_equal(got, np.unique(rows, axis=0))
        assert got.dtype == np.int64 and len(got) < len(rows)
    assert unique_rows(np.zeros((0, 3), dtype=np.int64)).shape == (0, 3)
