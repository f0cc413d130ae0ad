"""The shared conformance suite (scenarios/testing.py) on every scenario and back end we
ship, the custom-scenario guide's example included, the SUMO back end, and the per-run
simulators of the highway-env worked example (examples/highway)."""

import sys
from pathlib import Path

import numpy as np
import pytest

from scenarios import testing
from scenarios.base import ScenarioError
from scenarios.registry import make_backend

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "custom"
HIGHWAY = EXAMPLES.parent / "highway"

BACKENDS = {
    "lead-follow/brake": {"name": "lead-follow", "sv_policy": "brake"},
    "lead-follow/idm+disturbance": {"name": "lead-follow", "sv_policy": "idm", "disturbance": 0.3},
    "fleet3/idm": {"name": "fleet3", "sv_policy": "idm"},
    "platoon/idm k=4": {"name": "platoon", "sv_policy": "idm", "vehicles": 4},
    "platoon/brake k=5 r=2+disturbance": {"name": "platoon", "sv_policy": "brake", "vehicles": 5, "followers": 2,
                                          "disturbance": 0.3},
    "lead-follow-params/idm": {"name": "lead-follow-params", "sv_policy": "idm"},
    "toy": {"name": "toy"},
    "guide:approach": {"name": "approach:Approach"},
    "sumo:lead-follow": {"name": "lead-follow", "backend": "sumo", "sv_policy": "sumo"},
    "per-run:highway-idm": {"name": "lead-follow", "backend": "highway_idm:HighwayIDM"},
    "per-run:highway-lanes": {"name": "highway_lanes:TwoLaneFollow", "backend": "highway_lanes:HighwayMOBIL"},
}


@pytest.fixture(params=list(BACKENDS))
def backend(request, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))  # as the CLI does with the working directory
    monkeypatch.syspath_prepend(str(HIGHWAY))
    sys.modules.pop("approach", None)
    return make_backend(dict(BACKENDS[request.param]))


def test_declarations(backend):
    testing.check_declarations(backend.scenario)


def test_a_run_depends_on_its_key_and_start_alone(backend):
    testing.check_key_only(backend)


def test_search_actions_depend_on_the_key_and_start_alone(backend):
    """actions.mode = "search" needs only the black-box contract: on every back end."""
    from scenarios.search import SearchActions

    testing.check_key_only(backend, policy=SearchActions(backend.scenario))


@pytest.mark.parametrize("mode", ["uniform", "adversarial", "constant", "search", "feedback"])
@pytest.mark.parametrize("name", ["lead-follow", "fleet3", "toy"])
def test_every_action_policy_keeps_the_policy_contract(mode, name):
    from scenarios.action_modes import make_action_policy

    scenario = make_backend({"name": name}).scenario
    value = list(scenario.action_lower) if mode == "constant" else None
    policy = make_action_policy(mode, scenario, value, f"conformance_policies:{name.replace('-', '_')}")
    testing.check_action_policy(policy, scenario)


def test_runs_stay_finite(backend):
    testing.check_finite(backend)


def test_step_bound_bounds_every_observed_step(backend):
    largest = testing.check_step_bound(backend)
    assert largest > 0  # the check saw motion, not a frozen simulator


def test_outcomes_match_where_runs_end(backend):
    testing.check_outcomes(backend)


def test_parameters_of_the_domain_keep_their_start_values(backend):
    testing.check_parameters_held(backend)


def test_a_wrong_step_bound_is_an_error_naming_the_scenario(monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))
    backend = make_backend({"name": "approach:Approach"})
    monkeypatch.setattr(type(backend.scenario), "step_bound", lambda self: 0.01)
    with pytest.raises(ScenarioError, match=r"scenario 'approach:Approach': step_bound\(\) = 0.01 but sample index"):
        testing.check_step_bound(backend)


def test_the_suite_catches_a_scenario_whose_runs_see_their_batch():
    """The suite is not vacuous: a step that mixes rows of the batch is refused."""
    from scenarios.lead_follow import LeadFollow

    class Leaky(LeadFollow):
        name = "leaky"

        def step_into(self, states, actions, noise, out):
            super().step_into(states, actions, noise, out)
            out[0] += 1e-6 * float(np.mean(states[:, 0]))  # depends on the other runs

    with pytest.raises(AssertionError, match="leaky: sample index .* ran differently"):
        testing.check_key_only(make_backend({"name": "lead-follow"}).__class__(Leaky(sv_policy="idm")))


def test_the_policy_check_catches_a_policy_that_sees_its_batch_or_leaves_gamma():
    from scenarios.actions import UniformActions

    scenario = make_backend({"name": "lead-follow"}).scenario

    class Herd(UniformActions):
        def __call__(self, scenario, states, t, streams):
            u = super().__call__(scenario, states, t, streams)
            return np.clip(u + 1e-3 * np.mean(states[:, 0]), scenario.action_lower, scenario.action_upper)

    class Wild(UniformActions):
        def __call__(self, scenario, states, t, streams):
            return super().__call__(scenario, states, t, streams) * 2

    with pytest.raises(AssertionError, match="depends on its batch"):
        testing.check_action_policy(Herd(), scenario)
    with pytest.raises(AssertionError, match="outside Gamma"):
        testing.check_action_policy(Wild(), scenario)
