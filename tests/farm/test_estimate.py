"""`scenario-farm estimate DIR` (farm/jobs/estimation.py) on a real campaign with real files:
estimate.json and the ledger agree with each other, the same estimate after kill -9 and
resume and on 1 and 2 Ray workers, plain Monte Carlo beside it, two controllers on the
same runs, the exact bound when nothing fails, and one-line refusals of bad input."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from farm import api
from farm.reports.estimate_report import EstimateReport
from small_campaign import lead_follow_toml

NATURALISTIC = """
[estimate]
distribution = "axes"
runs = 6000
pilot = 600
[estimate.axes.v0]
law = "normal"
mean = 15.0
std = 2.5
[estimate.axes.v1]
law = "normal"
mean = 15.0
std = 2.5
[estimate.axes.p10]
law = "lognormal"
mu = 3.2
sigma = 0.6
"""


def cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "farm", *args], capture_output=True, text=True, **kw)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A finished lead-follow idm campaign under uniform Gamma, and an [estimate] file."""
    d = tmp_path_factory.mktemp("campaign")
    (d / "c.toml").write_text(lead_follow_toml(delta_min=1.0, horizon=30))
    r = cli("quantify", str(d / "c.toml"), "--out", str(d / "out"), "--quiet")
    assert r.returncode == 0, r.stderr
    (d / "estimate.toml").write_text(NATURALISTIC)
    return d / "out", d / "estimate.toml"


def _ledger(directory):
    return pq.read_table(directory / "ledger").sort_by("sample_index")


def test_estimate_json_agrees_with_its_ledger_and_beats_plain_monte_carlo(campaign):
    out, est = campaign
    r = cli("estimate", str(out), "--config", str(est), "--quiet")
    assert r.returncode == 0, r.stderr
    assert "failure rate: estimate stratified: P(failure) =" in r.stdout and "plain Monte Carlo at 6,000" in r.stdout
    folder = out / "estimates" / "stratified"
    report = EstimateReport.read(folder)
    ledger = _ledger(folder)
    assert ledger.num_rows == report.runs == 6000
    assert ledger.column("sample_index").to_pylist() == list(range(6000))
    failed = np.asarray(ledger.column("outcome").to_pylist()) == "failure"
    assert failed.sum() == report.failures > 0
    # the stage-weighted estimator recomputed from the ledger's rows alone
    masses = np.array([s["mass"] for s in report.strata])
    assert masses.sum() == pytest.approx(1.0)
    stage, stratum = ledger.column("stage").to_numpy(), ledger.column("stratum").to_numpy()
    recomputed = 0.0
    for t in np.unique(stage):
        rows = stage == t
        means = [failed[rows & (stratum == h)].mean() for h in range(len(masses))]
        recomputed += rows.sum() / len(stage) * float(np.dot(masses, means))
    assert report.estimate == pytest.approx(recomputed, rel=1e-12)
    assert report.interval[0] <= report.estimate <= report.interval[1]
    assert report.plain_mc["width_ratio"] > 2  # the set's strata put the runs where failures are
    assert report.distribution["axes"]["p10"]["law"] == "lognormal" and len(report.distribution["hash"]) == 16
    assert (folder / "failures.png").stat().st_size > 10_000
    r = cli("estimate", str(out), "--config", str(est), "--plain", "--quiet")
    assert r.returncode == 0, r.stderr
    plain = EstimateReport.read(out / "estimates" / "plain")
    assert len(plain.strata) == 1 and "Clopper-Pearson" in plain.method
    assert plain.half_width > report.half_width
    r = cli("report", str(out), "--html")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("failure rate: estimate") >= 2
    page = (out / "report.html").read_text()
    assert "<h2>Failure rate</h2>" in page and "estimates/stratified/failures.png" in page


def test_an_existing_estimate_is_replaced_only_with_force(campaign):
    out, est = campaign
    args = ("estimate", str(out), "--config", str(est), "--name", "twice", "--runs", "1500", "--quiet")
    assert cli(*args).returncode == 0
    before = (out / "estimates" / "twice" / "estimate.json").read_bytes()
    r = cli(*args)
    assert r.returncode == 2 and "estimate.json exists; pass --force" in r.stderr and len(r.stderr.splitlines()) == 1
    assert (out / "estimates" / "twice" / "estimate.json").read_bytes() == before
    assert cli(*args, "--force").returncode == 0


def test_kill_9_then_resume_reaches_the_same_estimate(campaign):
    out, est = campaign
    env = {**os.environ, "SCENARIO_FARM_MIN_CHECKPOINT_S": "0"}
    args = ["estimate", str(out), "--config", str(est), "--runs", "30000", "--checkpoint-every", "0", "--quiet"]
    assert cli(*args, "--name", "whole", env=env).returncode == 0
    proc = subprocess.Popen([sys.executable, "-m", "farm", *args, "--name", "cut"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    segments = out / "estimates" / "cut" / "ledger"
    deadline = time.time() + 120
    while len(list(segments.glob("segment-*.parquet"))) < 4 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL  # killed before it finished
    assert not (out / "estimates" / "cut" / "estimate.json").exists()
    r = cli(*args, "--name", "cut", "--resume", env=env)
    assert r.returncode == 0, r.stderr
    whole, cut = (EstimateReport.read(out / "estimates" / n) for n in ("whole", "cut"))
    assert (cut.estimate, cut.interval, cut.strata, cut.stages) == (whole.estimate, whole.interval, whole.strata,
                                                                     whole.stages)
    assert _ledger(out / "estimates" / "cut").equals(_ledger(out / "estimates" / "whole"))


def test_same_estimate_on_one_and_two_ray_workers(campaign, ray_local):
    out, est = campaign
    reports = [api.estimate(out, est, name=f"{executor}-{w}", estimate__runs=3000, farm__executor=executor,
                            farm__workers=w) for executor, w in (("local", 1), ("ray", 1), ("ray", 2))]
    assert len({(r.estimate, tuple(r.interval), r.failures) for r in reports}) == 1
    assert _ledger(out / "estimates" / "ray-1").equals(_ledger(out / "estimates" / "ray-2"))


def test_relative_error_stops_at_the_first_stage_narrow_enough(campaign):
    out, est = campaign
    report = api.estimate(out, est, name="precise", estimate__runs=200_000, estimate__relative_error=0.25)
    assert report.stopped_by == "relative error" and report.runs < 200_000
    assert report.half_width <= 0.25 * report.estimate
    assert len(report.stages) >= 2


def test_two_controllers_on_the_same_runs_give_a_paired_difference(campaign):
    out, est = campaign
    r = cli("estimate", str(out), "--config", str(est), "--versus-sv-policy", "brake", "--runs", "4000", "--quiet")
    assert r.returncode == 0, r.stderr
    report = EstimateReport.read(out / "estimates" / "stratified-vs-brake")
    v = report.versus
    assert v["controller"] == "brake" and report.controller == "idm"
    d = v["difference"]
    assert d["estimate"] == pytest.approx(report.estimate - v["estimate"], abs=1e-12)
    assert d["pairing_gain"] > 1  # common random numbers: narrower than two separate intervals
    ledger = _ledger(out / "estimates" / "stratified-vs-brake")
    both = np.asarray(ledger.column("outcome").to_pylist()) == "failure"
    other = np.asarray(ledger.column("outcome_versus").to_pylist()) == "failure"
    assert d["runs_only_first_failed"] == int((both & ~other).sum())
    assert "difference idm - brake" in r.stdout


def test_no_failure_reads_as_the_n_eps_rule(campaign, tmp_path):
    out, _ = campaign
    safe = {"estimate": {"distribution": "axes", "runs": 3000, "axes": {
        "v0": {"law": "uniform", "low": 0.0, "high": 2.0}, "v1": {"law": "uniform", "low": 18.0, "high": 20.0},
        "p10": {"law": "uniform", "low": 50.0, "high": 60.0}}}}
    report = api.estimate(out, safe, name="safe-corner", estimate__strata="none")
    assert report.failures == 0 and report.interval[0] == 0.0
    bound = report.zero_failures["upper_bound"]
    assert bound == pytest.approx(1 - 0.05 ** (1 / 3000))
    assert "N_eps" in report.zero_failures["n_eps_reading"] and "3,000 runs" in report.zero_failures["n_eps_reading"]


def test_recorded_start_states_are_a_distribution(campaign, tmp_path):
    out, _ = campaign
    rng = np.random.default_rng(0)
    starts = {"v0": rng.uniform(10, 20, 800), "v1": rng.uniform(10, 20, 800), "p10": rng.uniform(5, 40, 800)}
    pq.write_table(pa.table(starts), tmp_path / "recorded.parquet")
    cfg = {"estimate": {"distribution": "empirical", "data": str(tmp_path / "recorded.parquet"), "runs": 2000}}
    report = api.estimate(out, cfg, name="recorded")
    assert report.distribution["kind"] == "empirical" and report.distribution["rows"] == 800
    assert sum(s["mass"] * 800 for s in report.strata) == pytest.approx(800)
    assert all(abs(s["mass"] * 800 - round(s["mass"] * 800)) < 1e-9 for s in report.strata)  # shares of the rows


@pytest.mark.parametrize("table, flags, field", [
    ('[estimate]\ndistribution = "axes"\naxes = { v0 = { law = "normal", mean = 60.0, std = 0.5 } }', (),
     "estimate.axes.v0: the normal law"),
    ('[estimate]\ndistribution = "axes"\naxes = { speed = { law = "uniform" } }', (), "estimate.axes.speed: unknown"),
    ('[estimate]\ndistribution = "axes"\naxes = { v0 = { law = "normal", mean = 10.0 } }', (),
     "estimate.axes.v0.std: required for law 'normal'"),
    ('[estimate]\ndistribution = "empirical"\ndata = "{recorded}"', (), "estimate.data: "),
    ("[estimate]\nruns = 1000", ("--relative-error", "2"), "--relative-error: 2.0 is out of range; allowed (0, 1)"),
    ('[scenario]\nname = "toy"', (), "estimate config: holds [scenario]"),
])
def test_bad_input_is_one_line_exit_2(campaign, tmp_path, table, flags, field):
    out, _ = campaign
    pq.write_table(pa.table({"v0": [1.0], "v1": [2.0]}), tmp_path / "recorded.parquet")  # no p10
    (tmp_path / "bad.toml").write_text(table.replace("{recorded}", str(tmp_path / "recorded.parquet")))
    r = cli("estimate", str(out), "--config", str(tmp_path / "bad.toml"), "--name", "bad", *flags)
    assert r.returncode == 2, r.stderr
    assert field in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (out / "estimates" / "bad").exists()  # refused before any file


def test_a_missing_parquet_column_is_named(campaign, tmp_path):
    out, _ = campaign
    pq.write_table(pa.table({"v0": [1.0], "v1": [2.0]}), tmp_path / "recorded.parquet")
    with pytest.raises(Exception, match=r"estimate.data: .*recorded.parquet lacks column\(s\) p10; needs one per "
                                        r"state variable: v0, v1, p10"):
        api.estimate(out, {"estimate": {"distribution": "empirical", "data": str(tmp_path / "recorded.parquet")}})
    assert json.loads((out / "summary.json").read_text())["scenario"] == "lead-follow"  # the campaign untouched


def test_the_unpaired_width_comes_from_standard_errors_not_from_an_interval_clipped_at_zero():
    # B failed once, on a run where A failed too: B's normal interval reaches below 0 and is
    # clipped, so half of it understates B's spread; pairing (the same runs) can only narrow
    # the difference here, and its gain is a ratio of standard errors
    from coordinator.estimation.intervals import difference_interval, rate_interval, z_value
    from farm.reports.estimate_report import _unpaired

    masses, runs = np.array([0.5, 0.5]), np.array([[2000, 2000]])
    a, b = np.array([[200, 30]]), np.array([[1, 0]])
    first, second = rate_interval(masses, runs, a, 0.95), rate_interval(masses, runs, b, 0.95)
    diff = difference_interval(masses, runs, a - b, np.zeros_like(b), 0.95)
    assert second.low == 0.0 and second.half_width < z_value(0.95) * second.standard_error  # clipped
    unpaired, gain = _unpaired(first, second, diff)
    se = np.hypot(first.standard_error, second.standard_error)
    assert unpaired == pytest.approx(z_value(0.95) * se) and unpaired > np.hypot(first.half_width, second.half_width)
    assert gain == pytest.approx(se / diff.standard_error) and gain > 1
