"""Validation (Algs 2-4) on scenarios whose answers are known."""

import numpy as np
import pytest

from farm import api
from scenarios.base import FAILURE
from scenarios.simulator import SimSpec, Simulator


def run_validation(scenario_cfg, actions, section, *, algorithm="eps", seed=0, eps=0.001, beta=0.01, delta=1.0,
                   boundary=False, horizon=50):
    cert = api.validate({"scenario": scenario_cfg, "actions": actions,
                         "validate": {**section, "algorithm": algorithm, "epsilon": eps, "beta": beta,
                                      "delta": delta, "boundary": boundary, "horizon": horizon},
                         "farm": {"executor": "local", "seed": seed, "batch_size": 512, "pipeline_depth": 2}})
    return cert.data, cert, Simulator(SimSpec(scenario_cfg, actions, horizon, seed))


LF_BRAKE = {"name": "lead-follow", "sv_policy": "brake"}


def test_sigma_is_rejected_and_the_counterexample_fails_again_from_its_key():
    result, _, simulator = run_validation(LF_BRAKE, {"mode": "uniform"}, {})
    assert result["verdict"] == "counterexample"
    ce = result["counterexample"]
    assert ce["reason"].startswith("failure: crossed p10 < 0") and ce["outcome"] == "failure"
    start = np.array([[ce["start_state"][k] for k in simulator.scenario.state_names]])
    assert ce["stream_key"]["seed"] == 0
    again = simulator.simulate(ce["stream_key"]["index"], start)
    assert again.outcomes[0] == FAILURE
    np.testing.assert_array_equal(again.trajectory(0), np.array(ce["trajectory"]))
    assert result["n_run"] == ce["sample_index"] + 1  # the first violation in index order


def test_superlevel_set_of_min_future_gap_is_certified():
    section = {"domain_predicate": "invariant_sets:brake_superlevel_5"}
    result, *_ = run_validation(LF_BRAKE, {"mode": "uniform"}, section)
    assert result["verdict"] == "certified"
    assert result["n_run"] == result["n_required"] == 4603


def test_linear_cut_domain_is_certified_and_a_shifted_cut_is_not():
    # v0 <= v1: the brake SV slows faster than any admissible lead, so the gap never shrinks
    ok = {"domain": {"p10": [10.0, 70.0]}, "constraints": [{"a": {"v0": 1.0, "v1": -1.0}, "b": 0.0}]}
    assert run_validation(LF_BRAKE, {"mode": "uniform"}, ok)[0]["verdict"] == "certified"
    bad = {"domain": {"p10": [0.0, 70.0]}, "constraints": [{"a": {"v0": 1.0, "v1": -1.0}, "b": 8.0}]}
    assert run_validation(LF_BRAKE, {"mode": "uniform"}, bad)[0]["verdict"] == "counterexample"


@pytest.mark.parametrize("algorithm", ["eps", "eps-delta"])
def test_toy_invariant_sets_validate_and_their_complement_does_not(algorithm):
    toy = {"name": "toy", "sv_policy": "none"}
    for well in ([1.0, 4.0], [6.0, 9.0]):
        r = run_validation(toy, {"mode": "uniform"}, {"domain": {"x": well}}, algorithm=algorithm, delta=0.25)[0]
        assert r["verdict"] == "certified"
    r = run_validation(toy, {"mode": "uniform"}, {"domain": {"x": [4.0, 6.0]}}, algorithm=algorithm, delta=0.25)[0]
    assert r["verdict"] == "counterexample"
    r = run_validation(toy, {"mode": "uniform"}, {"domain": {"x": [0.5, 4.0]}}, algorithm=algorithm, delta=0.25)[0]
    assert r["verdict"] == "counterexample"


def test_boundary_band_and_adversarial_actions_reach_the_same_verdicts_with_fewer_runs():
    """Counterexample on an almost invariant Phi (the gap can fall below 10 m only from
    its lowest metre, when the SV is up to 3 m/s faster): runs until the first violation.
    Certificate on an invariant box+cut: VAL^delta over the band visits fewer centres."""
    phi = {"domain": {"p10": [10.0, 70.0]}, "constraints": [{"a": {"v0": 1.0, "v1": -1.0}, "b": 3.0}]}
    plain = run_validation(LF_BRAKE, {"mode": "uniform"}, phi)[0]
    fast = run_validation(LF_BRAKE, {"mode": "adversarial"}, phi, boundary=True)[0]
    assert plain["verdict"] == fast["verdict"] == "counterexample"
    assert fast["n_run"] < plain["n_run"]
    inv = {"domain": {"p10": [10.0, 70.0]}, "constraints": [{"a": {"v0": 1.0, "v1": -1.0}, "b": 0.0}]}
    full = run_validation(LF_BRAKE, {"mode": "adversarial"}, inv, algorithm="delta", delta=1.0)
    band = run_validation(LF_BRAKE, {"mode": "adversarial"}, inv, algorithm="delta", delta=1.0, boundary=True)
    assert full[0]["verdict"] == band[0]["verdict"] == "certified"
    assert band[0]["n_run"] < full[0]["n_run"]
    print(f"counterexample after {plain['n_run']} runs (Phi, Gamma) vs {fast['n_run']} (band, Gamma*); "
          f"certificate with {full[0]['n_run']} centres (Phi) vs {band[0]['n_run']} (band)")


def test_delta_validation_refuses_a_random_system():
    with pytest.raises(ValueError, match="validate.algorithm: 'delta' needs a deterministic system"):
        run_validation(LF_BRAKE, {"mode": "uniform"}, {}, algorithm="delta")
