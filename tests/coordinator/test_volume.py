import numpy as np
import pytest

from coordinator.volume import hull_volume, union_volume


def test_union_and_hull_volumes_exact_and_clipped():
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


@pytest.mark.parametrize("bounds", [(0.0, 7.0), (0.0, 6.875)])
def test_coarse_boxes_overhanging_the_bounds_fill_their_clipped_cells(monkeypatch, bounds):
    """Coarse aligned boxes that overhang Sigma (a band set's interior at the domain's
    edge): clipped on cell faces they fill whole cells, so no cell is resolved piece by
    piece; off cell faces they are cut as before. Both equal a raster count."""
    from coordinator import volume

    calls = []  # ragged cells resolved piece by piece
    real = volume._ragged_volumes
    monkeypatch.setattr(volume, "_ragged_volumes", lambda lo, hi, starts: calls.extend(starts) or real(lo, hi, starts))
    coarse = np.array([[-1.0, 3.0], [3.0, 7.0], [7.0, 7.0]])  # half-width 2, on the 0.25 grid
    fine = np.array([[4.125, 0.125], [5.375, 0.625]])  # half-width 0.125
    centres = np.concatenate([coarse, fine])
    widths = np.r_[np.full(3, 2.0), np.full(2, 0.125)]
    lo, hi = np.full(2, bounds[0]), np.full(2, bounds[1])
    axes = np.arange(lo[0], hi[0], 0.125) + 0.0625
    mid = np.stack(np.meshgrid(axes, axes, indexing="ij"), -1).reshape(-1, 2)
    inside = (np.abs(mid[:, None, :] - centres[None]) <= widths[None, :, None]).all(axis=2).any(axis=1)
    expected = inside.sum() * 0.125**2
    assert volume.union_volume(centres, widths, bounds=(lo, hi)) == pytest.approx(expected, rel=1e-12)
    on_faces = bounds[1] == 7.0
    assert (len(calls) == 0) == on_faces, calls


@pytest.mark.parametrize("n", [2, 3, 5])
def test_ragged_cells_in_groups_sum_as_cell_by_cell(monkeypatch, n):
    """Cells of one compressed shape are computed together: each cell's volume is the
    very float ``_compressed_union`` gives it alone (so a set's volume does not change),
    and cells too large for a group go through it."""
    from coordinator import volume

    rng = np.random.default_rng(n)
    cells = 300
    k = rng.integers(1, 7, size=cells)
    starts = np.r_[0, np.cumsum(k)[:-1]]
    cell_lo = rng.integers(0, 50, size=(cells, n)).astype(float)
    lo = np.repeat(cell_lo, k, axis=0) + rng.choice([0.0, 0.25, 0.5, 0.3], size=(k.sum(), n))
    hi = np.minimum(lo + rng.choice([0.25, 0.5, 1.0, 0.7], size=(k.sum(), n)), np.repeat(cell_lo, k, axis=0) + 1)
    alone = [volume._compressed_union(lo[s : s + m], hi[s : s + m]) for s, m in zip(starts, k)]
    assert volume._ragged_volumes(lo, hi, starts).tolist() == alone
    monkeypatch.setattr(volume, "GROUP_LIMIT", 8)  # most cells alone
    assert volume._ragged_volumes(lo, hi, starts).tolist() == alone
