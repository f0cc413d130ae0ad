"""Hostile user scenario code (issue 54 point 5): a user's per-run simulator or scenario
that raises, calls sys.exit, hangs in any of its methods or lacks one. Each ends as the
exit table says, in one line naming the user's class and method (never the scenario it
simulates, never a traceback), and never leaves a finished campaign: exit 2 for the
user's code raising (sys.exit too), exit 4 within farm.chunk_timeout for a hang (the
first run and close() too). Real CLI processes on a tiny campaign (a few seconds each)."""

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

TESTS = Path(__file__).resolve().parents[1]  # per_run_simulators.py, user_scenarios.py: imported from the cwd
TINY = "[quantify]\ndelta0 = 8.0\ndelta_min = 8.0\nepsilon = 0.05\nhorizon = 10\nholdout_runs = 0\n" \
       "[farm]\nexecutor = \"local\"\nbatch_size = 64\nchunk_timeout = 1.0\n"


def per_run(backend: str) -> str:
    return f'[scenario]\nname = "lead-follow"\nbackend = "per_run_simulators:{backend}"\n' + TINY


def quantify(tmp_path, text):
    (tmp_path / "c.toml").write_text(text)
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out",
                        str(tmp_path / "out"), "--quiet"], capture_output=True, text=True, cwd=TESTS, timeout=120)
    return r, time.monotonic() - t0


def one_line(r, code, *words):
    assert r.returncode == code, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr and "Exception ignored" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert "'lead-follow'" not in lines[0]  # the user's class is named, not the scenario it simulates


@pytest.mark.parametrize("text, words", [
    (per_run("Unfinished"), ["scenario.backend: 'per_run_simulators:Unfinished' (class Unfinished) does not "
                             "implement step"]),
    (per_run("RaisesInStep"), ["per_run_simulators:RaisesInStep.step() raised ValueError: sim boom on sample index"]),
    (per_run("ExitsInStep"), ["per_run_simulators:ExitsInStep.step() raised SystemExit: 0 on sample index"]),
    (per_run("RaisesInClose"), ["per_run_simulators:RaisesInClose.close() raised RuntimeError: the licence server"]),
    ('[scenario]\nname = "user_scenarios:ExitsInStep"\nsv_policy = "idm"\n' + TINY,
     ["scenario 'user_scenarios:ExitsInStep': step_into() raised SystemExit: 0 on sample index"]),
], ids=["no_step", "step_raises", "step_sys_exit", "close_raises", "vectorized_sys_exit"])
def test_user_code_that_raises_or_exits_is_the_users_error_in_one_line(tmp_path, text, words):
    r, _ = quantify(tmp_path, text)
    one_line(r, 2, *words)
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.parametrize("backend, words", [
    ("HangsInReset", ["per_run_simulators:HangsInReset.reset() on sample index 0 (start state", "within 1 s"]),
    ("HangsInStep", ["per_run_simulators:HangsInStep.step() on sample index 0 (start state", "within 1 s"]),
    ("HangsInClose", ["per_run_simulators:HangsInClose.close() did not finish within 1 s"]),
])
def test_a_hang_in_any_user_method_ends_with_exit_4_within_the_limit(tmp_path, backend, words):
    """The first run (nothing timed yet) and close() too: the config check closes the back
    end it built, before the campaign directory exists."""
    r, took = quantify(tmp_path, per_run(backend))
    one_line(r, 4, *words)
    assert took < 30, f"{took:.1f} s"
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_close_that_raises_at_exit_is_one_line_however_many_simulators():
    """close() left to interpreter exit (three back ends built): one warning line, not a
    traceback per object."""
    code = ("from scenarios.registry import make_backend\n"
            "keep = [make_backend({'name': 'lead-follow', 'backend': 'per_run_simulators:RaisesInClose'}) "
            "for _ in range(3)]\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=TESTS, timeout=60)
    assert r.returncode == 0 and r.stderr.strip() == (
        "scenario-farm: warning: per_run_simulators:RaisesInClose.close() raised RuntimeError: the licence server "
        "went away"), r.stderr


def test_on_ray_a_hung_step_gives_up_after_max_retries_naming_the_run(ray_local):
    from farm.execution.waiting import WorkerError
    from farm.ray_runtime.executor import RayExecutor
    from scenarios.simulator import SimSpec

    spec = SimSpec({"name": "lead-follow", "backend": "per_run_simulators:HangsInStep"}, {"mode": "uniform"}, 10, 0)
    ex = RayExecutor(spec, 2, "local", max_retries=1, chunk_timeout=1.5).start()
    t0 = time.monotonic()
    try:
        with pytest.raises(WorkerError, match=r"back end 'per_run_simulators:HangsInStep': sample index 7 "
                                              r"\(start state .* \(hung in per_run_simulators:HangsInStep.step\(\) "
                                              r"on sample index 7 .* 2 times, on a different worker each time"):
            for handle in ex.submit(7, np.array([[10.0, 10.0, 40.0]])):
                ex.result(handle)
    finally:
        ex.close()
    assert time.monotonic() - t0 < 60
