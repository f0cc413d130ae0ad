"""Margin refinement's parts on their own: the partition, the box index, the split rule's
neighbourhoods, the invariance fixpoint, runs' margins, sets with a half-width per axis."""

import numpy as np
import pytest

from coordinator.box_index import BoxIndex
from coordinator.margin.invariance import largest_invariant
from coordinator.margin.partition import Partition
from coordinator.safe_set import SafeSet
from scenarios.base import FAILURE
from scenarios.simulator import SimSpec, Simulator


def _refined(seed=0, rounds=4, n=3):
    rng = np.random.default_rng(seed)
    p = Partition(np.zeros(n), np.array([20.0, 20.0, 70.0][:n] + [10.0] * max(0, n - 3)), 2.0)
    for _ in range(rounds):
        leaves = p.leaves()
        pick = rng.choice(leaves, size=min(200, len(leaves)), replace=False)
        masks = rng.integers(1, 1 << n, len(pick))
        planes = p.lo[pick] + rng.uniform(0.2, 0.8, (len(pick), n)) * (p.hi[pick] - p.lo[pick])
        p.split(pick, masks, planes if seed % 2 else None)
    return p, rng


@pytest.mark.parametrize("seed", [0, 1])
def test_the_leaves_tile_sigma_and_locate_finds_the_leaf_holding_a_point(seed):
    p, rng = _refined(seed)
    leaves = p.leaves()
    assert np.isclose(np.prod(p.hi[leaves] - p.lo[leaves], axis=1).sum(), 20 * 20 * 70)
    x = rng.uniform([0, 0, 0], [20, 20, 70], (50_000, 3))
    box = p.locate(x)
    assert p.is_leaf(box).all()
    assert ((x >= p.lo[box]) & (x <= p.hi[box])).all()


def test_a_neighbour_shares_the_face_it_was_looked_for_across():
    p, _ = _refined(2)
    leaves = p.leaves()
    for axis in range(3):
        up = p.neighbours(leaves, axis, +1)
        ok = up >= 0
        assert np.allclose(p.lo[up[ok], axis], p.hi[leaves[ok], axis])
        assert (~ok == np.isclose(p.hi[leaves, axis], [20.0, 20.0, 70.0][axis])).all()


def test_the_box_index_finds_the_lowest_box_holding_a_point_as_brute_force_does():
    rng = np.random.default_rng(3)
    lo = rng.uniform(0, 10, (2000, 4))
    hi = lo + rng.uniform(0.1, 3, (2000, 4))
    q = rng.uniform(0, 13, (5000, 4))
    inside = ((q[:, None, :] >= lo[None] - 1e-9) & (q[:, None, :] <= hi[None] + 1e-9)).all(axis=2)
    expected = np.where(inside.any(axis=1), inside.argmax(axis=1), -1)
    assert np.array_equal(BoxIndex(lo, hi).locate(q), expected)


def test_the_fixpoint_drops_runs_that_leave_the_covering_and_those_that_lead_there():
    # boxes on a line: 0 [0,1], 1 [1,2], 2 [2,3] (failed), 3 [3,4]; run 0 visits box 1,
    # run 1 visits box 2 (failed: outside), run 3 stays home
    lo, hi = np.array([[0.0], [1.0], [2.0], [3.0]]), np.array([[1.0], [2.0], [3.0], [4.0]])
    locate = lambda x: np.clip(np.floor(x[:, 0]).astype(np.int64), 0, 3)  # noqa: E731
    candidates = np.array([0, 1, 3])
    states = np.array([[1.5], [2.7], [3.5]])
    offsets = np.array([0, 1, 2, 3])
    kept, rounds = largest_invariant(candidates, states, offsets, locate, 4, 0.1, lo[0], hi[-1])
    assert kept.tolist() == [False, False, True] and rounds == 2
    # a covering of 0.5 reaches box 3 from 2.7 (along the axis): every run stays
    kept, rounds = largest_invariant(candidates, states, offsets, locate, 4, 0.5, lo[0], hi[-1])
    assert kept.all() and rounds == 0


def test_a_runs_margin_is_negative_exactly_when_it_fails_and_deep_goes_deeper():
    x = np.random.default_rng(4).uniform([0, 0, 0], [20, 20, 70], (5000, 3))
    shallow = Simulator(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "adversarial"}, 50, 0))
    deep = Simulator(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "adversarial"}, 50, 0,
                             deep_margins=True))
    a, b = shallow.simulate(0, x), deep.simulate(0, x)
    failed = a.outcomes == FAILURE
    assert ((a.margins < 0) == failed).all() and ((b.margins < 0) == failed).all()
    assert (b.margins[failed] <= a.margins[failed]).all() and (b.margins[failed] < a.margins[failed]).any()
    assert np.array_equal(a.margins[~failed], b.margins[~failed])
    assert np.allclose(a.margins[~failed], [min(r[:, 2]) for r in (a.trajectory(i) for i in np.flatnonzero(~failed))])


def test_a_set_with_a_half_width_per_axis_round_trips_through_parquet(tmp_path):
    p, rng = _refined(5)
    leaves = p.leaves()[:500]
    s = SafeSet(p.centres(leaves), p.half_widths(leaves), ("v0", "v1", "p10"), {"covering_margin": "0.5"},
                disjoint=True)
    assert s.anisotropic
    s.to_parquet(tmp_path / "s.parquet")
    back = SafeSet.from_parquet(tmp_path / "s.parquet", ("v0", "v1", "p10"))
    assert back.anisotropic and back.disjoint and back.result_hash == s.result_hash
    assert back.metadata["covering_margin"] == "0.5"
    assert np.array_equal(back.axis_half_widths, s.axis_half_widths)
    x = rng.uniform([0, 0, 0], [20, 20, 70], (20_000, 3))
    inside = ((x[:, None] >= s.lower[None] - 1e-9) & (x[:, None] <= s.upper[None] + 1e-9)).all(2).any(1)
    assert np.array_equal(s.contains(x), inside)
    assert np.isclose(s.volume_union(), np.prod(2 * s.axis_half_widths, axis=1).sum())


def test_a_set_of_one_half_width_per_box_reads_back_with_its_old_hash(tmp_path):
    s = SafeSet(np.array([[1.0, 1.0, 1.0], [3.0, 1.0, 1.0]]), np.array([1.0, 0.5]), ("v0", "v1", "p10"))
    s.to_parquet(tmp_path / "s.parquet")
    back = SafeSet.from_parquet(tmp_path / "s.parquet", ("v0", "v1", "p10"))
    assert not back.anisotropic and back.result_hash == s.result_hash


def test_estimated_volumes_bracket_the_exact_ones():
    rng = np.random.default_rng(6)
    c = rng.uniform(2, 18, (300, 3))
    s = SafeSet(c, rng.uniform(0.5, 2, (300, 3)), ("a", "b", "c"))
    from coordinator.volume import corner_hull_volume
    from coordinator.volume_estimate import hull_volume_estimate, union_volume_estimate

    exact_hull = corner_hull_volume(s.lower, s.upper)
    hull = hull_volume_estimate(s.lower, s.upper, seed=1, samples=200_000)
    assert hull.high >= exact_hull and hull.value <= 1.05 * exact_hull  # an outer estimate, close
    union = union_volume_estimate(s.contains, s.lower, s.upper, seed=2, samples=200_000)
    x = rng.uniform(s.lower.min(0), s.upper.max(0), (400_000, 3))
    brute = s.contains(x).mean() * np.prod(s.upper.max(0) - s.lower.min(0))
    assert union.low * 0.99 <= brute <= union.high * 1.01
