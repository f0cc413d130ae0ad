"""`ray job submit` against a real local Ray head with token authentication on.

The head runs `ray start --head --block` in its own process group, bound to 127.0.0.1
on ports of its own (not a default Ray's 6379/8265), with RAY_AUTH_MODE=token and a
fresh token; the client gets the same two variables. Teardown stops that process group
only: other Ray instances on the machine (the test session's own) are left alone.
"""

import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from farm.ray_runtime.session import INLINE_RETURN_BYTES

ROOT = Path(__file__).resolve().parents[2]


def free_ports(k):
    socks = [socket.socket() for _ in range(k)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


@pytest.fixture
def ray_head(tmp_path):
    gcs, dashboard, client, agent = free_ports(4)
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16),
           "RAY_max_direct_call_object_size": str(INLINE_RETURN_BYTES)}  # as deploy/ starts a cluster
    temp_dir = Path("/tmp") / f"sfh-{secrets.token_hex(3)}"  # short: Ray's socket paths are length-limited
    log = open(tmp_path / "head.log", "w")
    head = subprocess.Popen(
        ["ray", "start", "--head", "--block", "--node-ip-address", "127.0.0.1", "--port", str(gcs),
         "--dashboard-host", "127.0.0.1", "--dashboard-port", str(dashboard), "--ray-client-server-port", str(client),
         "--dashboard-agent-listen-port", str(agent), "--num-cpus", "2", "--temp-dir", str(temp_dir),
         "--disable-usage-stats"], env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{dashboard}"
    deadline = time.time() + 90
    while time.time() < deadline:
        try:
            urllib.request.urlopen(f"{url}/api/version", timeout=2)
            break
        except OSError as exc:
            if getattr(exc, "code", None) in (401, 403):  # up, and asking for the token
                break
            assert head.poll() is None, (tmp_path / "head.log").read_text()
            time.sleep(1)
    else:
        pytest.fail("Ray head did not come up:\n" + (tmp_path / "head.log").read_text())
    yield {"url": url, "env": env}
    try:
        os.killpg(head.pid, signal.SIGTERM)
        head.wait(timeout=20)
    except (subprocess.TimeoutExpired, ProcessLookupError):
        pass
    try:  # some Ray daemons outlive SIGTERM of the group: make sure only ours go
        os.killpg(head.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    subprocess.run(["pkill", "-KILL", "-f", str(temp_dir)], check=False)


def submit(head, *entrypoint, token=None, timeout=600):
    env = dict(head["env"])
    if token is not None:
        env["RAY_AUTH_TOKEN"] = token
    return subprocess.run(["ray", "job", "submit", "--address", head["url"], "--working-dir", str(ROOT), "--",
                           *entrypoint], env=env, capture_output=True, text=True, timeout=timeout, cwd=ROOT)


@pytest.mark.slow
def test_quantification_via_ray_job_submit_with_token_auth(ray_head, tmp_path):
    out = tmp_path / "campaign"
    cfg = tmp_path / "job.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "brake"\n[actions]\nmode = "adversarial"\n'
                   '[quantify]\ndelta0 = 2.0\ndelta_min = 1.0\n[farm]\nexecutor = "ray"\nworkers = 2\n')
    r = submit(ray_head, "python", "-m", "farm", "quantify", str(cfg), "--out", str(out), "--address", "auto")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "succeeded" in (r.stdout + r.stderr)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] and summary["boxes"] > 0
    assert (out / "safe_set.parquet").exists() and (out / "plots" / "safe_set_3d.png").exists()
    # the same campaign in-process gives the same set: the cluster changed nothing but time
    local = subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(tmp_path / "local"),
                            "--executor", "local"], capture_output=True, text=True)
    assert local.returncode == 0, local.stderr
    assert json.loads((tmp_path / "local" / "summary.json").read_text())["result_hash"] == summary["result_hash"]
    # auth is really on: a wrong token is refused
    bad = submit(ray_head, "python", "-c", "print('should not run')", token="0" * 32, timeout=120)
    assert bad.returncode != 0
