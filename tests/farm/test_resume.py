"""Checkpoint and resume with real processes, real SIGKILLs and real files."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from farm.directory.journal import Journal
from small_campaign import lead_follow_toml

CONFIG = lead_follow_toml(delta_min=1.0, epsilon=0.002, horizon=40, farm_extra="pipeline_depth = 2\nseed = 5\n")


def cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "farm", *args], capture_output=True, text=True, **kw)


def ledger_indices(directory):
    return np.sort(pq.read_table(directory / "ledger").column("sample_index").to_numpy())


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    d = tmp_path_factory.mktemp("whole")
    (d / "c.toml").write_text(CONFIG)
    r = cli("quantify", str(d / "c.toml"), "--out", str(d / "out"))
    assert r.returncode == 0, r.stderr
    return json.loads((d / "out" / "summary.json").read_text()), ledger_indices(d / "out")


def test_refuses_non_empty_directory_and_changed_config(tmp_path, uninterrupted):
    (tmp_path / "c.toml").write_text(CONFIG)
    out = tmp_path / "out"
    assert cli("quantify", str(tmp_path / "c.toml"), "--out", str(out)).returncode == 0
    before = (out / "summary.json").read_bytes()
    r = cli("quantify", str(tmp_path / "c.toml"), "--out", str(out))
    assert r.returncode == 2 and "not empty" in r.stderr and "--resume" in r.stderr
    (tmp_path / "d.toml").write_text(CONFIG.replace("epsilon = 0.002", "epsilon = 0.003"))
    r = cli("quantify", str(tmp_path / "d.toml"), "--out", str(out), "--resume")
    assert r.returncode == 2 and "quantify.epsilon" in r.stderr
    (tmp_path / "e.toml").write_text(CONFIG.replace('executor = "local"', 'executor = "local"\nworkers = 7'))
    assert cli("quantify", str(tmp_path / "e.toml"), "--out", str(out), "--resume").returncode == 0
    assert (out / "summary.json").read_bytes() != b"" and before


def stopped_campaign(tmp_path):
    """A campaign stopped by SIGINT after a few checkpoints (resumable, unfinished)."""
    (tmp_path / "c.toml").write_text(CONFIG.replace("delta_min = 1.0", "delta_min = 0.25"))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out", str(out),
                             "--checkpoint-every", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "SCENARIO_FARM_MIN_CHECKPOINT_S": "0"})
    deadline = time.time() + 60
    while not list((out / "ledger").glob("segment-00000[2-9].parquet")) and time.time() < deadline:
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(60) == 130, proc.stderr.read()
    assert not (out / "summary.json").exists()
    return out


@pytest.mark.parametrize("damage", ["truncate_checkpoint", "garbage_checkpoint", "truncate_segment",
                                    "drop_checkpoint"])
def test_damaged_campaign_files_give_a_clear_error_and_touch_nothing(tmp_path, damage):
    out = stopped_campaign(tmp_path)
    ckpt = out / "checkpoint.npz"
    seg = sorted((out / "ledger").glob("segment-*.parquet"))[0]
    if damage == "truncate_checkpoint":
        ckpt.write_bytes(ckpt.read_bytes()[: ckpt.stat().st_size // 2])
    elif damage == "garbage_checkpoint":
        ckpt.write_bytes(b"not a checkpoint")
    elif damage == "truncate_segment":
        seg.write_bytes(seg.read_bytes()[:100])
    else:
        ckpt.unlink()
    snapshot = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    r = cli("resume", str(out))
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == snapshot


class _Stopper:
    """A progress that stops the campaign at the first update where ``due`` says so, and
    keeps (phase, attempts, committed) of that moment in ``stopped``."""

    enabled = True
    stopped = None

    def due(self, campaign) -> bool:
        raise NotImplementedError

    def update(self, label, campaign):
        if self.stopped is None and self.due(campaign):
            c = campaign.counters
            self.stopped = (campaign.algorithm.phase, c.attempts, c.committed)
            campaign.stop()

    def line(self, text):
        pass

    def close(self):
        pass


class _StopIn(_Stopper):
    """At its first commit in a given certification phase (``closing``, or ``check``: a
    check after at least one failed one when there is one)."""

    def __init__(self, phase: str):
        self.phase = phase

    def due(self, campaign) -> bool:
        algo = campaign.algorithm
        return algo.certifying and algo.closing == (self.phase == "closing") and campaign.counters.quiet > 0


class _Lines(_Stopper):
    """Never stops; keeps the lines said."""

    def __init__(self):
        self.lines = []

    def due(self, campaign) -> bool:
        return False

    def line(self, text):
        self.lines.append(text)

    def close(self, ending=""):
        pass


@pytest.mark.parametrize("phase", ["closing", "check"])
def test_stopped_mid_certification_then_resumed_gives_the_uninterrupted_result(tmp_path, uninterrupted, phase,
                                                                                monkeypatch):
    # in-process (the committed sequence does not depend on the executor): stopped in a
    # closing round or in a check, with a checkpoint, then resumed from it
    from farm import config as config_mod
    from farm.jobs.quantification import Stopped, run

    cfg = config_mod.parse(CONFIG, "c.toml")
    stop = _StopIn(phase)
    with pytest.raises(Stopped):
        run(cfg, tmp_path / "out", progress=stop)
    assert stop.stopped is not None and stop.stopped[0] == phase, stop.stopped
    # the edge's distances are kept, not computed again from every centre
    arrays, _ = Journal(tmp_path / "out").load()
    assert {"algo.edge_reach.near", "algo.edge_reach.values"} <= set(arrays)
    monkeypatch.setattr("farm.jobs.side_campaign.LARGE_CHECKPOINT_MB", 0)  # a line before and after reading it
    said = _Lines()
    summary = run(cfg, tmp_path / "out", resume=True, progress=said)
    assert said.lines[0].startswith("reading the checkpoint (") and \
        said.lines[1].startswith("checkpoint read in ") and f"resuming at {stop.stopped[2]:,} committed" in said.lines[1]
    want, indices = uninterrupted
    assert summary["result_hash"] == want["result_hash"]
    assert summary["runs_committed"] == want["runs_committed"]
    assert summary["runs_certification"] == want["runs_certification"] > 0
    assert summary["certification_attempts"] == want["certification_attempts"] >= 1
    np.testing.assert_array_equal(ledger_indices(tmp_path / "out"), indices)


class _StopInCertification(_Stopper):
    """Once certification has committed ``after`` runs."""

    def __init__(self, after: int):
        self.after, self.start = after, None

    def due(self, campaign) -> bool:
        if campaign.algorithm.certifying and self.start is None:
            self.start = campaign.counters.committed
        return self.start is not None and campaign.counters.committed > self.start + self.after


def test_a_deterministic_certification_stopped_then_resumed_with_another_window_gives_the_same_result(tmp_path):
    """Gamma*: certification runs every centre once, handed out batch by batch; with
    sequential counting farm.batch_size and pipeline_depth may change on resume and
    change no result (coordinator/driver/pipeline.py ENUMERATION_BATCH)."""
    from farm import config as config_mod
    from farm.jobs.quantification import Stopped, run

    toml = lead_follow_toml(delta_min=1.0, epsilon=0.002, horizon=40, farm_extra="pipeline_depth = 2\nseed = 5\n")
    toml = toml.replace('mode = "uniform"', 'mode = "adversarial"').replace("[quantify]\n", '[quantify]\nrefine = "all"\n')
    cfg = config_mod.parse(toml, "c.toml")
    assert cfg.quantify.refine == "all"  # SPE's certification round, not margin refinement
    whole = run(cfg, tmp_path / "whole")
    stop = _StopInCertification(1000)
    with pytest.raises(Stopped):
        run(cfg, tmp_path / "out", progress=stop)
    assert stop.stopped is not None and stop.stopped[0] == "check", stop.stopped
    other = config_mod.parse(toml.replace("batch_size = 256", "batch_size = 64").replace("pipeline_depth = 2",
                                                                                        "pipeline_depth = 3"), "c.toml")
    summary = run(other, tmp_path / "out", resume=True)
    assert summary["result_hash"] == whole["result_hash"]
    assert summary["runs_committed"] == whole["runs_committed"]
    assert summary["runs_certification"] == whole["runs_certification"] > 1000
    np.testing.assert_array_equal(ledger_indices(tmp_path / "out"), ledger_indices(tmp_path / "whole"))


def test_a_kill_while_finishing_after_the_summary_is_finished_by_resume_without_running_again(tmp_path):
    """finish() writes the sets, then summary.json, then plots/, then status "done": a kill
    between summary.json and the figures leaves status "finishing" and no plots; resume
    draws them from the saved files and ends as the campaign would have (exit 0)."""
    from farm import config as config_mod
    from farm.jobs.quantification import run

    out = tmp_path / "out"
    one_round = lead_follow_toml(delta_min=4.0).replace("horizon = 30", "horizon = 30\nholdout_runs = 0")
    run(config_mod.parse(one_round, "c.toml"), out)
    figures = sorted(p.name for p in (out / "plots").iterdir())
    shutil.rmtree(out / "plots")
    status = json.loads((out / "status.json").read_text())
    (out / "status.json").write_text(json.dumps({"state": "finishing", "updated": status["updated"],
                                                 "started": status["started"]}))
    kept = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name not in ("status.json", ".lock")}
    assert "stopped while finishing" in cli("status", str(out)).stdout
    r = cli("resume", str(out))
    assert r.returncode == 0, r.stderr
    assert "nothing to resume" not in r.stdout and f"result_hash: {status['result_hash']}" in r.stdout
    assert sorted(p.name for p in (out / "plots").iterdir()) == figures
    assert json.loads((out / "status.json").read_text())["state"] == "done"
    # no run again: the summary, the sets, the ledger and the checkpoint are as they were
    assert {p: p.read_bytes() for p in kept} == kept
    again = cli("resume", str(out))
    assert again.returncode == 0 and "nothing to resume" in again.stdout


def test_a_kill_while_finishing_before_the_summary_is_finished_by_resume_with_the_same_holdout(tmp_path):
    """A kill after the last checkpoint and before summary.json: resume writes every result
    file again from the checkpoint, the holdout read back from holdout.json (not run
    again); without that file (killed before it was written) the same seeded runs again."""
    from farm import config as config_mod
    from farm.jobs.quantification import run

    out = tmp_path / "out"
    toml = lead_follow_toml(delta_min=4.0).replace("horizon = 30", "horizon = 30\nholdout_runs = 300")
    run(config_mod.parse(toml, "c.toml"), out)
    want = json.loads((out / "summary.json").read_text())
    assert want["holdout"]["runs"] == 300
    assert json.loads((out / "holdout.json").read_text())["report"] == want["holdout"]
    segments = {p: p.read_bytes() for p in (out / "ledger").glob("*.parquet")}

    def killed_before_the_summary():
        for name in ("summary.json", "safe_set.parquet"):
            (out / name).unlink()
        shutil.rmtree(out / "plots")
        (out / "status.json").write_text(json.dumps({"state": "finishing"}))

    for saved in (True, False):
        killed_before_the_summary()
        if not saved:
            (out / "holdout.json").unlink()
        r = cli("resume", str(out))
        assert r.returncode == 0, r.stderr
        said = r.stdout + r.stderr
        assert ("holdout: 300 runs read back from holdout.json" in said) == saved
        assert ("holdout: 300 fresh runs" in said) != saved  # simulated only without the file
        got = json.loads((out / "summary.json").read_text())
        assert got["result_hash"] == want["result_hash"] and got["holdout"] == want["holdout"]
        assert (out / "safe_set.parquet").exists() and any((out / "plots").iterdir())
        assert {p: p.read_bytes() for p in (out / "ledger").glob("*.parquet")} == segments  # no campaign run again
    killed_before_the_summary()
    (out / "holdout.json").write_text('{"config_hash": ')  # damaged: refused in one line naming it
    r = cli("resume", str(out))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "holdout.json: not valid JSON" in r.stderr, r.stderr


def test_figures_that_run_out_of_memory_lose_no_result_and_resume_draws_them(tmp_path, monkeypatch):
    """A drawing past its memory (a large set under ``ulimit -v``) ends in one line, exit 4,
    with the set and summary.json written; resume draws the figures."""
    from farm import api, lazy
    from farm.reports import plots
    from scenarios.errors import InfrastructureError

    config = tmp_path / "c.toml"
    config.write_text(lead_follow_toml())
    out = tmp_path / "out"

    def out_of_memory(*args, **kwargs):
        raise MemoryError  # what numpy raises past RLIMIT_AS

    monkeypatch.setattr(lazy, "plots", type(sys)("plots_out_of_memory"), raising=False)
    lazy.plots.draw = out_of_memory
    with pytest.raises(InfrastructureError, match=r"out of memory while drawing .*summary\.json are written; "
                                                  r"resume draws the figures"):
        api.quantify(str(config), out)
    assert (out / "safe_set.parquet").is_file() and (out / "summary.json").is_file()
    assert not (out / "plots").exists()
    assert json.loads((out / "status.json").read_text())["state"] == "finishing"
    monkeypatch.setattr(lazy, "plots", plots)
    r = subprocess.run([sys.executable, "-m", "farm", "resume", str(out), "--quiet"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (out / "plots").iterdir())  # drawn
    assert json.loads((out / "status.json").read_text())["state"] == "done"
