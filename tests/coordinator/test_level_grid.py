"""The finest-grid summary of a leveled index (coordinator/level_grid.py): kept up to date
through inserts, kills and resizes it names the witnesses one rebuilt from scratch names
and reaches at least as far, and ``cover`` names the same witness with it as by asking
every level."""

import numpy as np
import pytest

from coordinator.level_grid import NestedGrid
from coordinator.levels import LeveledIndex

LOWER, UPPER = np.zeros(3), np.array([8.0, 8.0, 12.0])


def _points(rng, k, hw):
    """Centres of lattice boxes at ``hw`` (duplicates included), off-centre points (some
    beyond the bounds) and points on cell faces."""
    cells = rng.integers(0, 6, size=(k, 3))
    pts = cells * 2 * hw + hw
    kind = rng.random(k)
    pts[kind < 0.25] = rng.uniform(-0.5, 12.5, size=(int((kind < 0.25).sum()), 3))
    face = (kind >= 0.25) & (kind < 0.35)
    pts[face] = rng.integers(0, 24, size=(int(face.sum()), 3)) * 0.5
    return pts


def _queries(rng, k=3000):
    return np.concatenate([rng.uniform(-1, 13, size=(k, 3)),
                           rng.integers(-2, 50, size=(k // 3, 3)) * 0.25,  # faces and centres
                           rng.integers(-2, 50, size=(k // 3, 3)) * 0.25 + rng.choice([-1e-9, 1e-9], (k // 3, 3))])


def _asking_every_level(index, q):
    grid, stale = index._grid, index._grid_stale
    index._grid, index._grid_stale = None, False
    try:
        return index.cover(q)
    finally:
        index._grid, index._grid_stale = grid, stale


def _assert_like_rebuilt(index):
    grid = index._grid
    fresh = NestedGrid.build(index._levels, index._globals, index._order())
    assert np.array_equal(grid.witness, fresh.witness)
    assert np.array_equal(grid.centred, fresh.centred)
    assert not (fresh.reach & ~grid.reach).any()  # bits of points gone may stay, no bit may lack


@pytest.mark.parametrize("seed", range(4))
def test_the_grid_follows_every_change_and_cover_names_the_same_witnesses(seed):
    rng = np.random.default_rng(seed)
    index = LeveledIndex(3, 4.0, LOWER, bounds=(LOWER, UPPER))
    widths = [2.0, 1.0, 0.5, 0.25]
    index.insert(_points(rng, 40, 2.0))
    q = _queries(rng)
    used = 0
    for step in range(40):
        if step % 10 == 9 and used < 3:  # a round end: a finer level
            used += 1
            index.recell(2 * widths[used])
            index.resize(rng.integers(0, index.count, size=8), widths[used])
        op = rng.choice(["insert", "kill", "resize"])
        if op == "insert":
            hw = widths[int(rng.integers(0, used + 1))]
            index.insert(_points(rng, int(rng.integers(1, 30)), hw), half_width=hw)
        elif op == "kill":
            index.kill(rng.integers(0, index.count, size=int(rng.integers(1, 12))))
        else:
            index.resize(rng.integers(0, index.count, size=int(rng.integers(1, 6))),
                         widths[int(rng.integers(0, used + 1))])
        found = index.cover(q)
        assert index._grid is not None
        assert np.array_equal(found, _asking_every_level(index, q))
        _assert_like_rebuilt(index)
    assert len(index.levels()) == 4
    # the grid alone settles a query in the cell of a lattice box (the point of it), and
    # one beyond the reach of every box
    ids = index.alive_ids()
    lattice = np.array([index._levels[index._level[i]][1]._centre_cell[index._local[i]] >= 0 for i in ids])
    inside = ids[lattice][(index.points[ids[lattice]] < UPPER).all(axis=1)]
    witness, levels, outside = index._grid.lookup(index.points[inside] + 0.01)
    assert len(inside) > 20 and (witness >= 0).all() and not outside.any()
    far = np.array([[7.99, 7.99, 11.99]])
    index.kill(np.flatnonzero(np.abs(index.points[: index.count] - far).max(axis=1) <= 9.0))  # beyond the cells of every level holding it
    fresh = NestedGrid.build(index._levels, index._globals, index._order())
    witness, levels, outside = fresh.lookup(far)
    assert witness[0] == -1 and levels[0] == 0 and index.cover(far)[0] == -1
    again = LeveledIndex.from_state(index.state())
    assert np.array_equal(again.cover(q), index.cover(q))


def test_levels_that_are_not_nested_ask_every_level():
    rng = np.random.default_rng(9)
    index = LeveledIndex(3, 4.0, LOWER, bounds=(LOWER, UPPER))
    index.insert(_points(rng, 40, 2.0))
    index.insert(_points(rng, 40, 0.3) * 0.5, half_width=0.3)  # 2 / 0.3: no power of two
    q = _queries(rng)
    found = index.cover(q)
    assert index._grid is None
    assert np.array_equal(found, _asking_every_level(index, q))


def test_a_dropped_index_is_freed_without_a_collection():
    """The grid refers to its index's lists, never to the index: a coverage dropped (a
    finished campaign's, a replaced mirror's) frees its arrays at once."""
    import gc
    import weakref

    rng = np.random.default_rng(2)
    index = LeveledIndex(3, 4.0, LOWER, bounds=(LOWER, UPPER))
    index.insert(_points(rng, 40, 2.0))
    index.cover(_queries(rng, 30))
    assert index._grid is not None
    gone = weakref.ref(index)
    gc.disable()
    try:
        del index
        assert gone() is None
    finally:
        gc.enable()
