"""A real multi-node Ray cluster on one host gives the in-process result bit for bit."""

import json
import os
import subprocess
import sys
from pathlib import Path

from farm import config as config_mod
from farm.quantification import run

RAW = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
       "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30},
       "farm": {"executor": "ray", "workers": 3, "address": "auto", "batch_size": 128, "pipeline_depth": 3,
                "seed": 11}}


def test_a_three_node_cluster_spreads_the_actors_and_reproduces_the_in_process_result(tmp_path):
    local = run(config_mod.normalize({**RAW, "farm": {**RAW["farm"], "executor": "local"}}), tmp_path / "local")
    here = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(here.parents[1]), os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run([sys.executable, str(here / "multinode_campaign.py"), json.dumps(RAW)], capture_output=True,
                       text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["result_hash"] == local["result_hash"] and out["runs_committed"] == local["runs_committed"]
    assert len(set(out["nodes"][0])) == 3  # one actor on each node
