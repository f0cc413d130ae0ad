"""Ray failing under a real CLI campaign (issue 34 points 3 and 4): each ends with one line
of ours and its exit code, and no Ray process outlives the driver.

- a user scenario that raises on a Ray worker: exit 2, our line, not Ray's traceback;
- the raylet killed mid-campaign: exit 4 (not 1, Ray's own exit), our line, no Ray log
  lines; `resume` then finishes with the uninterrupted result;
- the driver killed with kill -9: every Ray process it started is gone within seconds;
- a finished campaign, which ends its process at once (farm/ray_runtime/session.py ``exit_process``):
  its output and files whole, and no Ray process it started outlives it by more than seconds;
- SIGTERM while Ray starts: exit 130 and a "stopped" line.
The exit-code table of README.md is the CLI's (farm/cli/exits.py).
"""

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from small_campaign import lead_follow_toml

ROOT = Path(__file__).resolve().parents[2]
TESTS = ROOT / "tests"
RAY_LOG_LINE = re.compile(r"^\[\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} [DIWEF] \d+ \d+\] ", re.M)
# a few seconds of campaign on two Ray workers: long enough to be hit while it runs
CAMPAIGN = lead_follow_toml(delta_min=0.5, epsilon=0.002, horizon=40, executor="ray", farm_extra="workers = 2\n")
# run to its end: coarser, with a fifth of the runs per centre
SHORT_CAMPAIGN = lead_follow_toml(delta_min=1.0, epsilon=0.01, horizon=40, executor="ray", farm_extra="workers = 2\n")


def popen(*args):
    return subprocess.Popen([sys.executable, "-m", "farm", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=TESTS)


def descendants(proc) -> list[psutil.Process]:
    try:
        return psutil.Process(proc.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def wait_for(proc, ready, timeout=300):
    """Poll the driver's process tree until ``ready(processes)``; -> the processes."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        procs = descendants(proc)
        if ready(procs):
            return procs
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    pytest.fail("the campaign did not get there in time")


def named(procs, name):
    return [p for p in procs if _name(p).startswith(name)]


def _name(p) -> str:
    try:
        return p.name()
    except psutil.NoSuchProcess:  # a short-lived child that ended after it was listed
        return ""


def running(proc, config):
    """The two SimWorker actors are up and the campaign has committed runs."""
    out = Path(config).parent / "out"

    def ready(procs):
        if len(named(procs, "ray::SimWorker")) < 2:
            return False
        try:
            return json.loads((out / "status.json").read_text()).get("runs_committed", 0) > 0
        except (OSError, ValueError):
            return False
    return wait_for(proc, ready)


def alive(procs):
    out = []
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


def our_line_only(stderr: str, prefix: str, *words):
    lines = [line for line in stderr.splitlines() if prefix in line or "error" in line]
    assert len(lines) == 1 and lines[0].startswith(prefix), stderr
    assert "Traceback" not in stderr and "Unhandled error" not in stderr and not RAY_LOG_LINE.search(stderr), stderr
    for w in words:
        assert w in stderr, stderr


def test_a_scenario_that_raises_on_a_ray_worker_is_our_one_line_not_rays_traceback(tmp_path):
    (tmp_path / "c.toml").write_text('[scenario]\nname = "user_scenarios:Raising"\n[quantify]\ndelta0 = 0.25\n'
                                     'delta_min = 0.125\nepsilon = 0.01\nhorizon = 5\n'
                                     '[farm]\nexecutor = "ray"\nworkers = 2\nbatch_size = 256\n')
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    _, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 2, stderr
    our_line_only(stderr, "scenario-farm: error: ",
                  "scenario 'user_scenarios:Raising': step() raised ValueError: boom on sample index")


@pytest.mark.soak  # ~2.5 min; CI keeps kill -9 of the driver, a killed worker and a lost worker node's cluster
def test_a_killed_raylet_ends_with_our_line_and_exit_4_then_resume_finishes(tmp_path):
    (tmp_path / "c.toml").write_text(CAMPAIGN)
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    procs = running(proc, tmp_path / "c.toml")
    named(procs, "raylet")[0].kill()
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 4, stderr
    our_line_only(stderr, "scenario-farm: infrastructure error: ", "raylet", f"resume {tmp_path / 'out'}")
    assert not (tmp_path / "out" / "summary.json").exists()
    resumed = subprocess.run([sys.executable, "-m", "farm", "resume", tmp_path / "out", "--executor", "local",
                              "--quiet"], capture_output=True, text=True, timeout=900)
    assert resumed.returncode == 0, resumed.stderr
    whole = subprocess.run([sys.executable, "-m", "farm", "quantify", tmp_path / "c.toml", "--out",
                            tmp_path / "whole", "--executor", "local", "--quiet"], capture_output=True, text=True,
                           timeout=900)
    assert whole.returncode == 0, whole.stderr
    got, want = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("out", "whole"))
    assert got["result_hash"] == want["result_hash"]


def test_kill_9_of_the_driver_leaves_no_ray_process_behind(tmp_path):
    (tmp_path / "c.toml").write_text(CAMPAIGN)
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    procs = running(proc, tmp_path / "c.toml")
    assert named(procs, "ray::DashboardAgent") or named(procs, "ray::RuntimeEnvAgent")  # they outlived it by 60 s
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10  # "within seconds", on a loaded machine
    while alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(procs), [(p.pid, p.name()) for p in alive(procs)]


@pytest.mark.soak  # a Ray start; the reaper's start-up guard (farm/ray_runtime/reaper.py --starting)
def test_kill_9_of_the_driver_while_ray_starts_leaves_no_agent_behind(tmp_path):
    """The reaper that watches the raylet starts once ray.init returns: a kill -9 before
    that left ray::DashboardAgent and ray::RuntimeEnvAgent running."""
    (tmp_path / "c.toml").write_text(CAMPAIGN)
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    procs = wait_for(proc, lambda ps: bool(named(ps, "raylet")))  # ray.init is under way
    deadline = time.monotonic() + 2  # the agents, if they come before ray.init returns
    while not named(procs, "ray::RuntimeEnvAgent") and time.monotonic() < deadline:
        procs = list({p.pid: p for p in procs + descendants(proc)}.values())
        time.sleep(0.02)
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(procs), [(p.pid, p.name()) for p in alive(procs)]


def test_a_finished_campaign_exits_whole_and_leaves_no_ray_process_behind(tmp_path):
    (tmp_path / "c.toml").write_text(SHORT_CAMPAIGN)
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    procs = running(proc, tmp_path / "c.toml")
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert f"result_hash: {summary['result_hash']}" in stdout  # the last lines came out before the exit
    assert stdout.rstrip().splitlines()[-1].lstrip().startswith("results: "), stdout
    deadline = time.monotonic() + 10
    while alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(procs), [(p.pid, p.name()) for p in alive(procs)]


def test_sigterm_while_ray_starts_exits_130_with_a_stopped_line(tmp_path):
    (tmp_path / "c.toml").write_text(CAMPAIGN)
    proc = popen("quantify", tmp_path / "c.toml", "--out", tmp_path / "out")
    procs = wait_for(proc, lambda ps: bool(named(ps, "gcs_server")))  # ray.init is under way
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "stopped" in stderr and "Traceback" not in stderr, stderr
    procs += descendants(proc)
    deadline = time.monotonic() + 10
    while alive(procs) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(procs)


def test_the_readme_and_help_show_the_exit_code_table_of_the_cli():
    from farm.cli.exits import TABLE

    readme = (ROOT / "README.md").read_text()
    rows = re.findall(r"^\| (\d+) \| (.+) \|$", readme.split("## Exit codes and errors")[1].split("\n## ")[0], re.M)
    assert [(int(code), text) for code, text in rows] == list(TABLE)
    helped = subprocess.run([sys.executable, "-m", "farm", "--help"], capture_output=True, text=True)
    for code, text in TABLE:
        assert f"{code:>3}  {text.split(':')[0]}" in helped.stdout, helped.stdout
