"""A real multi-node Ray cluster on one host (ray.cluster_utils.Cluster, three nodes):
the in-process result bit for bit, also when a worker node is lost mid-campaign; a lost
head node or raylet stops the campaign with a line of ours and exit 4, and resume
completes it (issue 34)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from farm import config as config_mod
from farm.jobs.quantification import run

RAW = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
       "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30},
       "farm": {"executor": "ray", "workers": 3, "address": "auto", "batch_size": 128, "pipeline_depth": 3,
                "seed": 11}}
HERE = Path(__file__).resolve().parent


def on_a_cluster(mode: str, arg: str) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE.parents[1]), str(HERE.parent),
                                                        os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run([sys.executable, str(HERE / "multinode_campaign.py"), mode, arg], capture_output=True,
                       text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return run(config_mod.normalize({**RAW, "farm": {**RAW["farm"], "executor": "local"}}),
               tmp_path_factory.mktemp("local") / "c")


def test_a_three_node_cluster_spreads_the_actors_and_reproduces_the_in_process_result(local):
    out = on_a_cluster("whole", json.dumps(RAW))
    assert out["result_hash"] == local["result_hash"] and out["runs_committed"] == local["runs_committed"]
    assert len(set(out["nodes"][0])) == 3  # one actor on each node


@pytest.mark.soak  # CI keeps the three-node cluster's result; losing nodes is the soak tests' chaos
def test_a_lost_worker_node_is_survived_with_the_same_result(local):
    """Its actor cannot be restarted (no node has room): the other two carry on."""
    out = on_a_cluster("worker", json.dumps(RAW))
    assert out["lost"], "no node was removed"
    assert any("was lost" in n for n in out["notes"]), out["notes"]  # said, not hidden
    assert out["result_hash"] == local["result_hash"] and out["runs_committed"] == local["runs_committed"]


@pytest.mark.soak  # two multi-node clusters killed and resumed; a killed raylet on one node runs in CI
@pytest.mark.parametrize("what", ["head", "raylet"])
def test_a_lost_head_or_raylet_stops_with_our_line_and_exit_4_then_resume_completes(tmp_path, what):
    out = on_a_cluster(what, str(tmp_path))
    assert out["segments_before"] >= 2, out  # lost mid-campaign, after checkpoints
    assert out["code"] == 4, (out["code"], out["stderr"], out["driver_log"])
    last = out["stderr"].strip().splitlines()[-1]
    assert last.startswith("scenario-farm: infrastructure error:"), out["stderr"]
    assert out["seconds"] < 120, out
    assert out["resume_code"] == 0, out["resume_stderr"]
    whole = tmp_path / "whole"
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", out["config"], "--out", str(whole), "--executor",
                        "local", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert out["result_hash"] == json.loads((whole / "summary.json").read_text())["result_hash"]
