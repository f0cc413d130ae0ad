"""The conformance suite every scenario and back end must pass (like Optuna's shared
sampler tests): plain functions that raise ``AssertionError`` naming what broke.

    from scenarios.testing import check_backend
    check_backend(make_backend({"name": "my-scenario"}))     # in a test of your own
    check_backend(make_backend({"name": "lead-follow", "backend": "my_sim:MySimulator"}))  # a per-run simulator

What the farm relies on, and what each check tests:
- ``check_declarations``: Sigma, Gamma, Gamma* and the facets are consistent arrays.
- ``check_key_only``: a run depends on its key (seed, sample index) and start alone, not
  on which other runs share its batch or where it sits in it: parallel workers split
  batches as they like, and results must not move.
- ``check_finite``: runs from all over Sigma under uniform actions stay finite.
- ``check_step_bound``: ``step_bound()`` (sigma-bar, Assumption 1) bounds every observed
  step; the boundary-band options rely on it. The rollout core refuses a violated bound
  with an error naming the scenario.
- ``check_outcomes``: a failed run ends beyond a failure facet, a truncated one beyond
  a truncating facet, and the rest run the full horizon inside Sigma.
- ``check_parameters_held``: the parameters of the domain (``parameter_names``) keep
  their start values through every run.
"""

from __future__ import annotations

import numpy as np

from scenarios.actions import UniformActions
from scenarios.base import FAILURE, TRUNCATED
from scenarios.rollout import run_scenario
from scenarios.streams import RunStreams

HORIZON = 30


def _starts(scenario, count: int, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)  # test data only; runs draw from their keyed streams
    return rng.uniform(scenario.lower, scenario.upper, (count, scenario.n))


def _run(backend, starts, indices, seed=3, horizon=HORIZON, check_step_bound=False, policy=None):
    streams = RunStreams.of(seed, np.asarray(indices, dtype=np.uint64))
    return run_scenario(backend, starts, horizon, policy or UniformActions(), streams,
                        check_step_bound=check_step_bound)


def check_declarations(scenario) -> None:
    n, m = scenario.n, scenario.m
    name = scenario.name or type(scenario).__name__
    assert len(scenario.state_names) == n == len(scenario.lower) == len(scenario.upper), f"{name}: n mismatch"
    assert np.all(np.asarray(scenario.lower) < np.asarray(scenario.upper)), f"{name}: Sigma must have lower < upper"
    assert len(scenario.action_lower) == m == len(scenario.action_upper), f"{name}: m mismatch"
    assert np.all(scenario.action_lower <= scenario.action_upper), f"{name}: Gamma must have lower <= upper"
    adv = np.asarray(scenario.adversarial_actions, dtype=float)
    assert adv.ndim == 2 and adv.shape[1] == m and len(adv) >= 1, f"{name}: Gamma* must be (k, m), k >= 1"
    assert np.all((adv >= scenario.action_lower) & (adv <= scenario.action_upper)), f"{name}: Gamma* must lie in Gamma"
    assert set(scenario.failure_sides) <= set(scenario.state_names), f"{name}: failure facets must be state names"
    assert set(scenario.units) <= set(scenario.state_names), f"{name}: units name unknown states"
    assert scenario.step_bound() > 0, f"{name}: step_bound() must be positive"
    params = list(scenario.parameter_axes)
    assert set(scenario.parameter_names) <= set(scenario.state_names) - set(scenario.failure_sides), \
        f"{name}: parameters must be state names and no failure facets"
    assert np.all(np.asarray(scenario.step_bounds(), dtype=float)[params] == 0), \
        f"{name}: step_bounds() must be 0 on the parameters {scenario.parameter_names}"


def check_key_only(backend, runs: int = 64, policy=None) -> None:
    """The same keys and starts give the same runs, alone, reversed or among others
    (with uniform actions, or with ``policy``)."""
    sc = backend.scenario
    starts = _starts(sc, runs)
    keys = np.arange(100, 100 + runs)
    a = _run(backend, starts, keys, policy=policy)
    rev = slice(None, None, -1)
    b = _run(backend, starts[rev], keys[rev], policy=policy)
    others = _starts(sc, runs, seed=11)
    c = _run(backend, np.concatenate([others, starts]), np.concatenate([keys + 10_000, keys]), policy=policy)
    for r in range(runs):
        ta = a.trajectory(r)
        for tb, label in ((b.trajectory(runs - 1 - r), "reversed"), (c.trajectory(runs + r), "among other runs")):
            assert ta.shape == tb.shape and np.array_equal(ta, tb), (
                f"{sc.name}: sample index {keys[r]} ran differently {label} in its batch: a run must depend on "
                f"its key and start alone")


def check_finite(backend, runs: int = 512) -> None:
    sc = backend.scenario
    batch = _run(backend, _starts(sc, runs), np.arange(runs))
    for r in range(runs):
        assert np.isfinite(batch.trajectory(r)).all(), f"{sc.name}: sample index {r} produced a non-finite state"


def check_step_bound(backend, runs: int = 512) -> float:
    """Returns the largest observed step (l-inf) for the report. Per axis too: the
    observed steps along each axis stay within ``step_bounds()`` (the vector sigma-bar
    boundary refinement's band uses), whose largest is ``step_bound()``."""
    sc = backend.scenario
    per_axis = np.asarray(sc.step_bounds(), dtype=float)
    moving = np.ones(sc.n, dtype=bool)
    moving[list(sc.parameter_axes)] = False  # a parameter's bound is 0: it never changes
    assert per_axis.shape == (sc.n,) and (per_axis[moving] > 0).all() and (per_axis[~moving] == 0).all(), \
        f"{sc.name}: step_bounds() must be (n,), positive but 0 on the parameters"
    assert per_axis.max() <= sc.step_bound() * (1 + 1e-12), f"{sc.name}: step_bounds() exceed step_bound()"
    batch = _run(backend, _starts(sc, runs), np.arange(runs), check_step_bound=True)
    largest = np.zeros(sc.n)
    for r in range(runs):
        t = batch.trajectory(r)
        inside = t[: len(t) - (batch.outcomes[r] in (FAILURE, TRUNCATED))]  # the last state may be past a facet
        if len(inside) > 1:
            largest = np.maximum(largest, np.abs(np.diff(inside, axis=0)).max(axis=0))
    worst = int(np.argmax(largest - per_axis))
    assert (largest <= per_axis).all(), (f"{sc.name}: observed step {largest[worst]:g} along {sc.state_names[worst]} > "
                                         f"step_bounds() {per_axis[worst]:g}")
    return float(largest.max())


def check_outcomes(backend, runs: int = 512) -> None:
    sc = backend.scenario
    batch = _run(backend, _starts(sc, runs), np.arange(runs))
    fail_facets = [f for f, failure in sc.facets() if failure]
    lo, hi = np.asarray(sc.lower), np.asarray(sc.upper)
    for r in range(runs):
        t = batch.trajectory(r)
        last = t[-1]
        beyond = [(last[f.axis] > f.bound) if f.upper else (last[f.axis] < f.bound) for f in fail_facets]
        if batch.outcomes[r] == FAILURE:
            assert any(beyond), f"{sc.name}: sample index {r} 'failed' inside every failure facet: {last.tolist()}"
        elif batch.outcomes[r] == TRUNCATED:
            assert np.any((last < lo) | (last > hi)), f"{sc.name}: sample index {r} 'truncated' inside Sigma"
        else:
            assert len(t) == HORIZON, f"{sc.name}: sample index {r} ended early ({len(t)} states) without a reason"


def check_parameters_held(backend, runs: int = 256) -> None:
    sc = backend.scenario
    if not sc.parameter_axes:
        return
    axes = list(sc.parameter_axes)
    batch = _run(backend, _starts(sc, runs), np.arange(runs))
    for r in range(runs):
        t = batch.trajectory(r)
        assert np.array_equal(t[:, axes], np.broadcast_to(t[0, axes], (len(t), len(axes)))), \
            f"{sc.name}: sample index {r} changed a parameter {sc.parameter_names} during its run"


def check_backend(backend) -> None:
    """Every check, for a back end (a bare Scenario runs on its numpy dynamics)."""
    from scenarios.backend import NumpyBackend
    from scenarios.base import Scenario

    if isinstance(backend, Scenario):
        backend = NumpyBackend(backend)
    check_declarations(backend.scenario)
    check_key_only(backend)
    check_finite(backend)
    check_step_bound(backend)
    check_outcomes(backend)
    check_parameters_held(backend)


def check_action_policy(policy, scenario, runs: int = 256, steps: int = HORIZON) -> None:
    """An action policy's contract (scenarios/actions.py): (B, m) finite actions inside
    Gamma, each run's depending on its key, its state and the step alone (not on its
    batch-mates), and an adaptive state that survives a round trip as plain data."""
    name = f"{type(policy).__name__} on {scenario.name}"
    states = _starts(scenario, runs)
    keys = np.arange(500, 500 + runs, dtype=np.uint64)
    for t in range(1, steps):
        u = np.asarray(policy(scenario, states, t, RunStreams.of(5, keys)), dtype=float)
        assert u.shape == (runs, scenario.m), f"{name}: step {t} gave actions of shape {u.shape}"
        assert np.isfinite(u).all(), f"{name}: non-finite actions at step {t}"
        assert ((u >= scenario.action_lower - 1e-12) & (u <= scenario.action_upper + 1e-12)).all(), \
            f"{name}: actions outside Gamma at step {t}"
        rows = np.arange(runs)[::-7]
        alone = np.asarray(policy(scenario, states[rows], t, RunStreams.of(5, keys[rows])), dtype=float)
        assert np.array_equal(alone, u[rows]), f"{name}: a run's action at step {t} depends on its batch"
    state = policy.state()
    if state is not None:
        import json

        assert json.loads(json.dumps(state)) == state, f"{name}: state() must be plain JSON data"
        policy.load(state)
        again = np.asarray(policy(scenario, states, 1, RunStreams.of(5, keys)), dtype=float)
        first = np.asarray(policy(scenario, states, 1, RunStreams.of(5, keys)), dtype=float)
        assert np.array_equal(again, first), f"{name}: load(state()) changed the actions"
