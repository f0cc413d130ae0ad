"""The SUMO back end against real libsumo (no mocks)."""

import numpy as np
import pytest

pytest.importorskip("libsumo")

from scenarios.streams import RunStreams  # noqa: E402
from scenarios import make_backend, make_scenario  # noqa: E402
from scenarios.actions import AdversarialActions, UniformActions  # noqa: E402
from scenarios.base import FAILURE, ScenarioError  # noqa: E402
from scenarios.policies import IDM_A, IDM_B, IDM_DELTA, IDM_MIN, IDM_S0, IDM_T, IDM_V_DES  # noqa: E402
from scenarios.rollout import run_scenario  # noqa: E402

# SUMO's IDM with the spec's parameters. minGap is IDM's jam distance s0 (SUMO adds it
# back to the gap it hands to IDM, so IDM sees the bumper gap, as the spec's IDM does);
# emergencyDecel is the spec's clipping -4.67 (SUMO brakes at most max(decel,
# emergencyDecel)); maxSpeed is the desired speed (the roads' limit is 100 m/s).
IDM_MATCHED = {"car_follow_model": "IDM", "params": {
    "accel": IDM_A, "decel": IDM_B, "tau": IDM_T, "minGap": IDM_S0, "maxSpeed": IDM_V_DES,
    "delta": float(IDM_DELTA), "emergencyDecel": -IDM_MIN}}

# SUMO's IDM stops the SV at the end of a step (it clamps the new speed at 0), so a stop
# inside a step travels v*dt/2 where the spec's kinematics give v^2/(2|a|): at most
# |a|*dt^2/8 = 4.67 * 0.01 / 8 = 5.8 mm per stop, and the later IDM accelerations differ
# by the same order. Runs whose SV never stops inside a step must agree to rounding.
GAP_TOL, SPEED_TOL, EXACT_TOL = 0.01, 0.01, 1e-9


def sumo(name="lead-follow", **config):
    """The SUMO back end for ``name`` (its scenario geometry is ``.scenario``)."""
    return make_backend({"name": name, "backend": "sumo", "sv_policy": "sumo", "sumo": config})


def uniform_starts(backend, count, seed=0):
    sc = backend.scenario
    return sc.lower + (sc.upper - sc.lower) * np.random.default_rng(seed).random((count, sc.n))


def inserted(backend, starts):
    """The states SUMO reads back right after inserting runs at ``starts``."""
    try:
        return backend.insert(starts, 2)
    finally:
        backend.clear()


def same_runs(a, b):
    return np.array_equal(a.lengths, b.lengths) and np.array_equal(a.outcomes, b.outcomes) and all(
        np.array_equal(a.trajectory(i), b.trajectory(i)) for i in range(len(a)))


@pytest.mark.parametrize("name", ["lead-follow", "fleet3"])
def test_a_run_starts_exactly_at_the_requested_state(name):
    sc = sumo(name, **IDM_MATCHED)
    starts = uniform_starts(sc, 200, seed=1)
    # Edge cases SUMO's insertion rules would refuse or change: contact, standstill, top speed.
    geo = sc.scenario
    corner = geo.lower.copy()
    corner[: 3 if name == "fleet3" else 2] = geo.upper[0]
    starts[:2] = [geo.lower, corner]
    back = inserted(sc, starts)
    np.testing.assert_allclose(back, starts, rtol=0, atol=1e-12)
    # ... and the first step starts from there: the lead's speed after one step is the
    # commanded v1 + u*dt (the same stream gives the same u in both back ends).
    batch = run_scenario(sc, starts, 2, UniformActions(), RunStreams.of(0, np.arange(200)))
    np.testing.assert_array_equal(batch.trajectories[0], starts)
    numpy_sc = make_scenario(name, sv_policy="idm")
    ref = run_scenario(numpy_sc, starts, 2, UniformActions(), RunStreams.of(0, np.arange(200)))
    np.testing.assert_allclose(batch.trajectories[1, :, 1], ref.trajectories[1, :, 1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["lead-follow", "fleet3"])
def test_sumo_idm_matches_the_numpy_idm(name):
    sc, ref_sc = sumo(name, **IDM_MATCHED), make_scenario(name, sv_policy="idm")
    count = 600
    starts = uniform_starts(sc, count, seed=2)
    streams = RunStreams.of(11, np.arange(5000, 5000 + count))
    got = run_scenario(sc, starts, 80, UniformActions(), streams)
    ref = run_scenario(ref_sc, starts, 80, UniformActions(), streams)
    np.testing.assert_array_equal(got.outcomes, ref.outcomes)
    np.testing.assert_array_equal(got.lengths, ref.lengths)
    speeds = list(range(3 if name == "fleet3" else 2))
    gaps = [a for a in range(sc.scenario.n) if a not in speeds]
    exact = commanded_stops = 0
    for i in range(count):
        a, b = got.trajectory(i), ref.trajectory(i)
        assert np.abs(a[:, speeds] - b[:, speeds]).max() <= SPEED_TOL
        assert np.abs(a[:, gaps] - b[:, gaps]).max() <= GAP_TOL
        sv = b[:, 0]
        if not ((sv[:-1] > 0) & (sv[1:] == 0)).any():  # the SV never stops inside a step
            np.testing.assert_allclose(a, b, rtol=0, atol=EXACT_TOL)
            exact += 1
            commanded = b[:, 1:len(speeds)]
            commanded_stops += int(((commanded[:-1] > 0) & (commanded[1:] == 0)).any())
    # Most runs are exact, including runs where a commanded vehicle stops inside a step
    # (the back end places it where the spec's kinematics say, not where SUMO would).
    assert exact > 0.8 * count
    assert commanded_stops > 10


@pytest.mark.parametrize("name,start", [
    ("lead-follow", [20.0, 0.0, 10.0]),      # fast SV, lead stopped 10 m ahead
    ("lead-follow", [15.0, 15.0, 1.0]),      # tailgating 1 m behind, lead brakes hardest
    ("fleet3", [6.0, 0.0, 2.0, 8.0, -20.0]),  # SV 3 m behind a stopped lead
])
def test_braking_into_the_lead_fails_at_the_same_step_as_numpy(name, start):
    sc, ref_sc = sumo(name, **IDM_MATCHED), make_scenario(name, sv_policy="idm")
    starts = np.array([start])
    policy = AdversarialActions(deterministic=True)
    got = run_scenario(sc, starts, 50, policy, RunStreams.of(0, [0]))
    ref = run_scenario(ref_sc, starts, 50, policy, RunStreams.of(0, [0]))
    assert got.outcomes[0] == ref.outcomes[0] == FAILURE
    assert got.lengths[0] == ref.lengths[0] < 50
    gap = sc.scenario.state_names.index("p10")
    contact = sc.scenario.lower[gap]
    assert got.trajectory(0)[-1, gap] < contact <= got.trajectory(0)[-2, gap]


def test_the_same_batch_twice_gives_identical_runs_and_a_run_depends_on_its_key_only():
    sc = sumo("fleet3")  # Krauss, the default model
    starts = uniform_starts(sc, 300, seed=3)
    streams = RunStreams.of(4, np.arange(300))
    first = run_scenario(sc, starts, 40, UniformActions(), streams)
    run_scenario(sc, starts[::-1], 60, UniformActions(), RunStreams.of(5, np.arange(300)))  # something else between
    second = run_scenario(sc, starts, 40, UniformActions(), streams)
    assert same_runs(first, second)
    alone = run_scenario(sc, starts[17:18], 40, UniformActions(), streams.subset([17]))
    np.testing.assert_array_equal(alone.trajectory(0), first.trajectory(17))


def test_krauss_with_sigma_zero_is_deterministic_and_random_settings_are_refused():
    sc = sumo(car_follow_model="Krauss", params={"sigma": 0.0, "accel": 2.6, "decel": 4.5, "tau": 1.0})
    starts = uniform_starts(sc, 400, seed=4)
    streams = RunStreams.of(6, np.arange(400))
    runs = [run_scenario(sc, starts, 50, UniformActions(), streams) for _ in range(3)]
    assert same_runs(runs[0], runs[1]) and same_runs(runs[0], runs[2])
    assert len(np.unique(runs[0].outcomes)) > 1  # the batch exercises more than one outcome
    with pytest.raises(ValueError, match=r"^scenario\.sumo\.params\.sigma: must be 0"):
        sumo(params={"sigma": 0.5})
    with pytest.raises(ValueError, match=r"^scenario\.sumo\.car_follow_model: 'W99' is not reproducible"):
        sumo(car_follow_model="W99")


def test_batches_larger_than_one_simulation_run_in_chunks_with_the_same_results(monkeypatch):
    sc = sumo(**IDM_MATCHED)
    starts = uniform_starts(sc, 100, seed=5)
    streams = RunStreams.of(7, np.arange(100))
    whole = run_scenario(sc, starts, 30, UniformActions(), streams)
    monkeypatch.setattr(sc, "max_batch", 32)
    chunked = run_scenario(sc, starts, 30, UniformActions(), streams)
    assert same_runs(whole, chunked)


@pytest.mark.parametrize("kwargs,message", [
    ({"sv_policy": "idm"}, r"^scenario\.sv_policy: .*allowed: sumo"),
    ({"disturbance": 0.3}, r"^scenario\.disturbance: the sumo back end supports only 0$"),
    ({"sumo": {"car_follow_model": "Foo"}}, r"^scenario\.sumo\.car_follow_model: unknown model 'Foo'; allowed: .*IDM"),
    ({"sumo": {"model": "IDM"}}, r"^scenario\.sumo: unknown key 'model'"),
    ({"sumo": {"params": {"Accel": 2.0}}}, r"^scenario\.sumo\.params\.Accel: not a SUMO vType attribute \(did you mean 'accel'\?\)"),
    ({"sumo": {"params": {"decel": -1}}}, r"^scenario\.sumo\.params\.decel: must be > 0"),
    ({"sumo": {"params": {"length": 4.0}}}, r"^scenario\.sumo\.params\.length: not settable"),
    ({"sumo": {"params": {"latAlignment": "bogus"}}}, r"^scenario\.sumo\.params: SUMO rejected the SV vType: .*bogus"),
])
def test_config_errors_name_the_field(kwargs, message):
    args = {"sv_policy": "sumo", **kwargs}
    with pytest.raises(ValueError, match=message):
        make_backend({"name": "lead-follow", "backend": "sumo", **args})
    # a refused vType leaves the process's simulation usable
    sc = sumo()
    assert run_scenario(sc, uniform_starts(sc, 3), 5, UniformActions(), RunStreams.of(0, [0, 1, 2])).lengths.min() >= 2


def test_geometry_is_the_numpy_scenarios():
    for name in ("lead-follow", "fleet3"):
        sc, ref = sumo(name).scenario, make_scenario(name, sv_policy="idm")
        assert isinstance(sc, type(ref))
        assert sc.state_names == ref.state_names and sc.failure_facets == ref.failure_facets
        np.testing.assert_array_equal(sc.lower, ref.lower)
        np.testing.assert_array_equal(sc.adversarial_actions, ref.adversarial_actions)
        assert sc.step_bound() == ref.step_bound()  # SUMO's default emergencyDecel 9 < the numpy SVs' 10
        with pytest.raises(ScenarioError, match="simulated by the back end"):
            sc.step(ref.lower[None], ref.adversarial_actions, None)
