"""Validation on the farm's executors, on set domains, and the status/progress displays."""

import io
import json
import subprocess
import sys


from farm import api
from farm.reports.progress import Progress


def verdicts(executor, section):
    return api.validate({"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
                         "validate": {**section, "algorithm": "eps-delta", "delta": 1.0},
                         "farm": {"executor": executor, "workers": 2, "seed": 3, "batch_size": 300}}).data


def test_validation_on_ray_gives_the_in_process_verdict(ray_local):
    section = {"domain": {"p10": [30.0, 70.0]}}
    local = verdicts("local", section)
    ray = verdicts("ray", section)
    assert local["verdict"] == ray["verdict"] == "counterexample"
    assert local["counterexample"] == ray["counterexample"] and local["n_run"] == ray["n_run"]


def test_a_quantified_set_validates_as_a_domain(tmp_path):
    cfg = tmp_path / "q.toml"
    cfg.write_text('[scenario]\nname = "toy"\nsv_policy = "none"\n[actions]\nmode = "uniform"\n'
                   '[quantify]\ndelta0 = 1.0\ndelta_min = 0.25\nepsilon = 0.01\nhorizon = 20\n'
                   '[farm]\nexecutor = "local"\n')
    assert subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(tmp_path / "q")],
                          capture_output=True).returncode == 0
    v = tmp_path / "v.toml"
    v.write_text(f'[scenario]\nname = "toy"\nsv_policy = "none"\n[actions]\nmode = "uniform"\n'
                 f'[validate]\nalgorithm = "eps-delta"\ndelta = 0.25\nepsilon = 0.01\n'
                 f'domain_set = "{tmp_path / "q" / "safe_set.parquet"}"\n')
    r = subprocess.run([sys.executable, "-m", "farm", "validate", str(v), "--json"], capture_output=True, text=True)
    cert = json.loads(r.stdout)
    # SPE's set is the two wells up to delta: the boxes overhanging a well by up to delta
    # are not invariant, so a counterexample is the right answer, and it must start in an
    # overhang (x outside the wells), never inside a well
    if cert["verdict"] == "counterexample":
        x = cert["counterexample"]["start_state"]["x"]
        assert not (1.0 <= x <= 4.0 or 6.0 <= x <= 9.0)
    assert r.returncode in (0, 1) and "union of" in cert["domain"]


def test_status_reports_a_killed_campaign_as_stopped(tmp_path):
    import os
    import signal
    import time

    cfg = tmp_path / "q.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[actions]\nmode = "uniform"\n'
                   '[quantify]\ndelta0 = 2.0\ndelta_min = 0.25\n[farm]\nexecutor = "local"\n')
    out = tmp_path / "q"
    proc = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(out),
                             "--checkpoint-every", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while not (out / "status.json").exists() and time.time() < deadline:
        time.sleep(0.2)
    running = subprocess.run([sys.executable, "-m", "farm", "status", str(out)], capture_output=True, text=True)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert "running (pid" in running.stdout and "N_eps" not in running.stderr
    stopped = subprocess.run([sys.executable, "-m", "farm", "status", str(out)], capture_output=True, text=True)
    assert "stopped while running (process gone" in stopped.stdout and "runs_committed" in stopped.stdout


def test_progress_lines_when_not_a_terminal_and_silence_when_quiet():
    from coordinator.driver import Campaign, CampaignSettings
    from coordinator.spe import SPE, SPESettings
    from scenarios import make_scenario

    algo = SPE(make_scenario("toy", sv_policy="none"), SPESettings(delta0=1.0, delta_min=1.0))
    c = Campaign(algo, None, CampaignSettings(epsilon=0.2, beta=0.1, budget=10, batch_size=1, pipeline_depth=1))
    assert c.n_eps == 11
    log = io.StringIO()  # not a terminal: plain lines, as a job log gets them
    Progress(stream=log).update("total", c)
    assert log.getvalue().startswith("scenario-farm: round 0") and "N_eps 0/11" in log.getvalue()
    Progress(stream=log).update("total", c)
    quiet = io.StringIO()
    Progress(stream=quiet, mode="quiet").update("total", c)
    Progress(enabled=False, stream=quiet).update("total", c)
    assert quiet.getvalue() == ""
