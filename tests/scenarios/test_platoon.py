"""The platoon family (shared/spec/scenarios.md, section platoon): k = 3 is fleet3 bit for
bit; k = 4, 5 checked against the spec's formulas by hand."""

import math

import numpy as np
import pytest

from scenarios.base import CONTINUE, FAILURE, TRUNCATED
from scenarios.errors import ConfigError
from scenarios.fleet3 import Fleet3
from scenarios.platoon import Platoon
from scenarios.registry import make_backend

DT = 0.1  # [s]


def spec_idm(v, v_ahead, s, a, b, T, lo, hi, v_des=30.0, s0=2.0):
    """The IDM of the spec, for one car in plain floats."""
    if s <= 0:
        return lo
    s_star = s0 + max(0.0, v * T + v * (v - v_ahead) / (2 * math.sqrt(a * b)))
    return min(max(a * (1 - (v / v_des) ** 4 - (s_star / s) ** 2), lo), hi)


def traffic(v, v_ahead, s):
    return spec_idm(v, v_ahead, s, 1.0, 2.0, 1.0, -6.0, 1.0)


def travel(v, a):
    """[m] distance over one step with constant a, stopping inside the step if need be."""
    return v * DT + a * DT**2 / 2 if v + a * DT >= 0 else v * v / (2 * abs(a))


@pytest.mark.parametrize("policy", ["idm", "brake"])
@pytest.mark.parametrize("disturbance", [0.0, 0.4])
def test_three_vehicles_are_fleet3_bit_for_bit(policy, disturbance):
    fleet3 = Fleet3(sv_policy=policy, disturbance=disturbance)
    platoon = Platoon(sv_policy=policy, disturbance=disturbance, vehicles=3)
    assert platoon.state_names == fleet3.state_names and platoon.noise_width == fleet3.noise_width
    assert np.array_equal(platoon.lower, fleet3.lower) and np.array_equal(platoon.upper, fleet3.upper)
    rng = np.random.default_rng(11)
    states = rng.uniform(fleet3.lower - 1.0, fleet3.upper + 1.0, (50_000, 5))
    actions = rng.uniform(fleet3.action_lower, fleet3.action_upper, (50_000, 2))
    noise = rng.random((50_000, 3)) if disturbance else None
    for _ in range(5):  # a few steps: the states move off the sampled ones
        nxt = platoon.step(states, actions, noise)
        np.testing.assert_array_equal(nxt, fleet3.step(states, actions, noise))
        states = nxt
    points = rng.uniform(fleet3.lower, fleet3.upper, (5000, 5))
    if not disturbance:
        np.testing.assert_array_equal(platoon.reference_safe(points), fleet3.reference_safe(points))


def test_four_vehicles_one_step_by_hand():
    """k = 4, r = 1: lead 1 drives the traffic IDM behind lead 2 (the front lead)."""
    sc = Platoon(sv_policy="brake", vehicles=4)
    assert sc.state_names == ("v0", "v1", "v2", "v3", "p10", "p21", "p30")
    v0, v1, v2, v3, p10, p21, p30 = 4.0, 3.0, 5.0, 2.0, 12.0, 15.0, -10.0
    u_lead, u_rear = 1.0, -4.0
    nxt = sc.step(np.array([[v0, v1, v2, v3, p10, p21, p30]]), np.array([[u_lead, u_rear]]), None)[0]
    a1 = traffic(v1, v2, p21 - 5.0)
    assert a1 == pytest.approx(1 - 1e-4 - ((2 + 3 - 6 / (2 * math.sqrt(2))) / 10) ** 2)  # 0.917 [m/s^2]
    x0, x1, x2, x3 = travel(v0, -10.0), travel(v1, a1), travel(v2, u_lead), travel(v3, u_rear)
    expected = [v0 - 1.0, v1 + a1 * DT, v2 + u_lead * DT, v3 + u_rear * DT,
                p10 + x1 - x0, p21 + x2 - x1, p30 + x3 - x0]
    assert nxt.tolist() == pytest.approx(expected, abs=1e-12)


def test_five_vehicles_middle_follower_by_hand():
    """k = 5, r = 2: follower 1 (car 3) drives the traffic IDM behind the SV; the rear
    follower (car 4) is the scenario's; lead 1 is a traffic car behind the front lead."""
    sc = Platoon(sv_policy="idm", vehicles=5, followers=2)
    assert sc.state_names == ("v0", "v1", "v2", "v3", "v4", "p10", "p21", "p30", "p43")
    assert sc.failure_facets == ("p10", "p30") and sc.sides == {"lead": ("p10",), "rear": ("p30",)}
    state = [2.0, 5.0, 1.0, 4.0, 3.0, 20.0, 5.0, -9.0, -8.0]  # p21 = 5: lead 1 touches the front lead
    v0, v1, v2, v3, v4, p10, p21, p30, p43 = state
    u_lead, u_rear = -5.0, -7.0
    nxt = sc.step(np.array([state]), np.array([[u_lead, u_rear]]), None)[0]
    a0 = spec_idm(v0, v1, p10 - 5.0, 0.73, 1.67, 1.5, -4.67, 0.73)
    a1 = traffic(v1, v2, p21 - 5.0)  # bumper gap 0: full braking
    a3 = traffic(v3, v0, -p30 - 5.0)  # 4 m behind a slower SV
    assert a1 == -6.0 and -6.0 < a3 < 0.0
    x = [travel(v0, a0), travel(v1, a1), travel(v2, u_lead), travel(v3, a3), travel(v4, u_rear)]
    expected = [v0 + a0 * DT, v1 + a1 * DT, max(v2 + u_lead * DT, 0.0), v3 + a3 * DT, v4 + u_rear * DT,
                p10 + x[1] - x[0], p21 + x[2] - x[1], p30 + x[3] - x[0], p43 + x[4] - x[3]]
    assert nxt.tolist() == pytest.approx(expected, abs=1e-12)


def test_five_vehicles_facets():
    sc = Platoon(sv_policy="idm", vehicles=5)  # r = 1: cars 1, 2 traffic, 3 the front lead, 4 the rear
    names = sc.state_names
    assert names == ("v0", "v1", "v2", "v3", "v4", "p10", "p21", "p32", "p40")
    inside = np.array([3.0, 3.0, 3.0, 3.0, 3.0, 10.0, 10.0, 10.0, -10.0])

    def moved(**change):
        s = inside.copy()
        for name, value in change.items():
            s[names.index(name)] = value
        return s

    states = np.array([inside, moved(p10=4.9), moved(p40=-4.9), moved(p21=4.9), moved(p32=4.9), moved(v2=6.1),
                       moved(p32=25.1), moved(p40=-25.1), moved(p10=5.0), moved(p40=-5.0 + 5e-10),
                       moved(p21=4.0, p10=4.0)])
    assert sc.classify(states).tolist() == [CONTINUE, FAILURE, FAILURE, TRUNCATED, TRUNCATED, TRUNCATED,
                                            TRUNCATED, TRUNCATED, CONTINUE, CONTINUE, FAILURE]
    lead_side = Platoon(sv_policy="idm", vehicles=5, failure_facets=["p10"])
    assert lead_side.classify(states[[1, 2]]).tolist() == [FAILURE, TRUNCATED]  # the rear facet truncates


@pytest.mark.parametrize("vehicles, followers", [(4, 1), (4, 2), (5, 1), (5, 3)])
@pytest.mark.parametrize("policy", ["idm", "brake"])
def test_reference_safe_set_is_not_trivial(vehicles, followers, policy):
    sc = Platoon(sv_policy=policy, vehicles=vehicles, followers=followers)
    points = np.random.default_rng(3).uniform(sc.lower, sc.upper, (4000, sc.n))
    safe = sc.reference_safe(points)
    assert 0.5 < safe.mean() < 0.999
    standing = (sc.lower + sc.upper) / 2
    standing[: sc.vehicles] = 0.0  # everybody stands, mid-range gaps: nothing can happen
    rushing = standing.copy()
    rushing[0] = 6.0  # [m/s] the SV, 0.5 m behind a standing lead 1: no policy stops in time
    rushing[sc.state_names.index("p10")] = 5.5
    assert sc.reference_safe(np.array([standing, rushing])).tolist() == [True, False]


def test_vehicle_layout_round_trip():
    sc = Platoon(vehicles=5, followers=2)
    states = np.random.default_rng(0).uniform(sc.lower, sc.upper, (100, sc.n))
    fronts, speeds = sc.to_vehicles(states)
    assert np.all(fronts[:, 2] > fronts[:, 1]) and np.all(fronts[:, 1] > 0) and np.all(fronts[:, 4] < fronts[:, 3])
    np.testing.assert_allclose(sc.from_vehicles(fronts, speeds), states, atol=1e-12)


def test_step_bounds_per_axis():
    sc = Platoon(vehicles=4, disturbance=0.5)
    a_max = 10.0 + 0.5  # [m/s^2] the brake SV's, plus w
    assert sc.step_bounds().tolist() == pytest.approx([a_max * DT] * 4 + [6.0 * DT + a_max * DT**2 / 2] * 3)
    assert sc.step_bound() == pytest.approx(a_max * DT)


def test_options_are_checked_in_one_line():
    with pytest.raises(ConfigError, match=r"^scenario\.vehicles: 2 is out of range; allowed \[3, 8\]$"):
        Platoon(vehicles=2)
    with pytest.raises(ConfigError, match=r"^scenario\.followers: 3 is out of range; allowed \[1, 2\] with 4 "):
        Platoon(vehicles=4, followers=3)
    with pytest.raises(ConfigError, match=r"^scenario\.vehicles: scenario 'lead-follow' takes no option "):
        make_backend({"name": "lead-follow", "vehicles": 4})
    backend = make_backend({"name": "platoon", "vehicles": 5, "followers": 2, "sv_policy": "brake"})
    assert backend.scenario.n == 9 and backend.scenario.sv_policy_name == "brake"
