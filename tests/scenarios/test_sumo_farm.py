"""The SUMO back end through the whole farm: Ray actors each holding one libsumo."""

import pytest

from coordinator.safe_set import SafeSet
from coordinator.volume import raster_iou
from farm import config as config_mod
from farm.jobs.quantification import run
from scenarios.lead_follow import LeadFollow
from scenarios.policies import IDM_A, IDM_B, IDM_DELTA, IDM_MIN, IDM_S0, IDM_T, IDM_V_DES

pytest.importorskip("libsumo")

KRAUSS = {"car_follow_model": "Krauss", "params": {"sigma": 0.0, "accel": 2.6, "decel": 4.5, "tau": 1.0}}
IDM_MATCHED = {"car_follow_model": "IDM", "params": {
    "accel": IDM_A, "decel": IDM_B, "tau": IDM_T, "minGap": IDM_S0, "maxSpeed": IDM_V_DES,
    "delta": float(IDM_DELTA), "emergencyDecel": -IDM_MIN}}


def sumo_config(executor="local", workers=1, sumo=KRAUSS, actions="uniform", **quantify):
    q = {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 40, **quantify}
    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "backend": "sumo", "sv_policy": "sumo", "sumo": sumo},
        "actions": {"mode": actions}, "quantify": q,
        "farm": {"executor": executor, "workers": workers, "batch_size": 256, "seed": 2}})


def test_parallel_contract_holds_on_sumo(ray_local, tmp_path):
    # checks allowing no violation: shorter, and the contract with the tolerance is
    # tests/farm/test_parallel_contract.py's on numpy
    local = run(sumo_config(certify_tolerance=0), tmp_path / "local", resume=False)
    for workers in (1, 2):
        ray = run(sumo_config("ray", workers, certify_tolerance=0), tmp_path / f"ray{workers}", resume=False)
        assert ray["result_hash"] == local["result_hash"]
        assert ray["runs_committed"] == local["runs_committed"]


def test_sumo_idm_and_numpy_idm_quantify_the_same_set(tmp_path):
    sumo = run(sumo_config(sumo=IDM_MATCHED, actions="adversarial", delta0=2.0, delta_min=1.0, horizon=50),
               tmp_path / "sumo", resume=False)
    numpy_cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "adversarial"},
        "quantify": {"delta0": 2.0, "delta_min": 1.0, "epsilon": 0.005, "beta": 0.1, "horizon": 50},
        "farm": {"executor": "local", "batch_size": 256, "seed": 2}})
    ref = run(numpy_cfg, tmp_path / "numpy", resume=False)
    names = LeadFollow.state_names
    a = SafeSet.from_parquet(tmp_path / "sumo" / "safe_set.parquet", names)
    b = SafeSet.from_parquet(tmp_path / "numpy" / "safe_set.parquet", names)
    iou = raster_iou(a, b, LeadFollow.lower, LeadFollow.upper)
    assert iou >= 0.9, (iou, sumo.volume_union, ref.volume_union)


@pytest.mark.soak  # minutes of SUMO runs; compare's plan and estimate run in CI (tests/farm/test_compare_plan.py)
def test_compare_on_a_sumo_campaign_uses_the_simulated_reference(tmp_path):
    import json
    import subprocess
    import sys

    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nbackend = "sumo"\nsv_policy = "sumo"\n'
                   '[scenario.sumo]\ncar_follow_model = "Krauss"\nparams = { sigma = 0.0 }\n'
                   '[actions]\nmode = "adversarial"\n[quantify]\ndelta0 = 2.0\ndelta_min = 1.0\n'
                   '[farm]\nexecutor = "local"\n')
    out = tmp_path / "q"
    assert subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(out)],
                          capture_output=True).returncode == 0
    r = subprocess.run([sys.executable, "-m", "farm", "compare", str(out), "--grid", "12"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert "simulated under Gamma*" in r.stdout
    # up front: the runs (1,728 grid points + 4 slices of 30 x 30 for the figure) and their time
    plan = r.stderr.index("1,728 grid points (12 per axis) + 3,600 for the figure = 5,328 runs")
    assert plan < r.stderr.index("for the rest (a shared machine") < r.stderr.index("reference done")
    metrics = json.loads((out / "compare.json").read_text())
    assert metrics["iou"] >= 0.95 and metrics["precision"] >= 0.97


def test_the_adversary_search_finds_krauss_worst_case_on_sumo(tmp_path):
    """actions.mode = "search" needs only the black-box contract: on SUMO it proposes
    maximal lead braking, nobody having told it, and falsify cannot refute it."""
    import json
    import subprocess
    import sys

    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nbackend = "sumo"\nsv_policy = "sumo"\n'
                   '[scenario.sumo]\ncar_follow_model = "Krauss"\nparams = { sigma = 0.0 }\n'
                   '[actions]\nmode = "search"\n[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nepsilon = 0.005\n'
                   '[farm]\nexecutor = "local"\n')
    out = tmp_path / "q"
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    found = json.loads((out / "adversary.json").read_text())
    assert found["proposed_gamma_star"]["actions"] == [[-5.0]]
    r = subprocess.run([sys.executable, "-m", "farm", "falsify", str(out), "--points", "400", "--tries", "2"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "not refuted" in r.stdout, r.stdout + r.stderr


def test_a_platoon_of_three_is_fleet3_on_sumo_and_traffic_cars_are_refused(tmp_path):
    # every car but the SV commanded by an action column: platoon k = 3 is fleet3's
    # scenario (shared/spec/scenarios.md), the same result; k = 4 has a car driving the
    # traffic IDM, which SUMO's commanded vehicles cannot be: refused, naming it
    from scenarios.errors import ConfigError

    def cfg(name, **options):
        return config_mod.normalize({
            "scenario": {"name": name, "backend": "sumo", **options}, "actions": {"mode": "adversarial"},
            "quantify": {"delta0": 2.0, "delta_min": 2.0, "horizon": 30, "certify": False, "sides": False},
            "farm": {"executor": "local"}})

    platoon = run(cfg("platoon", vehicles=3), tmp_path / "platoon", resume=False)
    fleet3 = run(cfg("fleet3"), tmp_path / "fleet3", resume=False)
    assert platoon["result_hash"] == fleet3["result_hash"] and platoon["boxes"] == fleet3["boxes"] > 0
    with pytest.raises(ConfigError, match="scenario.backend: .* in scenario 'platoon' its own traffic model drives "
                                          "lead1 "):
        run(cfg("platoon", vehicles=4), tmp_path / "four", resume=False)
    assert not (tmp_path / "four").exists()
