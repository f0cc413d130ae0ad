import numpy as np
import pytest


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
