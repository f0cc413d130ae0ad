"""The per-run simulator contract (scenarios/per_run.py): the scenario's own dynamics run
one scene at a time give the numpy back end's runs bit for bit, through the same keyed
action streams and classification; one simulator object serves every run of a worker;
broken simulators are refused with errors naming what broke."""

import numpy as np
import pytest

from scenarios import testing
from scenarios.action_modes import make_action_policy
from scenarios.base import ScenarioError
from scenarios.registry import make_backend
from scenarios.rollout import run_scenario
from scenarios.simulator import SimSpec, Simulator
from scenarios.streams import RunStreams

ROW_BY_ROW = {"name": "lead-follow", "backend": "per_run_simulators:RowByRow"}


def _starts(scenario, count, seed=0):
    return np.random.default_rng(seed).uniform(scenario.lower, scenario.upper, (count, scenario.n))


@pytest.mark.parametrize("mode", ["uniform", "adversarial", "search"])
def test_one_scene_at_a_time_gives_the_numpy_runs_bit_for_bit(mode):
    per_run = make_backend(dict(ROW_BY_ROW))
    numpy = make_backend({"name": "lead-follow", "sv_policy": "idm"})
    starts = _starts(numpy.scenario, 300)
    a = run_scenario(per_run, starts, 40, make_action_policy(mode, per_run.scenario), RunStreams.of(4, np.arange(300)))
    b = run_scenario(numpy, starts, 40, make_action_policy(mode, numpy.scenario), RunStreams.of(4, np.arange(300)))
    assert np.array_equal(a.lengths, b.lengths) and np.array_equal(a.outcomes, b.outcomes)
    assert np.array_equal(a.exits, b.exits)
    assert all(np.array_equal(a.trajectory(r), b.trajectory(r)) for r in range(300))
    assert len(set(a.outcomes.tolist())) == 3  # failures, truncations and full runs all compared


def test_one_simulator_object_serves_every_run_of_a_worker():
    sim = Simulator(SimSpec(dict(ROW_BY_ROW), {"mode": "adversarial"}, 20, 0))
    user = sim.backend.simulator
    sim.simulate(0, _starts(sim.scenario, 50))
    sim.simulate(50, _starts(sim.scenario, 30, seed=1))
    assert sim.backend.simulator is user and user.resets == 80
    assert sim.scenario.sv_policy_name == "idm-row-by-row" and sim.deterministic


def test_the_conformance_suite_runs_on_per_run_simulators_and_catches_one_that_remembers():
    testing.check_backend(make_backend(dict(ROW_BY_ROW)))
    with pytest.raises(AssertionError, match="ran differently"):
        testing.check_key_only(make_backend({"name": "lead-follow", "backend": "per_run_simulators:Remembers"}))


def test_a_simulator_that_cannot_place_the_start_is_refused():
    backend = make_backend({"name": "lead-follow", "backend": "per_run_simulators:Misplaces"})
    with pytest.raises(ScenarioError, match=r"did not start sample index 7 at its start state"):
        run_scenario(backend, _starts(backend.scenario, 1), 5, make_action_policy("uniform", backend.scenario),
                     RunStreams.of(0, [7]))


def test_keyed_randomness_follows_the_run_key():
    backend = make_backend({"name": "lead-follow", "backend": "per_run_simulators:Keyed"})
    testing.check_key_only(backend)  # the same key gives the same run wherever it sits
    policy = make_action_policy("adversarial", backend.scenario)
    start = np.array([[15.0, 5.0, 30.0]])
    one = run_scenario(backend, start, 30, policy, RunStreams.of(0, [3])).trajectory(0)
    other = run_scenario(backend, start, 30, policy, RunStreams.of(0, [4])).trajectory(0)
    assert not np.array_equal(one, other)
    sim = Simulator(SimSpec({"name": "lead-follow", "backend": "per_run_simulators:Keyed"}, {"mode": "adversarial"},
                            20, 0))
    assert not sim.deterministic  # a run is not a function of its start: no exact enumeration


@pytest.mark.parametrize("section, message", [
    ({"backend": "per_run_simulators:Unfinished"}, "does not implement step"),
    ({"backend": "per_run_simulators:RowByRow", "disturbance": 0.5}, "scenario.disturbance: a per-run simulator"),
    ({"backend": "per_run_simulators:RowByRow", "sv_policy": "idm"}, "scenario.sv_policy"),
])
def test_a_misused_per_run_simulator_is_a_one_line_error(section, message):
    with pytest.raises(ValueError, match=message):
        make_backend({"name": "lead-follow", **section})
