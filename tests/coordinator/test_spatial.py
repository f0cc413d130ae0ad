import numpy as np
import pytest
from scipy.spatial import cKDTree

from coordinator.cell_grid import REACH_TABLE, box_cells
from coordinator.levels import LeveledIndex
from coordinator.spatial import PointIndex


@pytest.mark.parametrize("n", [2, 3, 5])
def test_any_within_is_exact_against_a_kd_tree(n):
    rng = np.random.default_rng(n)
    pts = rng.random((5000, n)) * 10
    idx = PointIndex(n, 1.0, np.zeros(n))
    idx.insert(pts[:100])
    idx.insert(pts[100:])  # grows and rehashes
    dead = rng.random(5000) < 0.3
    idx.kill(np.nonzero(dead)[0])
    q = np.concatenate([rng.random((20000, n)) * 10, pts[:50] + 0.5])  # some exactly on box faces
    dist, _ = cKDTree(pts[~dead]).query(q, p=np.inf)
    np.testing.assert_array_equal(idx.any_within(q, 0.5), dist <= 0.5 + 1e-9)
    np.testing.assert_array_equal(idx.cover(q, 0.5) >= 0, dist <= 0.5 + 1e-9)  # the cells (5-D asks a tree above)
    idx.recell(0.6)
    dist2 = dist <= 0.3 + 1e-9
    np.testing.assert_array_equal(idx.any_within(q, 0.3), dist2)


def test_state_round_trip():
    idx = PointIndex(2, 1.0, np.zeros(2))
    idx.insert(np.array([[0.5, 0.5], [3.0, 3.0]]))
    idx.kill([0])
    back = PointIndex.from_state(idx.state())
    assert back.any_within(np.array([[0.5, 0.5], [3.2, 3.2]]), 0.5).tolist() == [False, True]


def test_dense_fast_path_agrees_with_the_chains():
    from coordinator.lattice import Lattice

    rng = np.random.default_rng(3)
    lo, hi = np.zeros(3), np.array([20.0, 20.0, 70.0])
    lat = Lattice.tiling(lo, hi, 1.0)
    centres = lat.box_centres(1.0)
    dense = PointIndex(3, 2.0, lat.anchor, bounds=(lo, hi))
    plain = PointIndex(3, 2.0, lat.anchor)
    extra = lo + (hi - lo) * rng.random((300, 3))
    doomed = rng.choice(len(centres) + len(extra), 2000, replace=False)
    for idx in (dense, plain):
        idx.insert(centres)
        idx.insert(extra)
        idx.kill(doomed)
        idx.kill([0, 0, 1])  # killing twice must not double count
    assert dense._dense is not None
    q = lo - 1 + (hi - lo + 2) * rng.random((50000, 3))
    np.testing.assert_array_equal(dense.any_within(q, 1.0), plain.any_within(q, 1.0))
    back = PointIndex.from_state(dense.state())
    np.testing.assert_array_equal(back.any_within(q, 1.0), plain.any_within(q, 1.0))
    dense.recell(1.0)
    plain.recell(1.0)
    np.testing.assert_array_equal(dense.any_within(q, 0.5), plain.any_within(q, 0.5))


def test_dense_miss_path_on_faces_and_edges():
    """Queries exactly on cell faces and at the grid's edges, with centre points killed
    so that only neighbours and off-centre points can answer."""
    from coordinator.lattice import Lattice

    rng = np.random.default_rng(5)
    lo, hi = np.zeros(2), np.array([10.0, 6.0])
    lat = Lattice.tiling(lo, hi, 0.5)
    centres = lat.box_centres(0.5)
    extra = np.concatenate([lo + (hi - lo) * rng.random((40, 2)), [[10.0, 6.0], [0.0, 0.0], [10.0 + 5e-10, 3.0]],
                            [[-3.2, -2.0], [13.0, 9.5], [12.4, 3.0]]])  # far outside: aliased into the margin
    doomed = rng.choice(len(centres), len(centres) // 2, replace=False)
    dense = PointIndex(2, 1.0, lat.anchor, bounds=(lo, hi))
    plain = PointIndex(2, 1.0, lat.anchor)
    for idx in (dense, plain):
        idx.insert(centres)
        idx.insert(extra)
        idx.kill(doomed)
    faces = np.stack(np.meshgrid(np.arange(-1.0, 11.5, 0.5), np.arange(-1.0, 7.5, 0.5), indexing="ij"), -1)
    q = np.concatenate([faces.reshape(-1, 2), lo - 0.5 + (hi - lo + 1) * rng.random((20000, 2)),
                        lo - 4 + (hi - lo + 8) * rng.random((20000, 2))])
    np.testing.assert_array_equal(dense.any_within(q, 0.5), plain.any_within(q, 0.5))


@pytest.mark.parametrize("seed", range(4))
def test_dense_paths_match_brute_force_near_faces_and_tolerances(seed):
    """Aligned lattice (faces on Sigma's bounds, as in SPE at delta = 2, 1, 0.5, ...),
    centres killed at random, off-centre points on faces, corners and a hair off them,
    queries likewise: the dense index answers exactly as a brute-force l-inf check."""
    from coordinator.lattice import Lattice

    rng = np.random.default_rng(seed)
    lo, hi = np.zeros(3), np.array([4.0, 4.0, 6.0])
    lat = Lattice.tiling(lo, hi, 0.5)
    centres = lat.box_centres(0.5)
    grid = np.round(lo + (hi - lo) * rng.random((400, 3)))  # lattice corners and faces
    hair = rng.choice([-2e-9, -1e-9, -5e-10, 0.0, 5e-10, 1e-9, 2e-9], size=(400, 3))
    off = np.concatenate([grid + hair, lo + (hi - lo) * rng.random((60, 3))])
    dense = PointIndex(3, 1.0, lat.anchor, bounds=(lo, hi))
    dense.insert(centres)
    dense.insert(off[:230])
    dense.kill(rng.choice(len(centres), len(centres) // 3, replace=False))
    dense.insert(off[230:])
    pts = dense.points[: dense.count][dense.alive[: dense.count]]
    q = np.concatenate([
        np.round(lo - 1 + (hi - lo + 2) * rng.random((3000, 3)) * 2) / 2,  # faces, centres
        np.round(lo + (hi - lo) * rng.random((3000, 3))) + rng.choice([-2e-9, -1e-9, 0.0, 1e-9, 2e-9], (3000, 3)),
        lo - 0.5 + (hi - lo + 1) * rng.random((6000, 3)),
    ])
    brute = (np.abs(q[:, None, :] - pts[None, :, :]).max(axis=2) <= 0.5 + 1e-9).any(axis=1)
    np.testing.assert_array_equal(dense.any_within(q, 0.5), brute)


@pytest.mark.parametrize("dense", [True, False])
def test_covered_by_since_answers_as_an_index_of_those_points(dense):
    """Re-deciding states against the points added since a screening (brute force) gives
    what ``cover`` gives on an index holding only those alive points: true distance with
    the tolerance, and on the dense grid a centre point covers its whole home cell even
    where it sits up to the centring tolerance off the exact centre (as below)."""
    rng = np.random.default_rng(7)
    delta, n = 1.0, 2
    lower, upper = np.zeros(n), np.full(n, 12.0)
    bounds = (lower, upper) if dense else None
    cells = rng.choice(36, size=40)
    centres = np.stack([cells // 6, cells % 6], axis=1) * 2 * delta + delta
    pts = np.concatenate([centres, rng.uniform(-1, 13, size=(40, n))])  # some beyond the bounds
    idx = PointIndex(n, 2 * delta, lower, bounds=bounds)
    idx.insert(pts[:30])
    first = idx.count
    idx.insert(pts[30:])
    dead = rng.choice(len(pts), size=15, replace=False)
    idx.kill(dead)
    alone = PointIndex(n, 2 * delta, lower, bounds=bounds)
    alone.insert(pts[first:])
    alone.kill(dead[dead >= first] - first)
    q = np.concatenate([rng.uniform(-2, 14, size=(3000, n)), pts + delta, pts - delta,
                        rng.integers(-1, 8, size=(500, n)) * 2 * delta])
    got = idx.covered_by_since(q, delta, first)
    np.testing.assert_array_equal(got, alone.cover(q, delta) >= 0)
    assert got.any() and not got.all()
    # a centre 1.8e-9 off its cell's exact centre, alone: its far corner is beyond the
    # true-distance tolerance (1e-9), covered on the dense grid only (by the home cell)
    lone = PointIndex(n, 2 * delta, lower, bounds=bounds)
    lone.insert(np.array([[9.0, 9.0], [3.0 + 1.8e-9, 3.0 + 1.8e-9]]))
    corner = np.array([[2.0, 2.0]])
    assert lone.covered_by_since(corner, delta, 1)[0] == dense == (lone.cover(corner, delta)[0] == 1)


def test_ids_stay_below_2_31_and_queries_answer_int64_ids():
    # chains and the dense grid hold int32 ids: the index refuses the 2^31st point
    index = PointIndex(2, 0.5, [0.0, 0.0], bounds=([0.0, 0.0], [4.0, 4.0]))
    ids = index.insert(np.array([[0.25, 0.25], [1.0, 1.1]]))
    assert index.cover(np.array([[0.3, 0.2], [1.05, 1.0], [3.0, 3.0]]), 0.25).tolist() == [ids[0], ids[1], -1]
    assert index.cover(np.array([[0.3, 0.2]]), 0.25).dtype == np.int64
    index.count = 2**31 - 1
    with pytest.raises(OverflowError, match="2\\^31"):
        index.insert(np.array([[2.0, 2.0]]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_deferred_chains_walk_as_chains_kept_at_once(seed):
    """A dense index links its hash chains only when a query walks them (radius other
    than cell/2); it must then name the very witnesses of an index that linked at every
    insert (no bounds: no dense grid), through rehashes, kills and a recell."""
    rng = np.random.default_rng(seed)
    lo, hi = np.zeros(3), np.full(3, 24.0)
    dense = PointIndex(3, 2.0, lo, bounds=(lo, hi))
    eager = PointIndex(3, 2.0, lo)
    assert dense._dense is not None and eager._dense is None

    def both(method, *args):
        getattr(dense, method)(*args)
        getattr(eager, method)(*args)

    for step in range(60):
        k = int(rng.integers(1, 40))  # crosses the table's doubling thresholds several times
        pts = np.where(rng.random((k, 1)) < 0.5, np.floor(rng.random((k, 3)) * 12) * 2 + 1, rng.random((k, 3)) * 24)
        both("insert", pts)
        if step % 7 == 3:
            both("kill", rng.choice(dense.count, size=dense.count // 5, replace=False))
        if step == 40:
            both("recell", 1.0)
        if step % 10 == 9:
            queries = rng.random((500, 3)) * 26 - 1
            small = dense.cell / 2 * 0.8  # walks the hash chains in both
            np.testing.assert_array_equal(dense.cover(queries, small), eager.cover(queries, small))
            large = dense.cell / 2 * 1.3
            alive = dense.points[: dense.count][dense.alive[: dense.count]]
            truth = (np.abs(queries[:, None, :] - alive[None, :, :]).max(axis=2) <= large + 1e-9).any(axis=1)
            np.testing.assert_array_equal(dense.any_within(queries, large), truth)


@pytest.mark.parametrize("n, span", [(2, 2), (3, 3), (5, 3), (7, 3)])
def test_box_cells_are_each_rows_cells_in_product_order(n, span):
    """The cells lo..hi of each row, row by row, each row's in itertools.product order of
    the offsets (the witness a search names depends on it), by the table and, past
    REACH_TABLE offsets (7 axes), by comparison."""
    import itertools

    rng = np.random.default_rng(n)
    lo = rng.integers(-3, 5, (40, n))
    hi = lo + rng.integers(0, span, (40, n))
    row_of, cells = box_cells(lo, hi, span)
    want_rows, want_cells = [], []
    for i in range(len(lo)):
        for o in itertools.product(range(span), repeat=n):
            if all(lo[i, a] + o[a] <= hi[i, a] for a in range(n)):
                want_rows.append(i)
                want_cells.append(lo[i] + np.array(o))
    assert (span**n > REACH_TABLE) == (n == 7)
    np.testing.assert_array_equal(row_of, want_rows)
    np.testing.assert_array_equal(cells, np.array(want_cells))


@pytest.mark.parametrize("seed", range(3))
def test_cover_away_names_the_witness_cover_names_where_the_home_cell_has_none(seed):
    """Queries whose home cell holds no centre point (and, for the index without a dense
    grid, any query): ``cover_away`` names the same witness as ``cover``, one query or many."""
    rng = np.random.default_rng(seed)
    lo, hi = np.zeros(3), np.full(3, 6.0)
    cells = rng.integers(0, 6, (120, 3))
    pts = np.concatenate([lo + cells + 0.5, rng.uniform(-0.5, 6.5, (150, 3))])
    for bounds in ((lo, hi), None):
        index = PointIndex(3, 1.0, lo, bounds=bounds)
        index.insert(pts)
        index.kill(rng.choice(len(pts), 60, replace=False))
        q = np.concatenate([rng.uniform(-1, 7, (4000, 3)), pts[:100] + rng.choice([0.0, 0.5, -0.5, 1e-10], (100, 3))])
        if bounds is not None:
            q = q[index.home_cover(q) < 0]
        assert len(q) > 1000
        np.testing.assert_array_equal(index.cover_away(q, 0.5), index.cover(q, 0.5))
        np.testing.assert_array_equal(index.cover_away(q[:1], 0.5), index.cover(q[:1], 0.5))


@pytest.mark.parametrize("n", [5, 7])
def test_a_large_high_dimensional_batch_asks_a_tree_and_answers_as_the_cells_do(n, monkeypatch):
    """From 5-D on, a large batch's misses go to a KD-tree (a round end's children checked
    3^n cells each): on an aligned lattice with centres killed, off-centre points on faces
    and a hair off them, and queries at centres, on faces and anywhere, the tree answers
    as the cells and as brute force do."""
    from coordinator import spatial
    from coordinator.lattice import Lattice

    rng = np.random.default_rng(n)
    lo, hi = np.zeros(n), np.full(n, 3.0)
    lat = Lattice.tiling(lo, hi, 0.5)
    centres = lat.box_centres(0.5)
    hair = rng.choice([-2e-9, -1e-9, 0.0, 1e-9, 2e-9], size=(300, n))
    off = np.round(lo + (hi - lo) * rng.random((300, n))) + hair
    idx = PointIndex(n, 1.0, lat.anchor, bounds=(lo, hi))
    idx.insert(centres)
    idx.insert(off)
    idx.kill(rng.choice(len(centres) + len(off), (len(centres) + len(off)) // 2, replace=False))
    faces = np.round(2 * (lo + (hi - lo) * rng.random((3000, n)))) / 2  # centres and faces of cells
    q = np.concatenate([faces, faces + rng.choice([-1e-9, 0.0, 1e-9], size=faces.shape),
                        lo - 0.5 + (hi - lo + 1) * rng.random((6000, n))])
    alive = idx.alive_points()
    tree, asked = spatial.PointIndex._tree_within, []
    monkeypatch.setattr(spatial.PointIndex, "_tree_within", lambda self, qs, r: asked.append(len(qs)) or tree(self, qs, r))
    for radius in (0.5, 0.3):
        truth = cKDTree(alive).query(q, p=np.inf)[0] <= radius + 1e-9
        asked.clear()
        got = idx.any_within(q, radius)
        assert asked and asked[0] > 0  # the tree answered the misses
        np.testing.assert_array_equal(got, truth)
        np.testing.assert_array_equal(idx.cover(q, radius) >= 0, truth)  # the cells, asked directly


@pytest.mark.parametrize("kind", ["cells", "dense", "leveled"])
def test_the_alive_count_kept_by_insert_and_kill_is_the_flags_count(kind):
    # the closing edge and the quiet rule ask it after every change: kept, not summed over
    # every point (a 9-D band campaign of 4 M boxes spent most of its head there)
    rng = np.random.default_rng(4)
    lo, hi = np.zeros(3), np.full(3, 8.0)
    cls = LeveledIndex if kind == "leveled" else PointIndex
    idx = cls(3, 1.0, np.zeros(3), bounds=(lo, hi) if kind == "dense" else None)
    for step in range(30):
        pts = np.round(rng.uniform(-1, 9, (int(rng.integers(1, 200)), 3)) * 2) / 2 + 0.5
        if kind == "leveled" and step % 3 == 1:
            idx.insert(pts, half_width=rng.choice([0.25, 0.5], len(pts)))  # mixed sizes, levels of their own
        else:
            idx.insert(pts)
        doomed = rng.integers(0, idx.count, int(rng.integers(0, 80)))
        idx.kill(np.concatenate([doomed, doomed[:5]]))  # repeats, and ids already dead
        if kind == "leveled":
            idx.resize(rng.integers(0, idx.count, 20), 0.25)  # a resize keeps a box alive or dead
        assert idx.alive_count == np.count_nonzero(idx.alive[: idx.count])
    assert cls.from_state(idx.state()).alive_count == idx.alive_count


def _cover_cell_by_cell(index: PointIndex, q: np.ndarray, radius: float) -> np.ndarray:
    """``cover`` without a dense grid as one ``_scan`` per cell: each query's home cell,
    then the cells its ball reaches in ``itertools.product`` order (per axis home then
    the side it crosses; for a query at a cell centre, offsets -1, 0, 1), the first cell
    holding an alive point within the radius naming the witness."""
    import itertools

    from coordinator.spatial import TOLERANCE

    r = radius + TOLERANCE
    found = np.full(len(q), -1, dtype=np.int64)
    rel = q - index.origin
    rel *= 1.0 / index.cell
    home = np.floor(rel).astype(np.int64)
    lo = np.floor(rel - r / index.cell).astype(np.int64)
    hi = np.floor(rel + r / index.cell).astype(np.int64)
    for i in range(len(q)):
        index._scan(q, home[i][None], np.array([i]), r, found)
        down, up = lo[i] < home[i], hi[i] > home[i]
        if (down & up).any():
            cells = (home[i] + np.array(off) for off in itertools.product((-1, 0, 1), repeat=index.n)
                     if any(off) and all((o >= 0 or d) and (o <= 0 or u) for o, d, u in zip(off, down, up)))
        else:
            side = np.where(down, lo[i], hi[i])
            cells = (np.where(pat, side, home[i]) for pat in itertools.product((False, True), repeat=index.n)
                     if any(pat) and all(not p or s != h for p, s, h in zip(pat, side, home[i])))
        for cell in cells:
            if found[i] >= 0:
                break
            index._scan(q, cell[None], np.array([i]), r, found)
    return found


@pytest.mark.parametrize("by_blocks", [True, False])
@pytest.mark.parametrize("n", [2, 4, 6])
def test_cover_without_a_dense_grid_names_the_witness_of_a_cell_by_cell_search(n, by_blocks, monkeypatch):
    """The cells around a query that misses its home cell are tried in blocks for every
    query at once (a few queries) or one cell index at a time for all (many), yet each
    query's witness is the one a cell-by-cell search in product order names, query by
    query: at dead centres (a ball reaching both neighbours of every axis), on faces,
    and anywhere."""
    import coordinator.spatial

    if not by_blocks:
        monkeypatch.setattr(coordinator.spatial, "ORDERED_QUERIES", 0)
    rng = np.random.default_rng(n)
    centres = 2.0 * rng.integers(0, 5, (1500, n)) + 1.0
    points = np.concatenate([centres, rng.uniform(0, 10, (300, n))])
    index = PointIndex(n, 2.0, np.zeros(n))  # no bounds: no dense grid
    index.insert(points)
    dead = rng.choice(len(points), len(points) // 2, replace=False)
    index.kill(dead)
    q = np.concatenate([points[dead[:60]], rng.uniform(-1, 11, (120, n)), np.round(rng.uniform(0, 10, (40, n))),
                        points[dead[60:80]] + 1e-10])
    for radius in (1.0, 0.7):
        got = index.cover(q, radius)
        assert np.array_equal(got, _cover_cell_by_cell(index, q, radius))
        assert 0 < (got >= 0).sum() < len(q)


@pytest.mark.parametrize("n", [3, 5, 7])
@pytest.mark.parametrize("off_centre", [False, True])
def test_a_miss_asks_only_the_cells_whose_centre_can_be_near_and_names_the_same_witness(n, off_centre, monkeypatch):
    """A query whose home cell holds no centre point: its witness, asked only of the cells
    whose centre lies within reach (mostly the home cell alone), is the one every cell its
    ball touches (2^n, 3^n near a centre) names, with centre points a hair off their
    centres, queries on faces, near centres and a hair off them, and off-centre points
    (whose chains every cell is asked for) or none."""
    import coordinator.spatial as spatial

    rng = np.random.default_rng(n + 10 * off_centre)
    lo, hi = np.zeros(n), np.full(n, 4.0)
    cells = rng.integers(0, 4, (600, n))
    centres = lo + cells + 0.5 + rng.choice([0.0, 4e-10, -4e-10], (600, n))  # within 1e-9 cells: centre points
    index = PointIndex(n, 1.0, lo, bounds=(lo, hi))
    index.insert(centres)
    if off_centre:
        index.insert(rng.uniform(-0.5, 4.5, (200, n)))
    index.kill(rng.choice(index.count, index.count // 3, replace=False))
    assert (index._off_alive > 0) == off_centre
    q = np.concatenate([rng.uniform(-0.7, 4.7, (3000, n)),
                        np.round(rng.uniform(0, 4, (1500, n)) * 2) / 2 + rng.choice([0.0, 1e-9, -1e-9, 3e-9], (1500, n)),
                        centres[:500] + rng.choice([0.0, 0.5, -0.5, 0.5 + 1e-9, 1.0], (500, n))])
    q = q[index.home_cover(q) < 0]
    assert len(q) > 1000
    got = index.cover(q, 0.5)
    monkeypatch.setattr(spatial, "CENTRE_SLACK", 1e6)  # every touched cell asked, as before
    want = index.cover(q, 0.5)
    assert (want >= 0).sum() > 100
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("n", [3, 5, 7])
def test_the_cells_a_chain_walk_asks_are_those_of_the_enumeration_in_its_order(n, monkeypatch):
    """``_touched``: rows spanning every axis inside the grid are summed from their first
    cell, the others enumerated; each row's flat cells, clipped into the margin, are the
    enumeration's in its order, for spans 2 and 3 and rows partly or wholly beyond the
    grid. And ``cover`` names the same witnesses as walking the enumerated cells, with
    off-centre points in and beyond the grid (dense enough that chains tie)."""
    from coordinator.cell_grid import box_cells

    rng = np.random.default_rng(n)
    lo, hi = np.zeros(n), np.full(n, 4.0)
    index = PointIndex(n, 1.0, lo, bounds=(lo, hi))
    index.insert(lo + rng.integers(0, 4, (300, n)) + 0.5)
    index.insert(rng.uniform(-0.6, 4.6, ({3: 40, 5: 800, 7: 6000}[n], n)))
    index.kill(rng.choice(index.count, index.count // 4, replace=False))
    for span in (2, 3):
        first = rng.integers(-3, 5, (400, n))
        first[:200] = rng.integers(-1, 5 - span + 1 + 1, (200, n))  # most inside the grid
        extent = np.where(rng.random((400, n)) < 0.9, span - 1, rng.integers(0, span, (400, n)))
        row_of, flat = index._touched(first, first + extent, span)
        want_rows, cells = box_cells(first, first + extent, span)
        want = index._flat(cells)
        for row in range(400):
            np.testing.assert_array_equal(flat[row_of == row], want[want_rows == row])
    q = np.concatenate([rng.uniform(-0.7, 4.7, (2000, n)),
                        np.floor(rng.uniform(0, 4, (1000, n))) + 0.5 + rng.choice([0.0, 1e-10, -1e-10], (1000, n))])
    got = index.cover(q, 0.5)

    def enumerated(self, lo_, hi_, span_):
        rows_, cells_ = box_cells(lo_, hi_, span_)
        return rows_, self._flat(cells_)

    monkeypatch.setattr(PointIndex, "_touched", enumerated)
    want = index.cover(q, 0.5)
    assert (want >= 0).sum() > 100 and (want < 0).sum() > 0
    np.testing.assert_array_equal(got, want)
