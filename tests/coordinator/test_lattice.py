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
