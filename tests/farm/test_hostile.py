"""Hostile inputs: every case is a real CLI process on real files, and must end with one
line `scenario-farm: error: ...` and exit 2 (never a traceback), and touch nothing that
is not ours; a full disk is the machine's fault (exit 4). The module grows with every
bug found (issue 34: the tables of configs and of damaged campaign directories)."""

import json
import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from pathlib import Path

from small_campaign import lead_follow_toml

GOOD = lead_follow_toml()
TESTS = Path(__file__).resolve().parents[1]  # user_scenarios.py: 'module:name' imports from the working directory
LF = '[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n'
PREFIX = {2: "scenario-farm: error: ", 4: "scenario-farm: infrastructure error: "}
EVERY_CHUNK = {**os.environ, "SCENARIO_FARM_MIN_CHECKPOINT_S": "0"}  # checkpoint_every = 0 as asked: many segments


def cli(*args, cwd=None, preexec_fn=None, timeout=120, env=None):
    return subprocess.run([sys.executable, "-m", "farm", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, preexec_fn=preexec_fn, timeout=timeout, env=env)


def one_line_error(r, *words, code=2):
    assert r.returncode == code, (r.returncode, r.stdout, r.stderr)
    lines = [line for line in r.stderr.strip().splitlines()  # progress lines and warnings aside
             if not line.startswith("scenario-farm: ") or "error" in line]
    assert len(lines) == 1 and lines[0].startswith(PREFIX[code]) and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in r.stderr, r.stderr


def snapshot(d):
    return {p: p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture
def config(tmp_path):
    (tmp_path / "c.toml").write_text(GOOD)
    return tmp_path / "c.toml"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A finished small campaign to damage (copied per test)."""
    d = tmp_path_factory.mktemp("campaign")
    (d / "c.toml").write_text(GOOD + "checkpoint_every = 0.0\n")
    r = cli("quantify", d / "c.toml", "--out", d / "out", env=EVERY_CHUNK)
    assert r.returncode == 0, r.stderr
    return d / "out"


def copy_of(campaign, tmp_path, unfinished=True):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(campaign, out)
    if unfinished:
        (out / "summary.json").unlink()  # resume then reads everything again
    return out


# -- 1. data loss: --force and --out only ever touch directories this tool wrote ------------
def test_force_refuses_a_user_directory_with_a_config_json(config, tmp_path):
    user = tmp_path / "project"
    (user / "src").mkdir(parents=True)
    for name, text in (("config.json", "{}"), ("main.py", "print(1)"), ("src/a.py", "x = 1")):
        (user / name).write_text(text)
    before = snapshot(user)
    one_line_error(cli("quantify", config, "--out", user, "--force"), "not a directory this tool wrote")
    assert snapshot(user) == before


def test_validate_out_into_a_campaign_directory_is_refused(config, campaign, tmp_path):
    out = copy_of(campaign, tmp_path, unfinished=False)
    before = snapshot(out)
    (tmp_path / "v.toml").write_text(GOOD.replace("[quantify]", "[validate]\nalgorithm = \"eps\"\n[quantify]"))
    one_line_error(cli("validate", tmp_path / "v.toml", "--out", out, "--force"), "quantify directory")
    assert snapshot(out) == before


# -- 2. two writers ----------------------------------------------------------------------------
def test_a_second_writer_is_refused_naming_the_holder(tmp_path):
    # long enough (~40 s here) that three CLI calls always find it running
    (tmp_path / "c.toml").write_text(GOOD.replace("delta_min = 2.0", "delta_min = 0.25")
                                     .replace("epsilon = 0.01", "epsilon = 0.0005"))
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out", str(out)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 60
        while not (out / "status.json").exists() and time.time() < deadline:  # written as it starts
            time.sleep(0.05)
        for args in (["quantify", tmp_path / "c.toml", "--out", out, "--force"],
                     ["quantify", tmp_path / "c.toml", "--out", out, "--resume"], ["resume", out]):
            one_line_error(cli(*args), f"pid {first.pid}")
        assert first.poll() is None  # the first writer runs on, untouched
    finally:
        first.send_signal(signal.SIGINT)
        first.wait(60)


def _lock_left_to_a_child(path) -> tuple[int, int]:
    """A process takes the flock on ``path``, starts a child that inherits it (it sleeps a
    minute) and ends: (the taker's pid, the child's pid). /proc/locks names the taker."""
    code = ("import fcntl, os, subprocess, sys\n"
            "fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)\nfcntl.flock(fd, fcntl.LOCK_EX)\n"
            "c = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'], pass_fds=(fd,),\n"
            "                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)\n"
            "print(os.getpid(), c.pid)\n")
    taker, child = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True,
                                  check=True).stdout.split()
    return int(taker), int(child)


def test_a_lock_outliving_its_pid_is_no_running_campaign(campaign, tmp_path):
    """Issue 54: after SIGHUP `status` said "running" for a campaign process that was gone. A
    process the campaign started inherited its lock and holds it past it; and a command
    that holds the lock before it has written its pid (a resume reading its checkpoint)
    is named as the one in use."""
    import fcntl
    import socket

    from farm.directory.storage import CampaignDir, CampaignError
    from farm.reports.status import describe

    out = copy_of(campaign, tmp_path)
    status = json.loads((out / "status.json").read_text())
    (out / "status.json").write_text(json.dumps({**status, "state": "running"}))
    taker, child = _lock_left_to_a_child(out / ".lock")
    try:
        with open(out / ".lock", "w") as f:  # what the taker announced
            f.write(f"{taker}\n{socket.gethostname()}\n")
        assert "stopped while running (process gone; continue with `scenario-farm resume" in describe(out)
        with pytest.raises(CampaignError, match=f"pid {taker} that worked there has ended"):
            CampaignDir(out).lock()  # resume's refusal
    finally:
        os.kill(child, signal.SIGKILL)
    ended = subprocess.Popen(["true"])
    ended.wait()
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # this process, alive, holds it
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n{socket.gethostname()}\n".encode(), 0)
        assert f"running (pid {os.getpid()}, updated" in describe(out)
        with pytest.raises(CampaignError, match=f"pid {os.getpid()} \\(a campaign runs there\\)"):
            CampaignDir(out).lock()
        os.ftruncate(fd, 0)  # the pid of the run before, ended; this process has not written its own yet
        os.pwrite(fd, f"{ended.pid}\n{socket.gethostname()}\n".encode(), 0)
        assert f"running (pid {os.getpid()}, updated" in describe(out)
        with pytest.raises(CampaignError, match=f"in use by pid {os.getpid()}, which has not written its pid"):
            CampaignDir(out).lock()
    finally:
        os.close(fd)


# -- 3. bad paths and bad files: one line each ------------------------------------------------
def test_out_is_a_file_or_unwritable(config, tmp_path):
    (tmp_path / "file").write_text("x")
    one_line_error(cli("quantify", config, "--out", tmp_path / "file"), "not a directory")
    one_line_error(cli("quantify", config, "--out", "/proc/scenario-farm"), "cannot create the directory")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user who can write anywhere")
        one_line_error(cli("quantify", config, "--out", ro / "out"), "not writable")
    finally:
        ro.chmod(0o700)


def test_out_is_a_symlink_that_dangles_or_loops(config, tmp_path):
    """Issue 54: both were "File exists"."""
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    one_line_error(cli("quantify", config, "--out", tmp_path / "dangling"), "a symlink that dangles", "nowhere")
    one_line_error(cli("validate", config, "--out", tmp_path / "loop"), "a symlink that loops")
    assert not (tmp_path / "nowhere").exists()


def test_a_path_of_4000_characters_is_shortened_in_its_middle_and_the_reason_kept():
    import errno

    from farm.cli.exits import one_line

    path = "/tmp/" + "/".join(f"{i:02d}" + "d" * 248 for i in range(16)) + "/out"
    text = one_line(OSError(errno.ENAMETOOLONG, "File name too long", path))
    assert len(text) <= 600 and text.endswith("/out: File name too long"), text
    assert text.startswith("OSError: /tmp/00ddd") and "..." in text


@pytest.mark.parametrize("case, text, words", [
    ("constraints_not_a_list", '[scenario]\nname = "lead-follow"\n[validate]\nconstraints = 3\n',
     ["validate.constraints"]),
    ("action_value_a_table", '[scenario]\nname = "lead-follow"\n[actions]\nmode = "constant"\nvalue = { a = 1 }\n',
     ["actions.value"]),
    ("b_a_string", '[scenario]\nname = "lead-follow"\n[validate]\nconstraints = [{ a = { v0 = 1.0 }, b = "10" }]\n',
     ["validate.constraints", "b"]),
    ("empty", "", ["scenario"]),
    ("not_toml", "[scenario\nname=", ["TOML"]),
    ("unknown_section", '[scenario]\nname = "lead-follow"\n[farms]\n', ["farms", "farm"]),
    ("nan", '[scenario]\nname = "lead-follow"\n[validate]\nepsilon = nan\n', ["validate.epsilon"]),
])
def test_bad_configs(tmp_path, case, text, words):
    (tmp_path / "c.toml").write_text(text)
    one_line_error(cli("validate", tmp_path / "c.toml"), *words)


def test_config_that_is_a_directory_or_unreadable(tmp_path):
    one_line_error(cli("validate", tmp_path), str(tmp_path))
    (tmp_path / "c.toml").write_text(GOOD)
    (tmp_path / "c.toml").chmod(0)
    try:
        if os.access(tmp_path / "c.toml", os.R_OK):
            pytest.skip("running as a user who can read anything")
        one_line_error(cli("validate", tmp_path / "c.toml"), "c.toml")
    finally:
        (tmp_path / "c.toml").chmod(0o600)


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_config_that_never_ends_is_refused_without_filling_the_memory(tmp_path, device):
    """Issue 54: read whole, /dev/zero exhausted the memory and ended with exit 4 and a resume
    hint for a directory never made. The address-space limit keeps a regression from
    taking the machine's memory with it."""
    def two_gib():
        resource.setrlimit(resource.RLIMIT_AS, (2**31, 2**31))

    out = tmp_path / "out"
    r = cli("quantify", device, "--out", out, preexec_fn=two_gib)
    one_line_error(r, device)
    assert "resume" not in r.stderr and not out.exists()
    if device == "/dev/zero":
        assert "allowed at most 4 MiB" in r.stderr


def test_no_resume_hint_for_a_directory_that_holds_no_campaign(tmp_path, capsys):
    from farm.cli import exits
    from scenarios.errors import InfrastructureError

    assert exits.report(InfrastructureError("Ray lost"), str(tmp_path / "never")) == exits.INFRASTRUCTURE
    assert capsys.readouterr().err == "scenario-farm: infrastructure error: Ray lost\n"
    (tmp_path / "config.json").write_text("{}")
    exits.report(InfrastructureError("Ray lost"), str(tmp_path))
    assert f"`scenario-farm resume {tmp_path}` continues" in capsys.readouterr().err


def test_a_domain_set_with_zero_half_width(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"v0": [1.0], "v1": [1.0], "p10": [40.0], "half_width": [0.0]}), tmp_path / "s.parquet")
    (tmp_path / "v.toml").write_text(f'[scenario]\nname = "lead-follow"\n[validate]\n'
                                     f'domain_set = "{tmp_path / "s.parquet"}"\n')
    one_line_error(cli("validate", tmp_path / "v.toml"), "half_width")


def test_replay_and_resume_on_things_that_are_not_campaigns(campaign, tmp_path):
    out = copy_of(campaign, tmp_path, unfinished=False)
    one_line_error(cli("replay", out, "--sample", str(2**70)), "--sample")
    one_line_error(cli("replay", out / "summary.json", "--sample", "1"), "not a campaign directory")
    one_line_error(cli("resume", out / "summary.json"), "not a campaign directory")
    one_line_error(cli("compare", out, "--grid", "-5"), "--grid")


@pytest.mark.parametrize("damage", ["drop_array", "drop_counters", "config_section", "ledger_values"])
def test_damaged_or_tampered_campaign_files(campaign, tmp_path, damage):
    out = copy_of(campaign, tmp_path)
    if damage in ("drop_array", "drop_counters"):
        with np.load(out / "checkpoint.npz", allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        if damage == "drop_array":
            del arrays["algo.coverage"]
        else:
            meta = json.loads(arrays["__meta__"].tobytes().decode())
            del meta["counters"]
            arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        np.savez(out / "checkpoint.npz", **arrays)
    elif damage == "config_section":
        data = json.loads((out / "config.json").read_text())
        del data["config"]["scenario"]
        (out / "config.json").write_text(json.dumps(data))
    else:  # changed values in a committed ledger segment, same size and schema
        import pyarrow.parquet as pq

        seg = sorted((out / "ledger").glob("segment-*.parquet"))[0]
        table = pq.read_table(seg)
        steps = table.column("steps").to_numpy().copy()
        steps[0] += 1
        pq.write_table(table.set_column(table.column_names.index("steps"), "steps",
                                        __import__("pyarrow").array(steps)), seg)
    before = snapshot(out)
    r = cli("resume", out)
    one_line_error(r)
    assert snapshot(out) == before


def test_a_reader_that_goes_away_is_no_error(campaign):
    """`scenario-farm status DIR | head -1`: the closed pipe is the reader's choice."""
    proc = subprocess.Popen([sys.executable, "-m", "farm", "status", str(campaign)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # before the child writes a line
    assert proc.wait(120) == 0
    assert proc.stderr.read() == ""


def test_commands_work_with_stderr_closed(campaign, tmp_path):
    """Issue 54: `status DIR 2>&-` (as some service managers start a process) exited 1 and
    did nothing: stderr is then None in Python, and fd 2 the next file opened."""
    def close_stderr():
        os.close(2)

    r = subprocess.run([sys.executable, "-m", "farm", "status", str(campaign)], stdout=subprocess.PIPE, text=True,
                       preexec_fn=close_stderr, timeout=120)
    assert r.returncode == 0 and f"campaign {campaign}" in r.stdout and "finished" in r.stdout, r
    r = subprocess.run([sys.executable, "-m", "farm", "status", str(tmp_path / "none")], stdout=subprocess.PIPE,
                       text=True, preexec_fn=close_stderr, timeout=120)
    assert r.returncode == 2 and r.stdout == ""  # the error line went nowhere; the exit code says it


def test_garbage_status_json_is_reported_and_rewritten(campaign, tmp_path):
    out = copy_of(campaign, tmp_path)
    (out / "status.json").write_text("\x00garbage")
    r = cli("status", out)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert cli("resume", out).returncode == 0
    assert json.loads((out / "status.json").read_text())["state"] == "done"


# -- disk full: a write that fails (a file-size limit stands in for a full disk) -------------
LIMIT = 60_000  # bytes: more than the config files, less than the first checkpoint


def test_a_failing_write_loses_nothing_and_resume_finishes(tmp_path):
    (tmp_path / "c.toml").write_text(GOOD.replace("delta_min = 2.0", "delta_min = 1.0") + "checkpoint_every = 0.0\n")
    whole = cli("quantify", tmp_path / "c.toml", "--out", tmp_path / "whole", env=EVERY_CHUNK)
    assert whole.returncode == 0, whole.stderr

    def small_disk():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))

    out = tmp_path / "out"
    r = cli("quantify", tmp_path / "c.toml", "--out", out, preexec_fn=small_disk, env=EVERY_CHUNK)
    one_line_error(r, "File too large", f"scenario-farm resume {out}", code=4)  # the disk's fault, not the input's
    r = cli("resume", out)
    assert r.returncode == 0, r.stderr
    got, want = (json.loads((d / "summary.json").read_text()) for d in (out, tmp_path / "whole"))
    assert got["result_hash"] == want["result_hash"] and got["runs_committed"] == want["runs_committed"]
    assert not [p for p in out.rglob("*") if ".tmp-" in p.name]


# -- 4. configs and flags: one line naming the field, before any file is written ----------------
QUICK = "[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nepsilon = 0.01\nhorizon = 30\n[farm]\nbatch_size = 256\n"


CONFIG_CASES = [
    # issue 34 point 5: refused up front with the allowed range (beta = 5e-324 ran a whole campaign, then overflowed)
    ("beta_denormal", "quantify", LF + "[quantify]\nbeta = 5e-324\n", [],
     ["quantify.beta: 5e-324 is out of range; allowed [1e-100, 1)"]),
    ("epsilon_denormal", "validate", LF + "[validate]\nepsilon = 5e-324\n", [],
     ["validate.epsilon: 5e-324 is out of range; allowed [1e-09, 1)"]),
    ("predicate_os_system", "validate", LF + '[validate]\nalgorithm = "eps"\ndomain_predicate = "os:system"\n', [],
     ["validate.domain_predicate: 'os:system' raised TypeError", "expected a function states (B, n) -> (B,) bool"]),
    ("predicate_scalar", "validate", LF + '[validate]\nalgorithm = "eps"\ndomain_predicate = "numpy:sum"\n', [],
     ["validate.domain_predicate: 'numpy:sum' returned shape ()"]),
    ("nested_3000_deep", "validate", LF + "x = " + "[" * 3000 + "]" * 3000 + "\n", [],
     ["nested too deeply to read; allowed at most 32 levels"]),
    ("nested_tables", "validate", LF + "sumo = " + "{a = " * 40 + "1" + "}" * 40 + "\n", [],
     ["nested 42 levels deep; allowed at most 32"]),
    # issue 34 point 8: the policy named, not the scenario; a byte-order mark read as nothing
    ("feedback_os_system", "quantify", LF + '[actions]\nmode = "feedback"\npolicy = "os:system"\n', [],
     ["actions.policy: 'os:system' raised TypeError", "states (B, n) -> actions (B, m)"]),
    ("feedback_wrong_shape", "quantify", LF + '[actions]\nmode = "feedback"\npolicy = "numpy:ravel"\n', [],
     ["actions.policy: 'numpy:ravel' returned shape (6,)"]),
    ("byte_order_mark", "validate", "\ufeff" + LF + "[validate]\nepsilon = 2.0\n", [],
     ["validate.epsilon: 2.0 is out of range"]),
    ("utf16", "validate", LF.encode("utf-16"), [], ["not UTF-8 text"]),
    ("infinite_sigma", "quantify", '[scenario]\nname = "user_scenarios:Unbounded"\n', [],
     ["scenario 'user_scenarios:Unbounded': Sigma must be a finite box; b has bounds [0, inf]"]),
    ("scenario_init_raises", "validate", '[scenario]\nname = "user_scenarios:BrokenInit"\n', [],
     ["scenario.name: constructing 'user_scenarios:BrokenInit' raised RuntimeError: no licence server"]),
    ("scenario_without_bounds", "validate", '[scenario]\nname = "user_scenarios:NoBounds"\n', [],
     ["raised AttributeError", "'lower'"]),
    ("not_a_module_path", "validate", '[scenario]\nname = "os.path"\n', [], ["scenario.name: unknown scenario"]),
    ("negative_checkpoint", "quantify", LF + "[farm]\ncheckpoint_every = -1.0\n", [], ["farm.checkpoint_every"]),
    ("seed_flag", "quantify", LF, ["--seed", "-1"], ["--seed: -1 is out of range"]),
    ("workers_flag_zero", "quantify", LF, ["--workers", "0"], ["--workers: 0 is out of range; allowed [1, 4096]"]),
    # issue 34 point 7: thousands of actors on two cores ran at 7 runs/s
    ("workers_4096_local_ray", "quantify", LF, ["--executor", "ray", "--workers", "4096"],
     ["farm.workers: 4096 actors on a local Ray", "4 per CPU"]),
    # issue 34 point 2: an address that answers nothing, within seconds, before any file
    ("address_refused", "quantify", LF, ["--executor", "ray", "--address", "127.0.0.1:1"],
     ["farm.address: nothing answers at", "for '127.0.0.1:1'"]),
    ("address_ray_client_refused", "quantify", LF, ["--executor", "ray", "--address", "ray://127.0.0.1:9"],
     ["farm.address: nothing answers at 127.0.0.1:9"]),
    ("address_garbage", "validate", LF, ["--executor", "ray", "--address", "no-port-here"],
     ["farm.address: 'no-port-here' is not 'local', 'auto', 'host:port' or 'ray://host:port'"]),
    ("address_auto_without_cluster", "quantify", LF, ["--executor", "ray", "--address", "auto"],
     ["farm.address: 'auto' found no Ray cluster"]),
]


@pytest.mark.parametrize("case, command, text, flags, words", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_bad_configs_and_flags_are_refused_before_any_file(tmp_path, case, command, text, flags, words):
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    env["RAY_TMPDIR"] = str(tmp_path / "ray")  # no `ray start` recorded there: 'auto' finds nothing
    t0 = time.monotonic()
    r = cli(command, cfg, "--out", out, *flags, cwd=TESTS, env=env)
    one_line_error(r, *words)
    assert not out.exists()
    if case.startswith("address"):  # a bounded wait: the probe's 3 s plus start-up (slow on a loaded machine)
        assert time.monotonic() - t0 < 60
    if case.startswith(("feedback", "infinite", "byte_order")):
        assert "scenario 'lead-follow'" not in r.stderr and "delta_min" not in r.stderr
        assert "Invalid statement" not in r.stderr


def test_a_feedback_policy_that_raises_mid_campaign_is_named_with_its_run(tmp_path):
    (tmp_path / "c.toml").write_text(LF + '[actions]\nmode = "feedback"\npolicy = "user_scenarios:raising_policy"\n'
                                     + QUICK)
    r = cli("quantify", tmp_path / "c.toml", "--out", tmp_path / "out", cwd=TESTS)
    one_line_error(r, "actions.policy: 'user_scenarios:raising_policy' raised ValueError: policy boom on sample index")
    assert "scenario 'lead-follow'" not in r.stderr


def test_a_config_given_as_a_stream_is_read_once_and_frozen_whole(tmp_path):
    """`quantify <(cat c.toml)`: the frozen config.toml was 0 bytes (the stream was read twice)."""
    text = LF + QUICK
    read, write = os.pipe()
    os.write(write, text.encode())
    os.close(write)
    try:
        r = subprocess.run([sys.executable, "-m", "farm", "quantify", f"/dev/fd/{read}", "--out", str(tmp_path / "out"),
                            "--quiet"], capture_output=True, text=True, pass_fds=(read,), timeout=300)
    finally:
        os.close(read)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out" / "config.toml").read_text() == text


def test_checkpoint_every_zero_is_raised_to_the_minimum_with_one_warning(tmp_path):
    (tmp_path / "c.toml").write_text(LF + QUICK)
    r = cli("quantify", tmp_path / "c.toml", "--out", tmp_path / "out", "--checkpoint-every", "0", "--quiet")
    assert r.returncode == 0, r.stderr
    warned = [line for line in r.stderr.splitlines() if line.startswith("scenario-farm: warning: ")]
    assert len(warned) == 1 and "farm.checkpoint_every: 0 s is below the minimum" in warned[0], r.stderr
    frozen = json.loads((tmp_path / "out" / "config.json").read_text())["config"]
    assert frozen["farm"]["checkpoint_every"] == 1.0


# -- 5. damaged campaign directories: every reader names the file, changes nothing --------------
def damage(path, how):
    if how == "delete":
        import shutil

        shutil.rmtree(path) if path.is_dir() else path.unlink()
    elif how == "empty":
        path.write_bytes(b"")
    elif how == "half":
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    elif how == "garbage":
        path.write_bytes(b"\x00garbage{[\xff")
    elif how == "keep":  # the copy is damage enough (an unfinished campaign)
        pass
    elif how.startswith("text:"):
        path.write_text(how[5:])
    elif how.startswith("drop_config:"):  # a frozen config without one section
        data = json.loads(path.read_text())
        del data["config"][how.split(":")[1]]
        path.write_text(json.dumps(data))
    elif how.startswith("reshape:"):  # one array of the checkpoint, written again with another shape
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        name = how.split(":")[1]
        arrays[name] = np.concatenate([arrays[name]] * 100)
        np.savez(path, **arrays)
    elif how.startswith("drop_meta:"):  # a checkpoint whose metadata lacks one key
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays["__meta__"].tobytes().decode())
        del meta[how.split(":")[1]]
        arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        np.savez(path, **arrays)


SEGMENT = "ledger/segment-000000.parquet"
DAMAGE_CASES = [  # (finished?, file, damage, command, words)
    # issue 34 point 8: a garbage summary.json or ledger segment was a raw JSON or pyarrow error
    (True, "summary.json", "garbage", "status", ["summary.json: not valid JSON"]),
    (True, "summary.json", "garbage", "report", ["summary.json: not valid JSON"]),
    (True, "summary.json", "text:{}", "status", ["summary.json: lacks", "boxes"]),
    (True, "summary.json", "text:[1, 2]", "report", ["summary.json: holds a JSON list"]),
    (True, SEGMENT, "garbage", "replay", [SEGMENT + ": ledger segment is damaged"]),
    (True, SEGMENT, "empty", "report", [SEGMENT + ": ledger segment is damaged"]),
    (True, "ledger", "delete", "replay", ["no ledger segments"]),
    (True, SEGMENT, "delete", "replay", ["sample 0 is not in the ledger"]),
    (True, "config.json", "garbage", "status", ["config.json: not valid JSON"]),
    (True, "config.json", "text:{\"config\": 3, \"config_hash\": 1}", "status", ["config.json: lacks"]),
    (True, "config.json", "garbage", "replay", ["config.json: not valid JSON"]),
    (True, ".scenario-farm.json", "garbage", "report", ["not a campaign directory"]),
    (True, "safe_set.parquet", "half", "report", ["safe_set.parquet: not a readable Parquet safe set"]),
    (True, "safe_set.parquet", "delete", "compare", ["safe_set.parquet: no such safe-set file"]),
    (True, "checkpoint.npz", "garbage", "report", ["checkpoint.npz: checkpoint is truncated or corrupt"]),
    (True, "checkpoint", "delete", "report", ["checkpoint segment missing"]),
    (True, "adversary.json", "garbage", "falsify", ["adversary.json: not valid JSON"]),
    # the OpenSCENARIO export reads summary.json as every other reader does
    (True, "summary.json", "garbage", "export", ["summary.json: not valid JSON"]),
    (True, "summary.json", 'text:{"scenario": "lead-follow", "algorithm": "spe", "boxes": "many", "result_hash": '
                           '"x", "guarantee": "g"}', "export", ["summary.json: boxes is 'many'; expected int"]),
    (True, "safe_set.parquet", "half", "export", ["safe_set.parquet: not a readable Parquet safe set"]),
    (True, "openscenario", "text:a file", "export", ["openscenario: exists and is not a directory"]),
    (False, "config.json", "garbage", "export", ["config.json: not valid JSON"]),
    (False, "checkpoint.npz", "keep", "compare", ["the campaign has not finished (no summary.json)"]),
    # issue 34 point 5: checkpoint metadata without its journal was a KeyError on resume
    (False, "checkpoint.npz", "drop_meta:journal", "resume", ["checkpoint metadata lacks 'journal'"]),
    (False, "checkpoint.npz", "drop_meta:epoch", "resume", ["checkpoint metadata lacks 'epoch'"]),
    (False, "checkpoint.npz", "half", "resume", ["checkpoint is truncated or corrupt"]),
    # issue 54 point 5: a wrong-shaped array was accepted, and the resume ran ~100x slower
    (False, "checkpoint.npz", "reshape:algo.vertices.alive", "resume",
     ["checkpoint.npz: checkpoint array 'algo.vertices.alive' has shape", "but was written as shape"]),
    (False, "checkpoint.npz", "delete", "resume", ["checkpoint.npz is missing"]),
    (False, SEGMENT, "half", "resume", ["ledger segment is corrupt"]),
    (False, SEGMENT, "delete", "resume", ["ledger segment missing"]),
    (False, "config.json", "garbage", "resume", ["config.json: not valid JSON"]),
    # issue 54: filled with defaults, it was "stamped with config hash ..., the config hashes to ..."
    (False, "config.json", "drop_config:quantify", "resume", ["config.json: the frozen config lacks its [quantify] "
                                                              "section"]),
    (False, ".scenario-farm.json", "delete", "resume", ["not a campaign directory"]),
    (False, ".scenario-farm.json", "text:{\"format\": 1}", "resume", ["directory format 1"]),
]


@pytest.mark.parametrize("finished, name, how, command, words", DAMAGE_CASES,
                         ids=[f"{'finished' if c[0] else 'unfinished'}-{c[1]}-{c[2]}-{c[3]}" for c in DAMAGE_CASES])
def test_a_damaged_campaign_file_is_named_and_nothing_changes(campaign, tmp_path, finished, name, how, command,
                                                              words):
    out = copy_of(campaign, tmp_path, unfinished=not finished)
    damage(out / name, how)
    before = snapshot(out)
    args = {"replay": ["--sample", 0], "compare": ["--grid", "8"], "export": ["--xosc"]}.get(command, [])
    one_line_error(cli(command, out, *args), *words)
    assert snapshot(out) == before


FLAG_CASES = [  # (command, flags, words): refused before any work, nothing written
    ("compare", ["--grid", "3", "--grid-total", "100"], ["not both"]),
    ("compare", ["--grid-total", "1"], ["--grid-total: 1 is out of range; allowed [8, "]),
    ("compare", ["--grid", "1", "--estimate"], ["--grid: 1 is out of range; allowed [2, 4096]"]),
    ("export", [], ["export: choose a format; allowed: --xosc"]),
]


@pytest.mark.parametrize("command, flags, words", FLAG_CASES, ids=[f"{c[0]}-{'_'.join(c[1])}" for c in FLAG_CASES])
def test_a_bad_flag_on_a_finished_campaign_is_one_line_and_writes_nothing(campaign, tmp_path, command, flags, words):
    out = copy_of(campaign, tmp_path, unfinished=False)
    before = snapshot(out)
    one_line_error(cli(command, out, *flags), *words)
    assert snapshot(out) == before


def test_a_damaged_certificate_is_named_by_replay(tmp_path):
    (tmp_path / "v.toml").write_text(LF + '[validate]\nalgorithm = "eps"\nepsilon = 0.01\n')
    out = tmp_path / "v"
    r = cli("validate", tmp_path / "v.toml", "--out", out)
    assert r.returncode == 1, r.stderr  # the whole of Sigma is not invariant: a counterexample, quickly
    sample = json.loads((out / "certificate.json").read_text())["counterexample"]["sample_index"]
    damage(out / "certificate.json", "text:[]")
    before = snapshot(out)
    one_line_error(cli("replay", out, "--sample", sample), "certificate.json: holds a JSON list")
    assert snapshot(out) == before


def test_replay_of_a_counterexample_is_a_finding_and_status_describes_the_validation(tmp_path):
    """Issue 54: replay of a counterexample exited 0 (the table says 1), and `status` read a
    validation directory as a quantification not started ("spe ... not started")."""
    (tmp_path / "v.toml").write_text(LF + '[validate]\nalgorithm = "eps"\nepsilon = 0.01\n')
    out = tmp_path / "v"
    assert cli("validate", tmp_path / "v.toml", "--out", out).returncode == 1
    cert = json.loads((out / "certificate.json").read_text())
    sample = cert["counterexample"]["sample_index"]
    r = cli("status", out)
    assert r.returncode == 0 and f"validation {out}" in r.stdout and " / eps, config hash" in r.stdout, r.stdout
    assert f"done: counterexample at sample {sample}" in r.stdout and "spe" not in r.stdout, r.stdout
    r = cli("replay", out, "--sample", sample)
    assert r.returncode == 1 and "replay reproduces the counterexample" in r.stdout, (r.returncode, r.stdout, r.stderr)
    cert["counterexample"]["trajectory"][-1][0] += 1.0  # a record the re-run cannot match
    (out / "certificate.json").write_text(json.dumps(cert))
    r = cli("replay", out, "--sample", sample)
    one_line_error(r, f"the replay of sample {sample} does not match the record")
    assert "DIFF trajectory" in r.stdout


def test_a_progress_reader_that_goes_away_does_not_end_the_campaign(config, campaign, tmp_path):
    """`quantify ... 2>&1 | head -1` ended the campaign at its second line, with nothing
    run and exit 0: the lines a reader that has gone would get are dropped, the campaign
    runs to its end and its result."""
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "farm", "quantify", str(config), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout.readline().startswith("scenario-farm: ")
    proc.stdout.close()  # the reader goes; the campaign's next lines meet a broken pipe
    assert proc.wait(300) == 0
    got, want = (json.loads((d / "summary.json").read_text()) for d in (out, campaign))
    assert got["result_hash"] == want["result_hash"] and got["runs_committed"] == want["runs_committed"]
    assert json.loads((out / "status.json").read_text())["state"] == "done"
