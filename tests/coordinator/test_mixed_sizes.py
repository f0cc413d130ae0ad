"""Boxes of mixed sizes (boundary refinement, issue 36): the leveled covering answers as
brute force over every box at its own half-width, a mirror applying the logged changes
(resizes included) names the same witnesses, a snapshot restores them, and SPE with
refine = "band" keeps interior boxes coarse, splits a coarse box a pruning reaches, and
exports and certifies a mixed-size set."""

import numpy as np
import pytest

from coordinator.coverage import AddFailures, Coverage, Insert, Kill, Recell, Resize
from coordinator.levels import LeveledIndex
from coordinator.spatial import TOLERANCE
from coordinator.spe import SPE, SPESettings
from scenarios.registry import make_scenario

LOWER, UPPER = np.zeros(2), np.full(2, 16.0)


def _boxes(rng, k, hw):
    """Lattice centres at half-width ``hw`` (anchored at 0), some off-centre points."""
    cells = rng.integers(0, int(16 / (2 * hw)), size=(k, 2))
    pts = cells * 2 * hw + hw
    off = rng.random(k) < 0.2
    pts[off] = rng.uniform(0, 16, size=(int(off.sum()), 2))
    return pts


def _brute(index, queries):
    ids = index.alive_ids()
    d = np.abs(queries[:, None, :] - index.points[ids][None, :, :]).max(axis=2)
    return (d <= index.half_width[ids][None, :] + TOLERANCE).any(axis=1)


def _queries(rng):
    # uniform ones and ones on box faces and corners of every level
    on_grid = rng.integers(0, 33, size=(300, 2)) * 0.5
    return np.concatenate([rng.uniform(-1, 17, size=(600, 2)), on_grid])


@pytest.mark.parametrize("seed", range(5))
def test_cover_is_brute_force_over_own_half_widths(seed):
    rng = np.random.default_rng(seed)
    index = LeveledIndex(2, 4.0, LOWER, bounds=(LOWER, UPPER))
    index.insert(_boxes(rng, 20, 2.0))
    index.recell(1.0)
    index.insert(_boxes(rng, 60, 0.5))
    index.insert(_boxes(rng, 10, 1.0), half_width=1.0)
    index.kill(rng.integers(0, index.count, size=15))
    index.resize(rng.integers(0, index.count, size=10), 0.5)
    q = _queries(rng)
    found = index.cover(q)
    assert np.array_equal(found >= 0, _brute(index, q))
    hit = found >= 0
    assert index.alive[found[hit]].all()
    reach = np.abs(q[hit] - index.points[found[hit]]).max(axis=1)
    assert (reach <= index.half_width[found[hit]] + TOLERANCE).all()
    assert sorted(index.levels()) == [0.5, 1.0, 2.0]
    # a snapshot names the same witnesses
    again = LeveledIndex.from_state(index.state())
    assert np.array_equal(again.cover(q), found)
    # covered_by_since: the boxes inserted after ``first`` (no resize since)
    first = index.count
    index.insert(_boxes(rng, 12, 0.5))
    since = index.covered_by_since(q, None, first)
    later = LeveledIndex(2, 1.0, LOWER, bounds=(LOWER, UPPER))
    later.insert(index.points[first : index.count])
    assert np.array_equal(since, later.any_within(q))


def _changes(rng, count):
    log = [Insert(_boxes(rng, 30, 2.0))]
    alive, delta = 30, 2.0
    for _ in range(count):
        kind = rng.choice(["insert", "kill", "fail", "round"], p=[0.45, 0.3, 0.15, 0.1])
        if kind == "insert":
            k = int(rng.integers(0, 6))
            log.append(Insert(_boxes(rng, k, delta), None if rng.random() < 0.5 else delta))
            alive += k
        elif kind == "kill":
            log.append(Kill(rng.integers(0, alive, size=int(rng.integers(1, 4)))))
        elif kind == "fail":
            log.append(AddFailures(_boxes(rng, 1, delta)))
        elif delta > 0.5:
            delta /= 2
            log.append(Recell(delta))
            log.append(Resize(rng.integers(0, alive, size=8), delta))
    return log


@pytest.mark.parametrize("seed", range(4))
def test_a_mirror_of_a_mixed_coverage_names_the_same_witnesses(seed):
    rng = np.random.default_rng(seed)
    coordinator = Coverage(2, 2.0, LOWER, bounds=(LOWER, UPPER), mixed=True)
    coordinator.start_log()
    mirror = Coverage(2, 2.0, LOWER, bounds=(LOWER, UPPER), mixed=True)
    for version, change in enumerate(_changes(rng, 60), start=1):
        coordinator.apply(change, version)
        if rng.random() < 0.3:
            mirror.sync(coordinator.changes_since(mirror.seq))
    mirror.sync(coordinator.changes_since(mirror.seq))
    q = _queries(rng)
    assert mirror.seq == coordinator.seq
    assert np.array_equal(mirror.vertices.cover(q), coordinator.vertices.cover(q))
    assert np.array_equal(mirror.classify_states(q)[1], coordinator.classify_states(q)[1])
    restored = Coverage.from_state(coordinator.state())
    assert np.array_equal(restored.vertices.cover(q), coordinator.vertices.cover(q))
    assert np.array_equal(coordinator.vertices.cover(q) >= 0, _brute(coordinator.vertices, q))


def test_a_plain_coverage_refuses_boxes_of_another_size():
    cov = Coverage(2, 1.0, LOWER, bounds=(LOWER, UPPER))
    with pytest.raises(ValueError, match="mixed"):
        cov.apply(Insert(np.ones((1, 2)), 0.5), 1)


def test_band_rounds_keep_interior_boxes_and_split_what_a_pruning_reaches():
    sc = make_scenario("lead-follow", "idm")
    band = SPE(sc, SPESettings(delta0=2.0, delta_min=0.5, refine="band"))
    full = SPE(sc, SPESettings(delta0=2.0, delta_min=0.5, refine="all"))
    for algo in (band, full):
        algo.end_round()
    widths = band.coverage.half_widths(band.vertices.alive_ids())
    assert set(np.unique(widths)) == {1.0, 2.0}
    assert band.vertices.alive_count < full.vertices.alive_count / 2
    # the band's boxes (and only they) were split: the union is the same volume
    assert band.result().volume_union() == pytest.approx(full.result().volume_union())
    # the near boxes are the ones within sigma-bar + delta of a failure facet
    coarse = band.vertices.alive_ids()[widths == 2.0]
    assert not band.band.near(band, coarse, 2.0).any()
    # a pruning that reaches a coarse box splits it: its children at delta = 1 replace
    # it, but for the one within delta of the failure (here in its upper corner)
    victim = int(coarse[len(coarse) // 2])
    centre = band.vertices.points[victim].copy()
    before = band.vertices.count
    band.coverage.apply(AddFailures(centre[None, :] + 1.5), band.version + 1)
    band._prune(np.array([victim]))
    assert not band.vertices.alive[victim]
    children = band.vertices.points[before : band.vertices.count]
    assert len(children) == 2 ** sc.n - 1
    assert (np.abs(children - centre).max(axis=1) == 1.0).all()
    assert not (children > centre).all(axis=1).any()
    assert (band.coverage.half_widths(np.arange(before, band.vertices.count)) == 1.0).all()
    # the band now reaches the split region: its pruned centre is a hole
    assert band.band.near(band, np.arange(before, band.vertices.count), 1.0).all()
