"""Run by tests/farm/test_multinode.py in its own process: a Ray cluster of three nodes
on this machine (ray.cluster_utils.Cluster: a head and two more raylets) and a campaign
on it; the outcome as JSON on the last line of stdout.

    python multinode_campaign.py whole CONFIG_JSON    # the campaign's result, actors spread
    python multinode_campaign.py worker CONFIG_JSON   # ... with a worker node removed mid-campaign
    python multinode_campaign.py head DIR             # the CLI's campaign loses the head node,
    python multinode_campaign.py raylet DIR           # ... or the head's raylet; then resume
"""

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ray.cluster_utils import Cluster

from farm.ray_runtime import session as ray_session
from small_campaign import lead_follow_toml

LOSE_AFTER = 3  # chunks read before a node is lost


def cluster() -> Cluster:
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "_system_config": ray_session.RAY_SYSTEM_CONFIG})
    workers = [c.add_node(num_cpus=1) for _ in range(2)]
    c.wait_for_nodes()
    return c, workers


def in_process(raw_config: str, lose_worker: bool) -> None:
    """The driver is this process; with ``lose_worker``, the node of the second actor is
    removed after ``LOSE_AFTER`` chunks (not the head: this driver is attached to it)."""
    import ray

    from farm import config as config_mod
    from farm.jobs import side_campaign
    from farm.jobs import quantification

    c, workers = cluster()
    ray.init(address=c.address, log_to_driver=False, configure_logging=False)
    nodes_seen: list[list[str]] = []
    notes: list[str] = []
    lost: list[str] = []
    make = side_campaign.make_executor

    def make_and_look(*args, **kwargs):
        executor = make(*args, **kwargs)
        nodes_seen.append(executor.nodes())
        if lose_worker:
            result, read = executor.result, [0]

            def result_then_lose(handle):
                read[0] += 1
                if read[0] == LOSE_AFTER:
                    by_id = {n.node_id: n for n in workers}
                    node = next(by_id[i] for i in nodes_seen[0] if i in by_id)
                    c.remove_node(node, allow_graceful=False)  # lost, not shut down
                    lost.append(node.node_id)
                return result(handle)

            executor.result = result_then_lose
        return executor

    side_campaign.make_executor = make_and_look
    cfg = config_mod.normalize(json.loads(raw_config))
    try:
        from farm.reports.progress import Progress

        class Notes(Progress):
            def line(self, text):
                notes.append(text)

        summary = quantification.run(cfg, Path(tempfile.mkdtemp()) / "c", progress=Notes(mode="verbose"))
    finally:
        ray.shutdown()
        c.shutdown()
    print(json.dumps({"result_hash": summary["result_hash"], "runs_committed": summary["runs_committed"],
                      "nodes": nodes_seen, "lost": lost, "notes": [n for n in notes if "Ray worker" in n]}))


def lose_head(what: str, directory: str) -> None:
    """The CLI's campaign (in its own process, attached to the head) on the cluster; the
    head node (or only its raylet) is lost mid-campaign; then ``resume`` on a local Ray."""
    d = Path(directory)
    (d / "c.toml").write_text(lead_follow_toml(executor="ray", farm_extra="workers = 3\nseed = 11\n"))
    out = d / "out"
    c, _ = cluster()
    logs = Path(c.head_node.get_session_dir_path()) / "logs"
    cli = [sys.executable, "-m", "farm"]
    proc = subprocess.Popen([*cli, "quantify", str(d / "c.toml"), "--out", str(out), "--address", c.address,
                             "--checkpoint-every", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while len(list((out / "ledger").glob("segment-*.parquet"))) < 2 and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.05)
    segments = len(list((out / "ledger").glob("segment-*.parquet")))
    t0 = time.monotonic()
    if what == "head":
        c.remove_node(c.head_node, allow_graceful=False)
    else:
        c.head_node.kill_raylet()
    try:
        code = proc.wait(300)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        code = "hung"
    took = time.monotonic() - t0
    stderr = proc.stderr.read()
    # Ray's own lines for the driver (the CLI keeps them off stderr): why it ended, if not by our exit 4
    driver_logs = logs.glob(f"python-core-driver-*_{proc.pid}.log")
    driver_log = "".join(f.read_text(errors="replace")[-3000:] for f in driver_logs)
    c.shutdown()
    r = subprocess.run([*cli, "resume", str(out), "--address", "local", "--workers", "2", "--quiet"],
                       capture_output=True, text=True)
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    print(json.dumps({"segments_before": segments, "code": code, "seconds": took, "stderr": stderr[-3000:],
                      "driver_log": driver_log if code != 4 else "",
                      "resume_code": r.returncode, "resume_stderr": r.stderr[-3000:],
                      "result_hash": summary.get("result_hash"), "config": str(d / "c.toml")}))


if __name__ == "__main__":
    mode, arg = sys.argv[1], sys.argv[2]
    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    if mode in ("whole", "worker"):
        in_process(arg, mode == "worker")
    else:
        lose_head(mode, arg)
