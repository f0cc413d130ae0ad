import numpy as np
import pytest

from scenarios.kinematics import advance
from scenarios.policies import idm, brake
from scenarios.lead_follow import LeadFollow
from scenarios.fleet3 import Fleet3


def test_constant_acceleration_step():
    v, x = advance(np.array([10.0]), np.array([2.0]), 0.1)
    assert v[0] == pytest.approx(10.2)
    assert x[0] == pytest.approx(10.0 * 0.1 + 0.5 * 2.0 * 0.01)


def test_vehicle_stops_inside_the_step_and_never_reverses():
    v, x = advance(np.array([0.5, 0.0]), np.array([-10.0, -5.0]), 0.1)
    assert v.tolist() == [0.0, 0.0]
    assert x[0] == pytest.approx(0.5**2 / (2 * 10.0))  # v^2 / (2|a|), not v dt + a dt^2 / 2
    assert x[1] == 0.0


def test_lead_follow_gap_changes_by_difference_of_distances():
    sc = LeadFollow(sv_policy="brake")
    s = np.array([[10.0, 5.0, 20.0]])
    nxt = sc.step(s, np.array([[3.0]]), None)
    x0 = 10.0 * 0.1 - 0.5 * 10.0 * 0.01
    x1 = 5.0 * 0.1 + 0.5 * 3.0 * 0.01
    assert nxt[0].tolist() == pytest.approx([9.0, 5.3, 20.0 + x1 - x0])


def test_idm_formula_and_clipping():
    v0, v1, s = np.array([10.0]), np.array([8.0]), np.array([30.0])
    s_star = 2.0 + max(0.0, 10.0 * 1.5 + 10.0 * 2.0 / (2 * np.sqrt(0.73 * 1.67)))
    expected = 0.73 * (1 - (10 / 30) ** 4 - (s_star / 30.0) ** 2)
    assert idm(v0, v1, s)[0] == pytest.approx(expected)
    # a tiny gap would ask for a huge deceleration: clipped at -4.67; s <= 0 brakes fully
    assert idm(np.array([20.0, 5.0]), np.array([0.0, 5.0]), np.array([0.5, 0.0])).tolist() == [-4.67, -4.67]
    # free road, standing SV: clipped at +0.73 at most
    assert idm(np.array([0.0]), np.array([20.0]), np.array([1e6]))[0] == pytest.approx(0.73)
    assert brake(v0, v1, s)[0] == -10.0


def test_fleet3_uses_bumper_gap_and_moves_follower():
    sc = Fleet3(sv_policy="idm")
    s = np.array([[5.0, 5.0, 5.0, 15.0, -15.0]])
    nxt = sc.step(s, np.array([[0.0, -3.0]]), None)
    a0 = idm(np.array([5.0]), np.array([5.0]), np.array([10.0]))[0]  # bumper gap 15 - 5
    x0 = 5.0 * 0.1 + 0.5 * a0 * 0.01
    assert nxt[0, 0] == pytest.approx(5.0 + a0 * 0.1)
    assert nxt[0, 4] == pytest.approx(-15.0 + (5.0 * 0.1 - 0.5 * 3.0 * 0.01) - x0)


def test_disturbance_is_bounded_and_drawn_per_vehicle():
    sc = LeadFollow(sv_policy="brake", disturbance=0.5)
    s = np.tile([[10.0, 10.0, 30.0]], (1000, 1))
    noise = np.random.default_rng(0).random((1000, 2))
    nxt = sc.step(s, np.full((1000, 1), 0.0), noise)
    dv0 = (nxt[:, 0] - 10.0) / 0.1
    dv1 = (nxt[:, 1] - 10.0) / 0.1
    assert dv0.min() >= -10.5 - 1e-9 and dv0.max() <= -9.5 + 1e-9
    assert dv1.min() >= -0.5 - 1e-9 and dv1.max() <= 0.5 + 1e-9
    assert abs(np.corrcoef(dv0, dv1)[0, 1]) < 0.1


def _spec_advance(v, a, dt):
    """The spec's two cases, row by row in plain Python floats."""
    out_v, out_x = [], []
    for vi, ai in zip(v.tolist(), a.tolist()):
        if vi + ai * dt >= 0:
            out_v.append(vi + ai * dt)
            out_x.append((vi + (vi + ai * dt)) * (0.5 * dt))
        else:
            out_v.append(0.0)
            out_x.append(vi * vi / (2.0 * abs(ai)))
    return np.array(out_v), np.array(out_x)


def test_branch_free_step_is_the_spec_formula_bit_for_bit():
    rng = np.random.default_rng(5)
    v = np.concatenate([rng.random(20000) * 20, np.zeros(6), [0.5, 0.5, 1.0, 2.0, 1e-300, 3.0]])
    a = np.concatenate([rng.random(20000) * 8 - 5, [0.0, -0.0, 3.0, -5.0, -10.0, 1e-300],
                        [-5.0, -4.999999999, -10.0, -20.0, -5.0, 0.0]])  # stop boundary v = -a dt
    speed, dist = advance(v, a, 0.1)
    ref_speed, ref_dist = _spec_advance(v, a, 0.1)
    np.testing.assert_array_equal(speed, ref_speed)
    np.testing.assert_array_equal(dist, ref_dist)
    # a row's result does not depend on its batch-mates (all stopping or none)
    alone = advance(v[:1], a[:1], 0.1)
    assert alone[0][0] == speed[0] and alone[1][0] == dist[0]


def test_idm_contact_is_exactly_full_braking_without_dividing_by_zero():
    gaps = np.array([0.0, -0.0, -3.0, 5e-324, 1e-310, 1e-300, 1e-3])
    with np.errstate(all="raise"):  # no division by zero, no invalid operation escapes
        accel = idm(np.full(7, 20.0), np.zeros(7), gaps)
    assert accel.tolist() == [-4.67] * 7
