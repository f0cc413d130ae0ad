"""Parameters of a domain as state axes with a zero step bound (scenarios/base.py
``parameter_names``), and their built-in example ``lead-follow-params``."""

import numpy as np
import pytest

from scenarios import testing
from scenarios.backend import NumpyBackend
from scenarios.base import Scenario
from scenarios.errors import ScenarioError
from scenarios.lead_follow import LeadFollow
from scenarios.lead_follow_params import LeadFollowParams

DT = 0.1  # [s]


def with_parameters(states, headway, friction):
    return np.column_stack([states, np.full(len(states), headway), np.full(len(states), friction)])


@pytest.mark.parametrize("policy", ["idm", "brake"])
@pytest.mark.parametrize("disturbance", [0.0, 0.3])
def test_nominal_parameters_are_lead_follow_bit_for_bit(policy, disturbance):
    plain = LeadFollow(sv_policy=policy, disturbance=disturbance)
    params = LeadFollowParams(sv_policy=policy, disturbance=disturbance)
    rng = np.random.default_rng(4)
    states = rng.uniform(plain.lower - 1.0, plain.upper + 1.0, (50_000, 3))
    actions = rng.uniform(-5.0, 3.0, (50_000, 1))
    noise = rng.random((50_000, 2)) if disturbance else None
    nxt = params.step(with_parameters(states, 1.5, 1.0), actions, noise)
    np.testing.assert_array_equal(nxt[:, :3], plain.step(states, actions, noise))
    assert (nxt[:, 3] == 1.5).all() and (nxt[:, 4] == 1.0).all()
    if not disturbance:
        points = rng.uniform(plain.lower, plain.upper, (20_000, 3))
        np.testing.assert_array_equal(params.reference_safe(with_parameters(points, 1.5, 1.0)),
                                      plain.reference_safe(points))


def test_friction_scales_every_braking_limit():
    mu = 0.5
    state = np.array([[10.0, 8.0, 1.0, 1.2, mu]])  # 1 m gap: the IDM asks for more than the road gives
    idm, brake = LeadFollowParams(sv_policy="idm"), LeadFollowParams(sv_policy="brake")
    for sc, a0 in ((idm, -4.67 * mu), (brake, -10.0 * mu)):
        for u, a1 in ((-5.0, -5.0 * mu), (-2.0, -2.0 * mu), (2.0, 2.0)):  # accelerating is not limited
            nxt = sc.step(state, np.array([[u]]), None)[0]
            x0, x1 = 10.0 * DT + a0 * DT**2 / 2, 8.0 * DT + a1 * DT**2 / 2
            assert nxt.tolist() == pytest.approx([10.0 + a0 * DT, 8.0 + a1 * DT, 1.0 + x1 - x0, 1.2, mu])


def test_the_time_headway_is_read_per_row():
    sc = LeadFollowParams(sv_policy="idm")
    states = np.array([[10.0, 10.0, 30.0, headway, 1.0] for headway in (0.8, 1.5, 2.0)])
    a0 = (sc.step(states, np.zeros((3, 1)), None)[:, 0] - 10.0) / DT
    for accel, headway in zip(a0, (0.8, 1.5, 2.0)):
        assert accel == pytest.approx(0.73 * (1 - (10 / 30) ** 4 - ((2.0 + 10.0 * headway) / 30.0) ** 2))


def test_parameters_never_change_during_a_run():
    sc = LeadFollowParams(sv_policy="idm", disturbance=0.5)
    assert sc.parameter_axes == (3, 4) and sc.step_bounds()[3:].tolist() == [0.0, 0.0]
    assert all(not failure for facet, failure in sc.facets() if facet.axis in sc.parameter_axes)
    testing.check_parameters_held(NumpyBackend(sc), runs=512)
    testing.check_step_bound(NumpyBackend(sc))  # a zero bound, checked against every step


class Drifting(Scenario):
    """A user scenario with a parameter k whose own step would let it drift."""

    name = "drifting"
    state_names = ("x", "k")
    parameter_names = ("k",)
    lower, upper = np.array([0.0, 0.0]), np.array([10.0, 1.0])
    failure_sides = {"x": False}
    action_names = ("u",)
    action_lower, action_upper = np.array([-1.0]), np.array([1.0])
    adversarial_actions = np.array([[-1.0]])

    def step(self, states, actions, noise):
        return states + np.column_stack([actions[:, 0] * states[:, 1], np.full(len(states), 0.01)])

    def step_bound(self):
        return 0.1


def test_the_generic_step_holds_parameters_and_the_suite_catches_one_that_does_not():
    sc = Drifting()
    states = np.array([[5.0, 0.5], [1.0, 0.25]])
    out = np.empty((2, 2))
    sc.step_into(states, np.array([[1.0], [1.0]]), None, out)
    assert out.T.tolist() == [[5.5, 0.5], [1.25, 0.25]]  # the parameter copied through
    assert sc.step_bounds().tolist() == [0.1, 0.0]

    class Leaky(Drifting):
        def step_into(self, states, actions, noise, out):
            out[...] = self.step(states, actions, noise).T  # a fast path that forgot hold_parameters

    with pytest.raises(AssertionError, match="drifting: sample index 0 changed a parameter"):
        testing.check_parameters_held(NumpyBackend(Leaky()))


def test_a_parameter_must_be_a_state_and_no_failure_facet():
    with pytest.raises(ScenarioError, match="parameter 'x' must be a state variable and no failure facet"):
        type("Bad", (Drifting,), {"parameter_names": ("x",)})()
    with pytest.raises(ScenarioError, match="parameter 'q' must be"):
        type("Bad", (Drifting,), {"parameter_names": ("q",)})()


def _grid(v0_max=20.0, p10_max=70.0):
    axes = np.linspace(0, v0_max, 19), np.linspace(0, 20, 21), np.linspace(0, p10_max, 31)
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


@pytest.mark.parametrize("policy", ["idm", "brake"])
def test_the_safe_set_shrinks_with_friction(policy):
    """A slippery road lowers the SV's braking and the lead's: every state safe at mu is
    safe at any larger mu (checked on a grid, at three headways), and the set shrinks."""
    sc = LeadFollowParams(sv_policy=policy)
    grid = _grid()
    for headway in (0.8, 1.5, 2.0):
        sets = [sc.reference_safe(with_parameters(grid, headway, mu)) for mu in (0.4, 0.55, 0.7, 0.85, 1.0)]
        for slippery, dry in zip(sets, sets[1:]):
            assert not (slippery & ~dry).any()
        assert sets[0].sum() < sets[-1].sum()


def test_the_idm_safe_set_grows_with_the_time_headway_away_from_the_truncating_facets():
    """A longer headway makes the IDM brake earlier: safe at T means safe at any longer T,
    on a grid that keeps clear of the truncating facets v0 = 20 and p10 = 70."""
    sc = LeadFollowParams(sv_policy="idm")
    grid = _grid(v0_max=18.0, p10_max=60.0)
    for mu in (0.4, 0.6, 1.0):
        sets = [sc.reference_safe(with_parameters(grid, headway, mu)) for headway in np.linspace(0.8, 2.0, 5)]
        for short, long in zip(sets, sets[1:]):
            assert not (short & ~long).any()
    assert sets[0].sum() == sets[-1].sum()  # on a dry road the emergency braking decides, not T
    slippery = [sc.reference_safe(with_parameters(grid, headway, 0.4)) for headway in (0.8, 2.0)]
    assert slippery[0].sum() < 0.8 * slippery[1].sum()


def test_containment_in_the_headway_fails_only_through_truncation():
    """At v0 = 20 a short-headway IDM accelerates and leaves Sigma through v0 > 20 (a
    truncation, so the paper counts the start safe), where a long-headway one brakes,
    stays inside and later collides: why the test above keeps off that facet."""
    sc = LeadFollowParams(sv_policy="idm")
    starts = np.array([[20.0, 18.0, 62.0, 1.7, 0.4], [20.0, 18.0, 62.0, 2.0, 0.4]])
    assert sc.reference_safe(starts).tolist() == [True, False]
    first = sc.step(starts, np.full((2, 1), -5.0), None)
    assert first[0, 0] > 20.0 + 1e-9 and first[1, 0] < 20.0
