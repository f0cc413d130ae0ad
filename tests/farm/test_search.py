"""actions.mode = "search": the adversary search (scenarios/search.py,
coordinator/adversary.py) under the parallel contract, resume, replay and falsify."""

import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from coordinator.adversary import AdversarySearch
from farm import config as config_mod
from farm.jobs.quantification import run
from scenarios.base import FAILURE
from scenarios.lead_follow import LeadFollow
from scenarios.fleet3 import Fleet3
from scenarios.rollout import run_scenario
from scenarios.search import SearchActions
from scenarios.streams import RunStreams
from small_campaign import lead_follow_toml

SEARCH_TOML = lead_follow_toml(delta_min=1.0, epsilon=0.005, horizon=40,
                               farm_extra="pipeline_depth = 2\nseed = 3\n").replace('mode = "uniform"', 'mode = "search"')


def cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "farm", *args], capture_output=True, text=True, **kw)


# -- the mixture ----------------------------------------------------------------------------
def _actions(policy, scenario, indices, steps=30, seed=7):
    starts = np.tile((scenario.lower + scenario.upper) / 2, (len(indices), 1))
    out = []
    for t in range(1, steps):
        out.append(policy(scenario, starts, t, RunStreams.of(seed, np.asarray(indices, dtype=np.uint64))))
    return np.stack(out, axis=1)  # (B, steps - 1, m)


def test_a_runs_actions_depend_on_its_key_and_the_schedule_only():
    sc = Fleet3("idm")
    policy = SearchActions(sc)
    batch = _actions(policy, sc, np.arange(500))
    alone = np.concatenate([_actions(policy, sc, [i]) for i in (0, 137, 499)])
    np.testing.assert_array_equal(batch[[0, 137, 499]], alone)
    # an appended entry changes the runs after it, never those before (replay stays exact)
    policy.append(300, [0.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # all weight on vertex (-5, -3)
    again = _actions(policy, sc, np.arange(500))
    np.testing.assert_array_equal(again[:300], batch[:300])
    np.testing.assert_array_equal(again[300:], np.broadcast_to([-5.0, -3.0], again[300:].shape))


def test_every_family_stays_in_gamma_and_has_its_shape():
    sc = LeadFollow("idm")
    policy = SearchActions(sc)
    acts = _actions(policy, sc, np.arange(4000))[:, :, 0]
    fam = policy.family_of(RunStreams.of(7, np.arange(4000, dtype=np.uint64)))
    labels = [f.label() for f in policy.families]
    assert labels == ["uniform", "vertex -5", "vertex 3", "bang-bang"]
    assert (acts >= -5).all() and (acts <= 3).all()
    counts = np.bincount(fam.astype(int), minlength=4)
    assert (np.abs(counts - 1000) < 150).all()  # equal initial weights
    assert (acts[fam == 1] == -5).all() and (acts[fam == 2] == 3).all()
    bang = acts[fam == 3]
    assert np.isin(bang, (-5.0, 3.0)).all()
    switches = (np.diff(bang, axis=1) != 0).sum(axis=1)
    assert switches.max() > 3 and (switches == 0).any()  # short and long dwell times
    uni = acts[fam == 0]
    assert len(np.unique(uni)) > 0.9 * uni.size  # continuous, i.i.d. over steps


def test_the_update_moves_weight_to_the_family_that_fails_and_is_pure():
    def adapted():
        sc = LeadFollow("idm")
        search = AdversarySearch(SearchActions(sc), seed=1)
        idx = np.arange(20_000)
        fam = search.policy.family_of(RunStreams.of(1, idx.astype(np.uint64)))
        outcomes = np.where((fam == 1) & (idx % 3 == 0), FAILURE, 0)  # "vertex -5" fails a third of the time
        search.observe(idx, outcomes)
        return search, search.end_round(20_000)

    search, weights = adapted()
    assert np.argmax(weights) == 1 and weights[1] > 0.5 and min(weights) >= 0.04 - 1e-12
    assert adapted()[1] == weights  # a function of the observed runs alone
    report = search.report(LeadFollow("idm"))
    assert report["proposed_gamma_star"]["actions"] == [[-5.0]]
    assert report["families"][1]["failure_share"] == 1.0


def test_before_any_round_end_the_proposal_reads_the_first_rounds_runs_and_changes_nothing():
    sc = LeadFollow("idm")
    search = AdversarySearch(SearchActions(sc), seed=1)
    idx = np.arange(8_000)
    fam = search.policy.family_of(RunStreams.of(1, idx.astype(np.uint64)))
    search.observe(idx, np.where((fam == 1) & (idx % 4 == 0), FAILURE, 0))  # no round end yet
    before = search.state()
    report = search.report(sc)
    assert [f["weight"] for f in report["families"]] == [0.25] * 4  # what the round sampled
    evidence = [f["evidence_weight"] for f in report["families"]]
    assert np.argmax(evidence) == 1 and evidence[1] >= 0.5 and abs(sum(evidence) - 1) < 1e-12
    assert report["proposed_gamma_star"]["actions"] == [[-5.0]]
    assert report["proposed_gamma_star"]["z_over_runner_up"] > 10  # ~500 failures against none
    after = search.state()
    assert all(np.array_equal(before[k], after[k]) for k in before)  # reporting changed no state
    assert search.report(sc) == report
    # once a round ended, the proposal reads the latest update: a later round's runs are
    # not folded in (the set was pruned against the leader, so it fails less there)
    search.end_round(8_000)
    search.observe(np.arange(8_000, 9_000), np.zeros(1_000))
    later = search.report(sc)
    assert [f["evidence_weight"] for f in later["families"]] == [f["weight"] for f in later["families"]]
    assert later["proposed_gamma_star"]["actions"] == [[-5.0]]


def test_no_proposal_when_no_vertex_family_stands_out():
    sc = LeadFollow("idm")
    search = AdversarySearch(SearchActions(sc), seed=1)
    idx = np.arange(8_000)
    search.observe(idx, np.where(idx % 50 == 0, FAILURE, 0))  # every family fails alike
    report = search.report(sc)
    assert report["proposed_gamma_star"] is None
    assert max(f["evidence_weight"] for f in report["families"]) < 0.5


# -- campaigns ------------------------------------------------------------------------------
def search_config(executor="local", workers=2):
    raw = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "search"},
           "quantify": {"delta0": 4.0, "delta_min": 1.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30},
           "farm": {"executor": executor, "workers": workers, "batch_size": 128, "pipeline_depth": 3, "seed": 11}}
    return config_mod.normalize(raw)


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    out = tmp_path_factory.mktemp("search") / "c"
    return run(search_config(), out, resume=False), out


def test_search_campaign_finds_the_papers_gamma_star_and_names_its_mixture(in_process):
    summary, out = in_process
    adversary = json.loads((out / "adversary.json").read_text())
    assert adversary["proposed_gamma_star"]["actions"] == [[-5.0]]  # the lead brakes hardest
    assert len(adversary["schedule"]) == summary["rounds"]  # one mixture per round
    final = adversary["schedule"][-1][1]
    # the guarantee is about the mixture the last round sampled, with its weights
    assert "search mixture" in summary["guarantee"]
    assert f"{100 * max(final):.3g}% the lead vehicle's acceleration at -5 m/s^2" in summary["guarantee"]
    assert summary["actions"].startswith("search mixture (") and f"vertex -5 {final[1]:.3f}" in summary["actions"]


@pytest.mark.soak  # CI keeps the search in-process, and Ray's result = in-process for SPE's other modes
@pytest.mark.parametrize("workers", [2])
def test_ray_gives_the_in_process_search_result(ray_local, in_process, tmp_path, workers):
    summary, out = in_process
    other = run(search_config("ray", workers), tmp_path / "c", resume=False)
    assert other["result_hash"] == summary["result_hash"]
    assert other["runs_committed"] == summary["runs_committed"]
    assert json.loads((tmp_path / "c" / "adversary.json").read_text()) == json.loads(
        (out / "adversary.json").read_text())


@pytest.mark.soak  # a kill -9 chain (minutes); the local interrupt chain runs in CI
def test_kill_9_mid_campaign_then_resume_gives_the_same_search(tmp_path):
    # one round finer than SEARCH_TOML: ~6 s of campaign, so that it is still running
    # when the kill comes (at delta_min 1 it can end within one status write)
    (tmp_path / "c.toml").write_text(SEARCH_TOML.replace("delta_min = 1.0", "delta_min = 0.5"))
    whole = cli("quantify", str(tmp_path / "c.toml"), "--out", str(tmp_path / "whole"), "--quiet")
    assert whole.returncode == 0, whole.stderr
    out = tmp_path / "cut"
    proc = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out", str(out),
                             "--checkpoint-every", "0", "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.time() + 120
    # killed once the mixture was re-weighted at least once (a round ended)
    while time.time() < deadline and proc.poll() is None:
        try:
            if json.loads((out / "status.json").read_text()).get("round", 0) >= 1:
                break
        except (FileNotFoundError, ValueError):
            pass
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(30)
    assert not (out / "summary.json").exists(), "the campaign ended before it was killed"
    status = cli("status", str(out))
    assert "search mixture: uniform 0." in status.stdout and "bang-bang 0." in status.stdout, status.stdout
    r = cli("resume", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    a, b = (json.loads((d / "summary.json").read_text()) for d in (tmp_path / "whole", out))
    assert a["result_hash"] == b["result_hash"] and a["runs_committed"] == b["runs_committed"]
    assert (json.loads((tmp_path / "whole" / "adversary.json").read_text())
            == json.loads((out / "adversary.json").read_text()))


def test_a_one_round_campaign_samples_its_first_mixture_and_proposes_from_its_runs(tmp_path):
    raw = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "search"},
           "quantify": {"delta0": 1.0, "delta_min": 1.0, "epsilon": 0.005, "beta": 0.1, "horizon": 40,
                        "certify": False},
           "farm": {"executor": "local", "batch_size": 256, "pipeline_depth": 2, "seed": 3}}
    summary = run(config_mod.normalize(raw), tmp_path / "c", resume=False)
    adversary = json.loads((tmp_path / "c" / "adversary.json").read_text())
    assert summary["rounds"] == 1 and adversary["rounds"] == []  # no round end: no update
    assert adversary["schedule"] == [[0, [0.25] * 4]]
    assert "25% the lead vehicle's acceleration at -5 m/s^2" in summary["guarantee"]  # what was sampled
    assert adversary["proposed_gamma_star"]["actions"] == [[-5.0]]  # what its runs point at


def test_replay_of_a_search_run_uses_the_schedule(in_process):
    summary, out = in_process
    last_round = json.loads((out / "adversary.json").read_text())["schedule"][-1][0]
    for sample in (5, last_round + 3):  # first mixture, last mixture
        r = cli("replay", str(out), "--sample", str(sample))
        assert r.returncode == 0 and "replay matches the record" in r.stdout, r.stdout + r.stderr


def test_falsify_keeps_the_true_worst_case_and_refutes_a_wrong_one(in_process):
    _, out = in_process
    r = cli("falsify", str(out), "--points", "3000")
    assert r.returncode == 0 and "not refuted" in r.stdout, r.stdout + r.stderr
    assert json.loads((out / "falsify.json").read_text())["gamma_star"] == [-5.0]
    r = cli("falsify", str(out), "--points", "3000", "--gamma-star", "3")
    assert r.returncode == 1 and "REFUTED" in r.stdout
    report = json.loads((out / "falsify.json").read_text())
    assert report["refuted"] and report["failures"] == len(report["counterexamples"]) > 0
    # a counterexample is reproduced from its key: the same policy, start and stream fail
    sc = LeadFollow("idm")
    ce = report["counterexamples"][0]
    policy = SearchActions(sc)
    policy.append(0, np.array([1.0, 1.0, 0.0, 1.0]) / 3)  # what falsify runs: every family but Gamma* = {3}
    batch = run_scenario(sc, np.array([ce["start"]]), report["horizon"], policy,
                         RunStreams.of(ce["key"]["seed"], [ce["key"]["index"]]))
    assert batch.outcomes[0] == FAILURE and batch.lengths[0] - 1 == ce["steps"]
    assert (out / "falsify.mcap").stat().st_size > 0


def test_falsify_errors_name_the_field(in_process, tmp_path):
    _, out = in_process
    r = cli("falsify", str(out), "--gamma-star", "9")
    assert r.returncode == 2 and "--gamma-star: u1 = 9 outside Gamma; allowed range [-5, 3]" in r.stderr
    r = cli("falsify", str(out), "--points", "0")
    assert r.returncode == 2 and "--points" in r.stderr and "allowed" in r.stderr
    (tmp_path / "c.toml").write_text(lead_follow_toml())
    assert cli("quantify", str(tmp_path / "c.toml"), "--out", str(tmp_path / "u"), "--quiet").returncode == 0
    r = cli("falsify", str(tmp_path / "u"))
    assert r.returncode == 2 and "no adversary.json" in r.stderr and "--gamma-star" in r.stderr
