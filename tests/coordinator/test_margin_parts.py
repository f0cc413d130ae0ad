"""Margin refinement's parts on their own: the partition, the box index, the split rule's
neighbourhoods, the invariance fixpoint, runs' margins, sets with a half-width per axis."""

import numpy as np
import pytest

from coordinator.box_index import BoxIndex
from coordinator.margin.cut_rule import CUT_MIN_SHARE, CUT_SHIFT, cuts
from coordinator.margin.invariance import largest_invariant
from coordinator.margin.partition import Partition
from coordinator.margin.split_rule import Neighbourhood
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
def test_the_leaves_tile_sigma_and_locate_finds_the_leaf_holding_a_point(seed, monkeypatch):
    p, rng = _refined(seed)
    leaves = p.leaves()
    assert np.isclose(np.prod(p.hi[leaves] - p.lo[leaves], axis=1).sum(), 20 * 20 * 70)
    x = rng.uniform([0, 0, 0], [20, 20, 70], (50_000, 3))
    box = p.locate(x)
    assert p.is_leaf(box).all()
    assert ((x >= p.lo[box]) & (x <= p.hi[box])).all()
    # in blocks (certification locates tens of millions of states): the same leaves
    monkeypatch.setattr("coordinator.margin.partition.LOCATE_BLOCK", 7_000)
    assert np.array_equal(p.locate(x), box)


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


def test_the_box_index_says_which_points_heavily_overlapping_boxes_hold_as_brute_force_does():
    # a covering widened past its boxes: most points lie in dozens of boxes, on shared faces too
    rng = np.random.default_rng(5)
    centres = rng.integers(0, 12, (3000, 5)) * 0.5
    lo, hi = centres - 1.25, centres + 1.25
    q = np.concatenate([rng.uniform(-2, 8, (4000, 5)), rng.integers(-4, 16, (1000, 5)) * 0.5 + 0.75])
    inside = ((q[:, None, :] >= lo[None] - 1e-9) & (q[:, None, :] <= hi[None] + 1e-9)).all(axis=2)
    index = BoxIndex(lo, hi)
    assert 0.1 < inside.any(axis=1).mean() < 0.9
    assert np.array_equal(index.contains(q), inside.any(axis=1))
    assert np.array_equal(index.locate(q) >= 0, inside.any(axis=1))


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


def _linear_hood(centres, h, g, b):
    """Boxes of half-width h at ``centres`` among face neighbours of their own size, the
    margin ``g . x + b`` (safe where positive)."""
    B, n = centres.shape
    margin = lambda x: x @ g + b  # noqa: E731
    at = np.stack([centres - 2 * h, centres + 2 * h], axis=-1)  # (B, n, 2) along each axis
    margins = np.zeros((B, n, 2))
    for axis in range(n):
        for side in range(2):
            x = centres.copy()
            x[:, axis] = at[:, axis, side]
            margins[:, axis, side] = margin(x)
    m = margin(centres)
    return Neighbourhood(centres, np.broadcast_to(h, (B, n)).copy(), m, m > 0, np.ones((B, n, 2), dtype=bool), at,
                         margins, margins > 0)


def test_a_cut_lands_on_the_margins_zero_crossing_moved_to_the_safe_side():
    g, h = np.array([0.2, -1.0, 0.1]), np.array([0.25, 0.25, 0.25])
    centres = np.array([[1.0, 1.1, 1.0],  # m = 0.2 - 1.1 + 0.1 + 0.9 = 0.1: safe, unclaimed, crossed
                        [1.0, 0.8, 1.0],  # m = 0.4: claimed (0.4 > KAPPA R = 0.1875): not cut
                        [1.0, 1.3, 1.0],  # m = -0.1: failing, crossed
                        [1.0, 2.0, 1.0]])  # m = -0.8: failing beyond the change across it: not cut
    hood = _linear_hood(centres, h, g, 0.9)
    cut, axis, at = cuts(hood, centres - h, centres + h)
    assert cut.tolist() == [True, False, True, False] and (axis[cut] == 1).all()
    other = abs(g[0]) * h[0] + abs(g[2]) * h[2]
    crossing = 1.2  # g . x + 0.9 = 0 at the centres' other coordinates
    # the safe side is where the margin grows: lower v1 here
    assert np.allclose(at[cut, 1], crossing - CUT_SHIFT * other / abs(g[1]))
    assert np.allclose(at[cut][:, [0, 2]], centres[cut][:, [0, 2]])
    # a crossing within CUT_MIN_SHARE of a face is not cut: the box is all but on one side
    near_face = np.array([[1.0, 1.2 + h[1] * (1 - CUT_MIN_SHARE) - 0.02, 1.0]])  # the cut 0.02 past its lower face
    cut, _, _ = cuts(_linear_hood(near_face, h, g, 0.9), near_face - h, near_face + h)
    assert not cut.any()
