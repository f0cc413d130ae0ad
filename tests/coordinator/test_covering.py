import numpy as np
import pytest

from coordinator.covering import Lattice, covering_size, n_eps


def test_lemma_2_sample_sizes():
    assert n_eps(0.001, 0.01) == 4603  # the paper's figure (Lemma 2 text)
    assert n_eps(0.001, 0.1) == 2302
    assert n_eps(0.01, 0.05) == 299
    # the rule itself: (1 - eps)^N <= beta, and N - 1 does not suffice
    for eps, beta in [(0.001, 0.01), (0.05, 0.2), (0.3, 0.001)]:
        n = n_eps(eps, beta)
        assert (1 - eps) ** n <= beta < (1 - eps) ** (n - 1)


def test_lemma_1_sample_size():
    assert covering_size(20 * 20 * 70, 1.0, 3) == 3500
    assert covering_size(10.0, 0.5, 1) == 10


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


def test_union_and_hull_volumes_exact_and_clipped():
    from coordinator.volume import hull_volume, union_volume

    grid = np.stack(np.meshgrid(np.arange(4), np.arange(3), indexing="ij"), -1).reshape(-1, 2) + 0.5
    assert union_volume(grid, 0.5) == pytest.approx(12.0)
    assert hull_volume(grid, 0.5) == pytest.approx(12.0)
    overlapping = np.array([[0.0, 0.0], [0.5, 0.5], [3.0, 3.0]])  # 1 + 1 - 0.25 + 1
    assert union_volume(overlapping, 0.5) == pytest.approx(2.75)
    # clipped to [0, 4] x [0, 3]: the first box shrinks to [0, .5]^2, inside the second
    # box [0, 1]^2; the third keeps [2.5, 3.5] x [2.5, 3]
    assert union_volume(overlapping, 0.5, bounds=([0, 0], [4, 3])) == pytest.approx(1.0 + 0.5)
    rng = np.random.default_rng(0)
    c = rng.random((300, 3)) * 10
    mc = rng.random((300_000, 3)) * 11 - 0.5
    inside = (np.abs(mc[:, None, :] - c[None, :60, :]).max(axis=2) <= 0.5).any(axis=1)
    assert union_volume(c[:60], 0.5) == pytest.approx(inside.mean() * 11**3, rel=0.03)


@pytest.mark.parametrize("chunk", [7, 1 << 18])
def test_union_volume_equals_a_raster_count_on_mixed_lattices(monkeypatch, chunk):
    """Aligned boxes (whole cells), ragged ones at quarter offsets and boxes overhanging
    the bounds: with every face on the 0.25 grid, counting 0.25-cells is exact. Small
    chunks check that cutting the set into passes changes nothing."""
    from coordinator import volume

    monkeypatch.setattr(volume, "CHUNK", chunk)
    rng = np.random.default_rng(3)
    aligned = rng.integers(0, 8, size=(40, 3)) + 0.5
    ragged = rng.integers(0, 32, size=(25, 3)) * 0.25
    centres = np.unique(np.concatenate([aligned, ragged]), axis=0)
    lo, hi = np.zeros(3), np.full(3, 7.5)
    axes = np.arange(0, 7.5, 0.25) + 0.125  # 0.25-cell midpoints inside the bounds
    mid = np.stack(np.meshgrid(axes, axes, axes, indexing="ij"), -1).reshape(-1, 3)
    inside = np.zeros(len(mid), dtype=bool)
    for c in centres:
        inside |= (np.abs(mid - c) <= 0.5).all(axis=1)
    expected = inside.sum() * 0.25**3
    assert volume.union_volume(centres, 0.5, bounds=(lo, hi)) == pytest.approx(expected, rel=1e-12)
    assert volume.union_volume(centres, 0.5, origin=np.zeros(3)) == pytest.approx(
        volume.union_volume(centres, 0.5), rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_the_windowed_greedy_pass_keeps_what_the_plain_one_keeps(seed, monkeypatch):
    """Experience replay's greedy pass over thousands of states compares each kept
    point only with its neighbours in the first coordinate: the same points are kept
    as by comparing it with every later point (duplicates, points exactly delta apart
    and on a lattice included)."""
    from coordinator import algorithm

    rng = np.random.default_rng(seed)
    delta = [0.5, 0.125, 1 / 3, 2.0][seed]
    pts = np.concatenate([rng.uniform(-5, 40, size=(3000, 3)),
                          rng.integers(0, 20, size=(800, 3)) * delta,  # exactly delta apart
                          rng.uniform(0, 10, size=(200, 3)).round(1)])
    pts = np.concatenate([pts, pts[rng.choice(len(pts), 300)]])[rng.permutation(len(pts) + 300)]
    windowed = algorithm.greedy_uncovered(pts, delta)
    monkeypatch.setattr(algorithm, "GREEDY_WINDOWED", len(pts))
    plain = algorithm.greedy_uncovered(pts, delta)
    np.testing.assert_array_equal(windowed, plain)
    assert 0 < len(plain) < len(pts)
