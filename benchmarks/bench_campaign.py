"""End to end: the lead-follow idm SPE campaign at delta_min = 0.25 (Gamma*, eps = 0.001,
beta = 0.1), in-process executor, through the same code path as `scenario-farm quantify`.

    python benchmarks/bench_campaign.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from farm import config as config_mod
from farm.quantification import run

TARGET_S = 120.0


def main() -> None:
    cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "adversarial"},
        "quantify": {"delta0": 2.0, "delta_min": 0.25, "epsilon": 0.001, "beta": 0.1, "horizon": 50},
        "farm": {"executor": "local", "seed": 0}})
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        s = run(cfg, Path(tmp) / "c", resume=False)
        wall = time.perf_counter() - t0
    print(f"lead-follow idm SPE campaign, delta 2 -> 0.25: {wall:.1f} s wall including result files and plots "
          f"(target <= {TARGET_S:.0f} s: {TARGET_S / wall:.2f}x margin); {s['runs_committed']} committed runs, "
          f"{s['boxes']} boxes, volume {s['volume_union']:.0f}, {s['runs_committed'] / wall:,.0f} runs/s")


if __name__ == "__main__":
    main()
