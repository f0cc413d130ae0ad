"""Resources and the smaller promises of a campaign: runaway configs refused before any
work, Ray in local mode private to this machine, temp files of dead writers removed on
resume, a set of another scenario refused, one damaged recording does not hide others."""

import os
import json
import resource
import subprocess
import sys

import numpy as np
import pytest
from small_campaign import lead_follow_toml

from coordinator.safe_set import SafeSet
from scenarios.registry import make_backend

LEAD_FOLLOW = lead_follow_toml()


def cli(*args, limit_gb=None, timeout=120):
    def cap():  # a runaway campaign dies of MemoryError here instead of swapping the machine
        resource.setrlimit(resource.RLIMIT_AS, (int(limit_gb * 2**30),) * 2)

    return subprocess.run([sys.executable, "-m", "farm", *args], capture_output=True, text=True, timeout=timeout,
                          preexec_fn=cap if limit_gb else None)


def one_line_error(r, *words):
    assert r.returncode == 2, r.stderr
    errors = [line for line in r.stderr.splitlines() if not line.startswith("scenario-farm: ") or "error" in line]
    assert len(errors) == 1 and "Traceback" not in r.stderr, r.stderr  # progress lines aside
    for w in words:
        assert w in r.stderr, r.stderr


@pytest.mark.parametrize("change, field", [
    ("delta_min = 2.0", "quantify.delta_min"),  # with delta_min = 1e-300 below
    ("delta0 = 4.0", "quantify.delta0"),  # with delta0 = 1e300 below
])
def test_runaway_quantification_is_refused_before_anything_is_written(tmp_path, change, field):
    value = "delta_min = 1e-300" if field.endswith("delta_min") else "delta0 = 1e300"
    (tmp_path / "c.toml").write_text(LEAD_FOLLOW.replace(change, value))
    r = cli("quantify", str(tmp_path / "c.toml"), "--out", str(tmp_path / "out"), limit_gb=2, timeout=60)
    one_line_error(r, field, "allowed")
    assert not (tmp_path / "out").exists()


def test_memory_estimate_names_the_limit_the_user_can_raise(tmp_path):
    # lead-follow (Sigma 20 x 20 x 70) at delta_min 0.125 may need 80*80*280 boxes: 1.8 GB
    text = LEAD_FOLLOW.replace("delta_min = 2.0", "delta_min = 0.125")
    (tmp_path / "c.toml").write_text(text + "max_memory_gb = 1.0\n")
    r = cli("quantify", str(tmp_path / "c.toml"), "--out", str(tmp_path / "out"))
    one_line_error(r, "quantify.delta_min", "farm.max_memory_gb")
    (tmp_path / "d.toml").write_text(text.replace("delta_min = 0.125", "delta_min = 1.0") + "max_memory_gb = 1.0\n")
    r = cli("quantify", str(tmp_path / "d.toml"), "--out", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("section, field", [
    ("algorithm = \"eps-delta\"\ndelta = 1000.0", "validate.delta"),
    ("algorithm = \"delta\"\ndelta = 1e-9", "validate.delta"),
])
def test_runaway_or_meaningless_validation_is_refused(tmp_path, section, field):
    (tmp_path / "v.toml").write_text(f'[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[validate]\n{section}\n'
                                     f'[farm]\nexecutor = "local"\n')
    one_line_error(cli("validate", str(tmp_path / "v.toml"), limit_gb=2, timeout=60), field, "allowed")


def test_a_degenerate_domain_is_decided_within_bounded_memory(tmp_path):
    (tmp_path / "v.toml").write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[validate]\n'
                                     'domain = { p10 = [30.0, 30.0000001] }\n[farm]\nexecutor = "local"\n')
    r = cli("validate", str(tmp_path / "v.toml"), "--json", limit_gb=3, timeout=90)
    assert r.returncode == 1, r.stderr  # a sliver of p10 is not invariant: a counterexample, quickly
    assert json.loads(r.stdout)["counterexample"]["reason"]


def test_a_set_of_another_scenario_is_refused_as_domain(tmp_path):
    # a fleet3 set as a fleet3 campaign writes it (the library's writer; the campaign itself
    # is tested elsewhere): its v0, v1, p10 mean other things than lead-follow's
    fleet3 = make_backend({"name": "fleet3", "sv_policy": "idm"}).scenario
    centres = (fleet3.lower + fleet3.upper)[None, :] / 2
    (tmp_path / "f").mkdir()
    SafeSet(centres, np.full_like(centres, 1.0), fleet3.state_names).to_parquet(tmp_path / "f" / "safe_set.parquet")
    (tmp_path / "v.toml").write_text(f'[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[validate]\n'
                                     f'domain_set = "{tmp_path / "f" / "safe_set.parquet"}"\ndelta = 2.0\n')
    one_line_error(cli("validate", str(tmp_path / "v.toml")), "another scenario")


def test_validate_out_that_is_not_ours_is_refused_before_the_runs(tmp_path):
    user = tmp_path / "project"
    user.mkdir()
    (user / "config.json").write_text("{}")
    (tmp_path / "v.toml").write_text('[scenario]\nname = "lead-follow"\nsv_policy = "brake"\n[validate]\n'
                                     'algorithm = "eps"\n[farm]\nexecutor = "local"\n')
    r = cli("validate", str(tmp_path / "v.toml"), "--out", str(user), "--force")
    one_line_error(r, "not a directory this tool wrote")
    assert (user / "config.json").read_text() == "{}" and len(list(user.iterdir())) == 1


def test_stale_temp_files_are_removed_on_resume_and_damaged_recordings_skipped(tmp_path, monkeypatch):
    monkeypatch.setenv("SCENARIO_FARM_MIN_CHECKPOINT_S", "0")  # a checkpoint, and recording, at every chunk
    (tmp_path / "c.toml").write_text(LEAD_FOLLOW + "checkpoint_every = 0.0\n[record]\nquantify_runs = 100000\n")
    out = tmp_path / "out"
    assert cli("quantify", str(tmp_path / "c.toml"), "--out", str(out)).returncode == 0
    # what a kill -9 or a full disk leaves: temp files of writers that are gone
    stale = [out / ".checkpoint.npz.tmp-999999999", out / "ledger" / ".segment-000001.parquet.tmp-1"]
    for p in stale:
        p.write_bytes(b"x" * 1000)
    (out / "summary.json").unlink()  # an unfinished campaign: resume opens it and finishes
    r = cli("resume", str(out))
    assert r.returncode == 0, r.stderr
    assert not any(p.exists() for p in stale)
    recordings = sorted((out / "recordings").glob("runs-*.mcap"))
    assert len(recordings) >= 2
    from farm.directory.recording import read_recording

    later = next(iter(read_recording(recordings[-1])["runs"]))
    recordings[0].write_bytes(b"damaged")
    r = cli("replay", str(out), "--sample", str(later))
    assert r.returncode == 0, r.stderr
    assert "trajectory" in r.stdout and recordings[0].name in r.stderr


def test_local_ray_listens_on_loopback_only():
    """... and is private whatever RAY_ADDRESS says: an address left in the environment (a
    shell's export, a test process that ran ray.init) is not joined by "local"."""
    code = """
import os, time, psutil, ray
from farm.ray_runtime.session import connect
connect("local", 2)
@ray.remote
def pid():
    return os.getpid()
ray.get([pid.remote() for _ in range(4)])
time.sleep(1.0)
procs = [psutil.Process()] + psutil.Process().children(recursive=True)
listening = []
for p in procs:
    try:
        listening += [c.laddr.ip for c in p.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]
    except psutil.NoSuchProcess:
        pass
print(len(procs), sorted(set(listening)), len(listening))
"""
    env = {**os.environ, "RAY_ADDRESS": "127.0.0.1:1"}  # nothing listens there
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=180, env=env)
    assert r.returncode == 0, r.stderr
    n_procs, rest = r.stdout.strip().split(" ", 1)
    addresses = eval(rest.rsplit(" ", 1)[0])  # the printed list of listening addresses
    assert int(n_procs) >= 4  # gcs, raylet, workers: the check looked at Ray's own processes
    assert addresses and set(addresses) <= {"127.0.0.1", "::1", "::ffff:127.0.0.1"}, addresses
    assert "Token authentication" not in r.stderr  # the banner is kept out of local-mode output


GAMMA_STAR = """
[scenario]
name = "lead-follow"
sv_policy = "idm"
[actions]
mode = "adversarial"
[quantify]
delta0 = 2.0
delta_min = 0.25
holdout_runs = 0
[farm]
executor = "local"
"""


def test_boundary_refinement_is_watched_as_it_runs_and_resumes_past_a_raised_limit(tmp_path):
    # margin refinement: the lattice at delta_min (the worst case, 6.3e5 boxes of 5 KB: 2.9 GB)
    # is not what it holds, so a 1 GB limit does not refuse it up front; the boxes it holds
    # pass 4 MB early: stopped, checkpointed, one line; a higher limit resumes it to the result
    # a run without the limit gives
    from farm.config import parse
    from farm.jobs.resources import check_quantify
    from scenarios.errors import ConfigError

    lead_follow = make_backend({"name": "lead-follow", "sv_policy": "idm"}).scenario
    fine = GAMMA_STAR.replace("delta_min = 0.25", "delta_min = 0.03125") + "max_memory_gb = 1.0\n"
    check_quantify(parse(fine), lead_follow.lower, lead_follow.upper)
    with pytest.raises(ConfigError, match="quantify.delta_min"):  # refined everywhere: the lattice is what it holds
        check_quantify(parse(fine.replace("holdout_runs = 0", "holdout_runs = 0\nrefine = \"all\"")),
                       lead_follow.lower, lead_follow.upper)
    (tmp_path / "c.toml").write_text(GAMMA_STAR + "max_memory_gb = 0.004\n")
    out = tmp_path / "out"
    r = cli("quantify", str(tmp_path / "c.toml"), "--out", str(out))
    one_line_error(r, "farm.max_memory_gb", "boxes", f"scenario-farm resume {out} --max-memory-gb")
    assert (out / "checkpoint.npz").exists() and not (out / "summary.json").exists()
    r = cli("resume", str(out), "--max-memory-gb", "2")
    assert r.returncode == 0, r.stderr
    (tmp_path / "d.toml").write_text(GAMMA_STAR)
    assert cli("quantify", str(tmp_path / "d.toml"), "--out", str(tmp_path / "d")).returncode == 0
    hashes = [json.loads((d / "summary.json").read_text())["result_hash"] for d in (out, tmp_path / "d")]
    assert hashes[0] == hashes[1]
