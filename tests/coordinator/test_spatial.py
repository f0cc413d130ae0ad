import numpy as np
import pytest
from scipy.spatial import cKDTree

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
    idx.recell(0.6)
    dist2 = dist <= 0.3 + 1e-9
    np.testing.assert_array_equal(idx.any_within(q, 0.3), dist2)


def test_state_round_trip():
    idx = PointIndex(2, 1.0, np.zeros(2))
    idx.insert(np.array([[0.5, 0.5], [3.0, 3.0]]))
    idx.kill([0])
    back = PointIndex.from_state(idx.state())
    assert back.any_within(np.array([[0.5, 0.5], [3.2, 3.2]]), 0.5).tolist() == [False, True]
