"""What a user sees while work runs: progress lines in job logs, --quiet, status --watch."""

import json
import subprocess
import sys
import time
from pathlib import Path

from small_campaign import lead_follow_toml


def test_progress_lines_reach_a_log_and_quiet_silences_them(tmp_path):
    (tmp_path / "c.toml").write_text(lead_follow_toml(delta_min=1.0))
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out",
                        str(tmp_path / "a"), "--verbose"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.startswith("scenario-farm: round")]
    rounds = {line.split()[2] for line in lines}
    assert {"0", "1", "2"} <= rounds, r.stderr  # a line at every round end at least
    assert all("boxes" in line and "runs/s" in line for line in lines)
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out",
                        str(tmp_path / "b"), "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stderr == "", r.stderr


def test_status_watch_follows_a_campaign_to_its_end(tmp_path):
    (tmp_path / "c.toml").write_text(lead_follow_toml(delta_min=0.5))
    out = tmp_path / "out"
    campaign = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out",
                                 str(out), "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not (out / "status.json").exists() and time.time() < deadline:
        time.sleep(0.05)
    watch = subprocess.run([sys.executable, "-m", "farm", "status", str(out), "--watch"], capture_output=True,
                           text=True, timeout=600)
    assert campaign.wait(60) == 0, campaign.stderr.read()
    assert watch.returncode == 0, watch.stderr
    assert "running" in watch.stdout and "runs_committed" in watch.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["result_hash"] in watch.stdout  # it followed to "done"


def test_resume_of_a_finished_campaign_says_so_and_touches_nothing(tmp_path):
    (tmp_path / "c.toml").write_text(lead_follow_toml(delta_min=2.0))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "startup_s" in json.loads((out / "summary.json").read_text())
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in out.rglob("*") if p.is_file()}
    r = subprocess.run([sys.executable, "-m", "farm", "resume", str(out)], capture_output=True, text=True)
    assert r.returncode == 0 and "has finished" in r.stdout, r.stderr
    assert {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in out.rglob("*") if p.is_file()} == before


def test_a_ray_campaign_ends_without_a_word_when_quiet(tmp_path):
    """At the last round end the chunks in flight are dropped but still running; ending
    the actors must not fail them (Ray then printed "Task SimWorker.run failed ... will be
    retried" at the end of every campaign of the README's main job)."""
    example = Path(__file__).resolve().parents[2] / "examples" / "lead_follow_idm.toml"
    config = tmp_path / "all.toml"  # refined everywhere: rounds whose ends drop chunks in flight
    config.write_text(example.read_text().replace("[quantify]\n", '[quantify]\nrefine = "all"\n', 1))
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(config), "--out", str(tmp_path / "out"),
                        "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr == "" and "failed" not in r.stdout, r.stdout + r.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["runs_simulated"] > summary["runs_committed"]  # chunks were dropped in flight
