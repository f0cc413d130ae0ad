"""The algorithm conformance suite (coordinator/testing.py) on every algorithm we ship,
with uniform actions (stochastic) and Gamma* (deterministic: enumerating certification)."""

import dataclasses

import pytest

from coordinator import testing
from coordinator.baselines import make_algorithm
from coordinator.spe import SPESettings
from farm.execution.local import LocalExecutor
from scenarios import make_scenario
from scenarios.simulator import SimSpec

SCENARIO = {"name": "lead-follow", "sv_policy": "idm"}
HORIZON = 30


def factories(algorithm: str, mode: str, **options):
    scenario = make_scenario(SCENARIO["name"], sv_policy=SCENARIO["sv_policy"])
    spec = SimSpec(dict(SCENARIO), {"mode": mode}, HORIZON, testing.SETTINGS.seed)
    deterministic = mode == "adversarial"
    settings = SPESettings(delta0=8.0, gamma=0.5, delta_min=4.0, **options)

    def make():
        return make_algorithm(algorithm, scenario, settings, testing.SETTINGS.seed, deterministic)

    # VS draws a new box after every failure: most runs change its state, so it is given
    # a small budget (it is incomplete anyway: Theorem 5)
    campaign = dataclasses.replace(testing.SETTINGS, budget=600) if algorithm == "vs" else testing.SETTINGS
    return make, lambda: LocalExecutor(spec), scenario, campaign


CASES = [("spe", "uniform", {}), ("spe", "adversarial", {}), ("spe", "uniform", {"prioritized": False}),
         ("spe", "uniform", {"boundary": True}), ("spe", "uniform", {"refine": "band"}),
         ("spe", "adversarial", {"refine": "band"}), ("ae", "uniform", {}), ("delta-pruning", "adversarial", {}),
         ("vs", "uniform", {})]


@pytest.fixture(params=CASES, ids=lambda c: f"{c[0]}-{c[1]}" + "".join(f"-{k}" for k in c[2]))
def algorithm(request):
    return factories(*request.param[:2], **request.param[2])


def test_draw(algorithm):
    make, _, scenario, _ = algorithm
    testing.check_draw(make, scenario)


def test_apply(algorithm):
    make, _, scenario, _ = algorithm
    testing.check_apply(make, scenario)


def test_rounds(algorithm):
    make, _, _, _ = algorithm
    testing.check_rounds(make)


def test_determinism(algorithm):
    make, make_executor, _, settings = algorithm
    testing.check_determinism(make, make_executor, settings)


def test_state_round_trip(algorithm):
    make, make_executor, _, settings = algorithm
    testing.check_state_round_trip(make, make_executor, settings)


def test_certification(algorithm):
    make, make_executor, _, settings = algorithm
    testing.check_certification(make, make_executor, settings)
