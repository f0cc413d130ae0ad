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
