"""Run by tests/farm/test_multinode.py in its own process: a Ray cluster of three nodes
on this machine (ray.cluster_utils.Cluster: a head and two more raylets), a campaign
whose actors are spread over them, and the campaign's result as JSON on stdout."""

import json
import sys
import tempfile
from pathlib import Path

import ray
from ray.cluster_utils import Cluster

from farm import config as config_mod
from farm import facet_campaign, quantification, ray_session


def main(raw_config: str) -> None:
    cluster = Cluster(initialize_head=True,
                      head_node_args={"num_cpus": 1, "_system_config": ray_session.RAY_SYSTEM_CONFIG})
    for _ in range(2):
        cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, log_to_driver=False, configure_logging=False)
    nodes_seen: list[list[str]] = []
    make = facet_campaign.make_executor

    def make_and_look(*args, **kwargs):
        executor = make(*args, **kwargs)
        nodes_seen.append(executor.nodes())
        return executor

    facet_campaign.make_executor = make_and_look
    cfg = config_mod.normalize(json.loads(raw_config))
    try:
        summary = quantification.run(cfg, Path(tempfile.mkdtemp()) / "c")
    finally:
        ray.shutdown()
        cluster.shutdown()
    print(json.dumps({"result_hash": summary["result_hash"], "runs_committed": summary["runs_committed"],
                      "nodes": nodes_seen, "cluster_nodes": 3}))


if __name__ == "__main__":
    main(sys.argv[1])
