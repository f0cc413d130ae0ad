"""`scenario-farm export DIR --xosc`: real campaigns (CLI processes), the files they
export validated against the ASAM OpenSCENARIO 1.0 / 1.2 and OpenDRIVE 1.5 schemas
(xmlschema), and played back against the recorded runs."""

import itertools
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from coordinator.safe_set import SafeSet
from farm.directory.recording import read_recording
from farm.openscenario.layout import affine_range
from scenarios.fleet3 import Fleet3
from scenarios.lead_follow import LeadFollow
from scenarios.registry import make_scenario
from small_campaign import lead_follow_toml
from xosc_reading import odr15, osc10, osc12, play, schema_errors

DT = 0.1


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "farm", *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def one_line_error(r, *words):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("scenario-farm: error: "), r.stderr
    for w in words:
        assert w in r.stderr, r.stderr


def campaign(tmp_path_factory, name, toml):
    d = tmp_path_factory.mktemp(name)
    (d / "c.toml").write_text(toml)
    r = cli("quantify", d / "c.toml", "--out", d / "out", "--quiet")
    assert r.returncode == 0, r.stderr
    r = cli("export", d / "out", "--xosc")
    assert r.returncode == 0, r.stderr
    return d / "out"


@pytest.fixture(scope="module")
def lead_follow(tmp_path_factory):
    return campaign(tmp_path_factory, "lf", lead_follow_toml() + "[record]\nquantify_runs = 4\n")


def lane_toml(scenario_lines: str) -> str:
    """A one-round adversarial campaign of a lane scenario that records 3 failing runs."""
    return (f'[scenario]\n{scenario_lines}sv_policy = "idm"\n[actions]\nmode = "adversarial"\n[quantify]\n'
            'delta0 = 2.0\ndelta_min = 2.0\nhorizon = 30\ncertify = false\nsides = false\n'
            '[record]\nquantify_runs = 3\n[farm]\nexecutor = "local"\nbatch_size = 256\n')


@pytest.fixture(scope="module")
def fleet3(tmp_path_factory):
    return campaign(tmp_path_factory, "f3", lane_toml('name = "fleet3"\n'))


@pytest.fixture(scope="module")
def platoon(tmp_path_factory):
    # 7-D: lead 2 (uL) and follower 1 (uF) commanded, lead 1 driving the traffic IDM
    return campaign(tmp_path_factory, "pl", lane_toml('name = "platoon"\nvehicles = 4\n'))


def recorded(directory):
    runs = {}
    for path in sorted((directory / "recordings").glob("*.mcap")):
        runs.update(read_recording(path)["runs"])
    return runs


def check_schemas(directory):
    out = directory / "openscenario"
    runs = sorted(out.glob("run-*.xosc")) + sorted(out.glob("counterexample-*.xosc"))
    for path in runs:  # concrete scenarios: OpenSCENARIO 1.0, and still valid in 1.2
        assert ET.parse(path).getroot().find("FileHeader").get("revMinor") == "0"
        assert schema_errors(osc10(), path) == [], path
        assert schema_errors(osc12(), path) == [], path
    for path in sorted(out.glob("*.xosc")):
        if path not in runs:  # expressions and distributions: OpenSCENARIO 1.2
            assert ET.parse(path).getroot().find("FileHeader").get("revMinor") == "2"
            assert schema_errors(osc12(), path) == [], path
    assert schema_errors(odr15(), out / "road.xodr") == []
    return runs


def assert_plays_as(path, scenario, traj):
    """The concrete scenario at ``path``, played with the SV replaying its recorded
    speeds, is the run ``traj``: speeds exactly, states to float rounding, except after
    a vehicle stops inside a step (the SpeedAction ramps to 0 over the whole step: at
    most |a| dt^2 / 8 further, 9 mm at 7 m/s^2)."""
    played = play(path, DT)
    s, v = (np.stack([played[r][i] for r in scenario.vehicle_roles], axis=1) for i in (0, 1))
    assert len(s) == len(traj)
    _, speeds = scenario.to_vehicles(traj)
    np.testing.assert_array_equal(v, speeds)
    stops = np.cumsum(np.r_[0, ((speeds[1:] == 0) & (speeds[:-1] > 0)).sum(axis=1)])
    states = scenario.from_vehicles(s, v)
    err = np.abs(states - traj).max(axis=1)
    assert np.all(err <= 1e-9 + 0.009 * stops), (path, err.max(), stops[-1])
    return states


def check_replay(directory, scenario):
    runs = recorded(directory)
    assert len(list((directory / "openscenario").glob("run-*.xosc"))) == len(runs) > 0
    for index, run in runs.items():
        states = assert_plays_as(directory / "openscenario" / f"run-{index}.xosc", scenario, run["trajectory"])
        assert run["outcome"] == "failure" and scenario.classify(states[-1:])[0] == 2  # the collision is there


def test_lead_follow_export_is_schema_valid_and_replays_the_recorded_runs(lead_follow):
    names = sorted(p.name for p in (lead_follow / "openscenario").iterdir())
    assert names == sorted(["road.xodr", "logical_scenario.xosc", "safe_set.xosc"] +
                           [f"run-{i}.xosc" for i in recorded(lead_follow)])
    check_schemas(lead_follow)
    check_replay(lead_follow, LeadFollow("idm"))


def test_fleet3_export_is_schema_valid_and_replays_the_recorded_runs(fleet3):
    check_schemas(fleet3)
    check_replay(fleet3, Fleet3("idm"))
    root = ET.parse(next((fleet3 / "openscenario").glob("run-*.xosc"))).getroot()
    assert [o.get("name") for o in root.iter("ScenarioObject")] == ["sv", "lead", "follower"]


def test_platoon_exports_its_recorded_runs_with_every_car_and_says_why_not_its_set(platoon):
    scenario = make_scenario("platoon", "idm", None, 0.0, {"vehicles": 4})
    names = sorted(p.name for p in (platoon / "openscenario").iterdir())
    assert names == sorted(["road.xodr"] + [f"run-{i}.xosc" for i in recorded(platoon)])  # no logical scenario
    check_schemas(platoon)
    check_replay(platoon, scenario)
    root = ET.parse(next((platoon / "openscenario").glob("run-*.xosc"))).getroot()
    assert [o.get("name") for o in root.iter("ScenarioObject")] == ["sv", "lead1", "lead2", "follower1"]
    assert "; lead1: the recorded speeds too" in root.find("FileHeader").get("description")
    r = cli("export", platoon, "--xosc", "--force")
    assert r.returncode == 0 and "note: no logical scenario or certified set: platoon's traffic model drives lead1" \
        in r.stdout, r.stdout


def test_the_sv_is_the_controller_under_test_unless_told_otherwise(lead_follow):
    path = next((lead_follow / "openscenario").glob("run-*.xosc"))
    root = ET.parse(path).getroot()
    sv = root.find("Entities/ScenarioObject[@name='sv']")
    assert sv.find("Vehicle/Properties/Property[@name='type']").get("value") == "ego_vehicle"
    controller = sv.find("ObjectController/Controller")
    assert controller.get("name") == "controller_under_test"
    assert controller.find("Properties/Property[@name='esminiController']").get("value") == "ExternalController"
    assert root.find("ParameterDeclarations/ParameterDeclaration[@name='SvDriver']").get("value") == \
        "controller_under_test"
    for driver in ("controller_under_test", "none"):  # the SV keeps its start speed: nothing scripts it
        _, v = play(path, DT, driver)["sv"]
        assert np.all(v == v[0])
    activating = [a for a in root.iter("Act") if a.find(".//ActivateControllerAction") is not None]
    assert len(activating) == 1
    assert activating[0].find("StartTrigger//ParameterCondition").get("value") == "controller_under_test"


def test_the_certified_set_is_a_value_set_per_box_over_the_logical_scenario(lead_follow):
    out = lead_follow / "openscenario"
    root = ET.parse(out / "safe_set.xosc").getroot()
    assert root.find("ParameterValueDistribution/ScenarioFile").get("filepath") == "logical_scenario.xosc"
    sets = root.findall(".//ValueSetDistribution/ParameterValueSet")
    got = np.array([[float(a.get("value")) for a in s.findall("ParameterAssignment")] for s in sets])
    safe_set = SafeSet.from_parquet(lead_follow / "safe_set.parquet", LeadFollow.state_names)
    centres, h = safe_set.centres, safe_set.finest
    np.testing.assert_array_equal(got, centres)
    assert [a.get("parameterRef") for a in sets[0]] == ["v0", "v1", "p10"]
    assert float(root.find("FileHeader/Properties/Property[@name='half_width']").get("value")) == h
    logical = ET.parse(out / "logical_scenario.xosc").getroot()
    declared = {p.get("name") for p in logical.iter("ParameterDeclaration")}
    assert declared == {"v0", "v1", "p10", "SvDriver"}
    lead = logical.find("Storyboard/Init/Actions/Private[@entityRef='lead']")
    assert lead.find(".//LanePosition").get("s") == "${$p10 + 16.0}"  # SV front at 15 m, 5 m cars, rear axle 1 m in
    assert lead.find(".//AbsoluteTargetSpeed").get("value") == "$v1"
    brake = logical.find(".//Act[@name='environment']//SpeedActionDynamics")
    assert (brake.get("dynamicsDimension"), brake.get("value")) == ("rate", "5.0")  # Gamma*: the lead brakes at -5


def test_a_second_export_needs_force_and_bad_requests_are_one_line_errors(lead_follow, tmp_path):
    before = {p.name: p.read_bytes() for p in (lead_follow / "openscenario").iterdir()}
    one_line_error(cli("export", lead_follow, "--xosc"), "--force")
    assert {p.name: p.read_bytes() for p in (lead_follow / "openscenario").iterdir()} == before
    one_line_error(cli("export", lead_follow), "--xosc")
    one_line_error(cli("export", tmp_path, "--xosc"), "not a campaign directory")
    assert cli("export", lead_follow, "--xosc", "--force").returncode == 0


def test_a_damaged_recording_is_left_out_with_a_note(lead_follow, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(lead_follow, copy)
    shutil.rmtree(copy / "openscenario")
    (copy / "recordings" / "runs-999999.mcap").write_bytes(b"not mcap")
    r = cli("export", copy, "--xosc")
    assert r.returncode == 0, r.stderr
    assert "note: skipped" in r.stdout and "runs-999999.mcap" in r.stdout
    assert len(list((copy / "openscenario").glob("run-*.xosc"))) == len(recorded(lead_follow))


def test_an_openscenario_symlink_is_refused_and_its_target_untouched(lead_follow, tmp_path):
    """Issue 54: --force wrote over the user's road.xodr through DIR/openscenario -> their folder."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(lead_follow, copy)
    shutil.rmtree(copy / "openscenario")
    user = tmp_path / "user"
    user.mkdir()
    (user / "road.xodr").write_text("the user's road")
    (copy / "openscenario").symlink_to(user)
    for flags in (["--xosc"], ["--xosc", "--force"]):
        one_line_error(cli("export", copy, *flags), "openscenario: a symlink", str(user))
    assert [p.name for p in user.iterdir()] == ["road.xodr"] and (user / "road.xodr").read_text() == "the user's road"
    assert (copy / "openscenario").is_symlink()


def test_a_scenario_without_vehicles_on_a_lane_is_refused(tmp_path):
    (tmp_path / "t.toml").write_text('[scenario]\nname = "toy"\n[quantify]\ndelta0 = 0.5\ndelta_min = 0.5\n'
                                     '[farm]\nexecutor = "local"\n')
    assert cli("quantify", tmp_path / "t.toml", "--out", tmp_path / "q", "--quiet").returncode == 0
    one_line_error(cli("export", tmp_path / "q", "--xosc"), "lane")
    assert not (tmp_path / "q" / "openscenario").exists()


def test_validation_counterexample_and_certified_box_domain(tmp_path):
    (tmp_path / "ce.toml").write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[validate]\n'
                                      'epsilon = 0.01\ndomain = { p10 = [30.0, 70.0] }\n')
    assert cli("validate", tmp_path / "ce.toml", "--out", tmp_path / "ce", "--quiet").returncode == 1
    assert cli("export", tmp_path / "ce", "--xosc").returncode == 0
    (path,) = check_schemas(tmp_path / "ce")
    assert path.name.startswith("counterexample-")
    import json

    ce = json.loads((tmp_path / "ce" / "certificate.json").read_text())["counterexample"]
    assert_plays_as(path, LeadFollow("idm"), np.array(ce["trajectory"]))
    assert not (tmp_path / "ce" / "openscenario" / "certified_domain.xosc").exists()
    # a certified box: the lead accelerates at 3 m/s^2, the brake SV starts nearly stopped
    (tmp_path / "ok.toml").write_text('[scenario]\nname = "lead-follow"\nsv_policy = "brake"\n[actions]\n'
                                      'mode = "constant"\nvalue = 3.0\n[validate]\nalgorithm = "eps"\n'
                                      'epsilon = 0.05\ndomain = { v0 = [0.0, 0.5], p10 = [1.0, 70.0] }\n')
    assert cli("validate", tmp_path / "ok.toml", "--out", tmp_path / "ok", "--quiet").returncode == 0
    r = cli("export", tmp_path / "ok", "--xosc")
    assert r.returncode == 0 and "certified_domain.xosc" in r.stdout, r.stdout + r.stderr
    check_schemas(tmp_path / "ok")
    root = ET.parse(tmp_path / "ok" / "openscenario" / "certified_domain.xosc").getroot()
    ranges = {d.get("parameterName"): (float(d.find(".//Range").get("lowerLimit")),
                                       float(d.find(".//Range").get("upperLimit")))
              for d in root.iter("StochasticDistribution")}
    assert ranges == {"v0": (0.0, 0.5), "v1": (0.0, 20.0), "p10": (1.0, 70.0)}
    hold = ET.parse(tmp_path / "ok" / "openscenario" / "logical_scenario.xosc").getroot().find(
        ".//Act[@name='environment']//SpeedAction")
    assert hold.find("SpeedActionDynamics").get("value") == "3.0"
    assert hold.find(".//AbsoluteTargetSpeed").get("value") == "70.0"  # accelerating: towards the top speed


@pytest.mark.parametrize("name", ["lead-follow", "fleet3"])
def test_the_layouts_extremes_over_sigma_are_its_corners_without_visiting_them(name):
    """The road's length and the SV's start come from the least and greatest position and
    speed over Sigma: n + 1 evaluations of the affine layout give the corners' values."""
    sc = make_scenario(name, "idm")
    corners = np.array(list(itertools.product(*zip(sc.lower, sc.upper))), dtype=float)
    for k in (0, 1):  # front positions, speeds
        lo, hi = affine_range(lambda x: sc.to_vehicles(x)[k], sc.lower, sc.upper)
        values = sc.to_vehicles(corners)[k]
        np.testing.assert_allclose(lo, values.min(axis=0), atol=1e-9)
        np.testing.assert_allclose(hi, values.max(axis=0), atol=1e-9)
