"""reachable(sigma, G): the undirected tree (the paper's wording) against the ancestors
only (the states that can reach sigma), on lead-follow with uniform Gamma, against the
model-based reference.

    python experiments/reachable.py     # writes docs/reachable.json, re-renders docs/convergence.md
"""

import json
import time
from pathlib import Path

from coordinator.baselines import make_algorithm
from coordinator.driver import Campaign, CampaignSettings
from coordinator.reference import compare_boxes
from coordinator.spe import SPESettings
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios import make_scenario
from scenarios.backend import NumpyBackend


def main() -> None:
    rows = []
    for policy in ("brake", "idm"):
        sc = make_scenario("lead-follow", sv_policy=policy)
        for mode in ("undirected", "ancestors"):
            algo = make_algorithm("spe", sc, SPESettings(delta0=2.0, delta_min=0.5, reachable=mode), 0)
            ex = LocalExecutor(SimSpec({"name": "lead-follow", "sv_policy": policy}, {"mode": "uniform"}, 50, 0))
            t0 = time.perf_counter()
            settings = CampaignSettings(epsilon=0.001, beta=0.1, budget=3_000_000, batch_size=1024, pipeline_depth=2)
            c = Campaign(algo, ex, settings).run()
            safe_set = algo.result()
            m = compare_boxes(NumpyBackend(sc), safe_set, grid_points_per_axis=100)
            row = {"policy": policy, "reachable": mode, "runs": c.committed, "boxes": len(safe_set),
                   "iou": m["iou"], "precision": m["precision"], "recall": m["recall"],
                   "seconds": round(time.perf_counter() - t0, 1)}
            rows.append(row)
            print(json.dumps(row), flush=True)
    (Path(__file__).resolve().parents[1] / "docs" / "reachable.json").write_text(json.dumps(rows, indent=1) + "\n")
    from convergence import render  # docs/convergence.md quotes this table

    render()


if __name__ == "__main__":
    main()
