"""Failure distances for prioritized sampling: incremental and bucketed, yet the very
values of the brute-force minimum (they feed a hashed result)."""

import numpy as np
import pytest

from coordinator.priorities import FailureDistances


def brute(points, failures):
    return np.abs(points[:, None, :] - failures[None, :, :]).max(axis=2).min(axis=1)


@pytest.mark.parametrize("cap", [np.inf, 1.5, 4.0])
@pytest.mark.parametrize("n", [2, 3, 5, 7])
def test_distances_equal_the_brute_force_minimum_bit_for_bit_through_interleaved_appends(n, cap):
    """Capped (the closing edge's holes: only "within a radius under the cap" is asked),
    the distances are min(d, cap), the brute force's below the cap bit for bit."""
    rng = np.random.default_rng(n)
    lower, upper = np.zeros(n), np.full(n, 10.0)
    points = np.empty((0, n))
    failures = np.empty((0, n))
    fd = FailureDistances(lower, upper, cap=cap)
    for step in range(60):
        if rng.random() < 0.6:  # vertices come in bulk, some on a lattice, some repeated
            new = rng.uniform(-1, 11, (int(rng.integers(1, 400)), n))
            if step % 5 == 0:
                new = np.round(new * 2) / 2
            points = np.concatenate([points, new, points[: int(rng.integers(0, 5))]])
        if rng.random() < 0.5:  # failures one by one or a few at once
            new = rng.uniform(0, 10, (int(rng.integers(1, 40)) if step % 7 == 0 else 1, n))
            failures = np.concatenate([failures, new])
        got = fd.update(points, len(points), failures, len(failures))
        if len(failures) == 0:
            assert np.isinf(got).all()
            continue
        assert np.array_equal(got[: len(points)], np.minimum(brute(points, failures), cap))


def test_take_lowered_names_exactly_the_ids_whose_distance_fell():
    rng = np.random.default_rng(11)
    points = rng.uniform(0, 10, (5000, 2))
    fd = FailureDistances(np.zeros(2), np.full(2, 10.0), track_lowered=True)
    fd.update(points, len(points), rng.uniform(0, 10, (1, 2)), 1)
    fd.take_lowered()
    failures = rng.uniform(0, 10, (6, 2))
    for k in range(2, 7):
        before = fd.dist.copy()
        after = fd.update(points, len(points), failures, k)
        fell = np.flatnonzero(after < before)
        assert len(fell) > 0
        assert np.array_equal(np.unique(fd.take_lowered()), fell)
    assert len(fd.take_lowered()) == 0


def test_a_copy_keeps_lowering_its_own_distances():
    # a copy of the algorithm (coordinator/driver/speculation.py) is restored and goes on: its
    # distances must go on falling in its own buffer (a view held apart from its buffer
    # would part from it in a deep copy and lose what a new failure lowers)
    import copy

    rng = np.random.default_rng(7)
    points = rng.uniform(0, 10, (500, 3))
    failures = rng.uniform(0, 10, (5, 3))
    fd = FailureDistances(np.zeros(3), np.full(3, 10.0))
    fd.update(points, 300, failures, 3)
    fd.update(points, 310, failures, 3)  # the buffer grows by doubling: room for the next ones
    twin = copy.deepcopy(fd)
    got = twin.update(points, 400, failures, 5)  # a failure lowers, then vertices are appended
    got = twin.update(points, 500, failures, 5)
    assert np.array_equal(got, brute(points, failures))


@pytest.mark.parametrize("n", [3, 7, 9])
def test_a_capped_failure_group_looks_at_exactly_the_buckets_a_full_scan_finds(n):
    """With a cap, the buckets a failure group may reach are listed from the grid cells
    around it (not tested one by one): the same buckets, in the same order, as testing
    every bucket's box, and the distances stay the brute force's."""
    rng = np.random.default_rng(n)
    lower, upper = np.zeros(n), np.full(n, 10.0)
    points = np.concatenate([rng.uniform(-0.5, 10.5, (30_000, n)), np.round(rng.uniform(0, 10, (2_000, n)))])
    cap = 1.0
    fd = FailureDistances(lower, upper, cap=cap)
    failures = rng.uniform(0, 10, (1, n))
    fd.update(points, len(points), failures, 1)
    assert fd._sorted == len(points)
    listed = 0
    for k in (1, 1, 2, 5, 64):
        fs = rng.uniform(0, 10, (k, n))
        if k == 2:  # the group's reach ends on a cell's face: floor's edge
            fs[:, 0] = 2 * fd._side[0] + cap
        lo, hi = fs.min(axis=0) - cap, fs.max(axis=0) + cap
        full = np.flatnonzero(((fd._box_hi >= lo) & (fd._box_lo <= hi)).all(axis=1))
        listed += fd._listed_cells(lo, hi) is not None
        assert np.array_equal(fd._near_buckets(fs), full)
        failures = np.concatenate([failures, fs])
        got = fd.update(points, len(points), failures, len(failures))
        assert np.array_equal(got, np.minimum(brute(points, failures), cap))
    assert listed >= 2  # the listing was taken, not only the full scan


def test_bucket_numbers_stay_within_int64_for_many_axes():
    """No cost exponential in the dimension: 24 axes bucket their first 20, and a
    bucket's box still spans every axis (the distances are the brute force's)."""
    n = 24
    rng = np.random.default_rng(5)
    points = rng.uniform(0, 1, (5_000, n))
    failures = rng.uniform(0, 1, (3, n))
    fd = FailureDistances(np.zeros(n), np.ones(n), cap=0.6)
    fd.update(points, len(points), failures[:1], 1)
    assert fd.bucket_axes == 20 and fd._sorted == len(points)
    got = fd.update(points, len(points), failures, 3)
    assert np.array_equal(got, np.minimum(brute(points, failures), 0.6))


def test_new_vertices_past_the_cap_get_the_cap_from_a_bounded_tree_search():
    """Many new vertices at once ask a KD-tree that searches no farther than the cap:
    on a lattice, distances equal to the cap are kept exactly, those beyond become the
    cap (the brute force's min(d, cap))."""
    n, cap = 4, 1.0
    rng = np.random.default_rng(3)
    points = np.concatenate([0.5 * rng.integers(0, 20, (60_000, n)), rng.uniform(0, 10, (20_000, n))])
    failures = np.concatenate([0.5 * rng.integers(0, 20, (3, n)), rng.uniform(0, 10, (2, n))])
    fd = FailureDistances(np.zeros(n), np.full(n, 10.0), cap=cap)
    got = fd.update(points, len(points), failures, len(failures))
    want = np.minimum(brute(points, failures), cap)
    assert np.array_equal(got, want)
    assert (brute(points, failures) == cap).sum() > 100 and (want < cap).sum() > 100


def test_the_kept_tree_and_the_failures_after_it_give_the_brute_force_values_in_a_copy_too():
    """New vertices ask a KD-tree of the failures kept from call to call, plus the
    failures added since by brute force; a copy (a speculation's) builds its own."""
    import copy

    n = 3
    rng = np.random.default_rng(9)
    points = rng.uniform(0, 10, (40_000, n))
    failures = rng.uniform(0, 10, (400, n))
    fd = FailureDistances(np.zeros(n), np.full(n, 10.0))
    count, failure_count = 1_000, 300
    fd.update(points, count, failures, failure_count)
    assert fd._tree is not None and fd._tree_count == 300
    for step in range(12):
        count += int(rng.integers(200, 400))
        failure_count += int(rng.integers(0, 6))
        if step == 6:
            fd = copy.deepcopy(fd)
            assert fd._tree is None
        got = fd.update(points, count, failures, failure_count)
        assert np.array_equal(got, brute(points[:count], failures[:failure_count]))
    assert fd._tree_count < failure_count  # the last calls used the tree and the failures after it


@pytest.mark.parametrize("n", [3, 9])
def test_kept_distances_read_back_go_on_as_the_brute_force_minimum(n):
    """A checkpoint keeps the capped distances (those below the cap and a bit per vertex):
    read back, they are the values kept, every id counts as lowered (as from infinity),
    and later vertices and failures bring them to the brute force's values."""
    cap = 2.5
    rng = np.random.default_rng(n)
    lower, upper = np.zeros(n), np.full(n, 10.0)
    points = rng.uniform(0, 10, (30_000, n))
    failures = rng.uniform(0, 10, (60, n))
    fd = FailureDistances(lower, upper, track_lowered=True, cap=cap)
    kept = fd.update(points, 20_003, failures, 40).copy()
    state = fd.state()
    assert 0 < len(state["values"]) < 20_003  # only those below the cap
    back = FailureDistances.from_state(lower, upper, state, track_lowered=True)
    assert np.array_equal(back.dist, kept)
    assert np.array_equal(back.take_lowered(), np.arange(20_003))
    got = back.update(points, len(points), failures, len(failures))
    assert np.array_equal(got, np.minimum(brute(points, failures), cap))
    assert 0 < back.take_lowered().size < 20_003


@pytest.mark.parametrize("damage", ["values short", "values at the cap", "bits short", "no failure"])
def test_kept_distances_that_do_not_fit_together_are_refused(damage):
    n, cap = 3, 2.5
    rng = np.random.default_rng(1)
    fd = FailureDistances(np.zeros(n), np.full(n, 10.0), cap=cap)
    fd.update(rng.uniform(0, 10, (500, n)), 500, rng.uniform(0, 10, (5, n)), 5)
    state = fd.state()
    if damage == "values short":
        state["values"] = state["values"][:-1]
    elif damage == "values at the cap":
        state["values"][0] = cap
    elif damage == "bits short":
        state["near"] = state["near"][:-2]
    else:
        state["seen"] = np.array([500, 0])
    with pytest.raises(ValueError, match="do not fit together"):
        FailureDistances.from_state(np.zeros(n), np.full(n, 10.0), state)
