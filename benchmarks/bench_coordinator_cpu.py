"""The coordinator's own cost: committed runs per CPU-second of the coordinating process,
the figure of the scale-out target (issue 11: >= 300,000).

lead-follow idm, uniform Gamma, delta 2 -> 0.5, the numpy back end on 2 Ray workers, the
default batch size and pipeline depth. CPU time is the driver's ``process_time`` over the
campaign (every thread of it, Ray's included); Ray start-up and actor creation are left
out. The workers' busy time (simulation and screening) is printed alongside.

    python benchmarks/bench_coordinator_cpu.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from bench_scaling import campaign_config, run_campaign  # noqa: E402
from targets import check, finish  # noqa: E402


def main() -> None:
    import ray

    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--batch", type=int, help="farm.batch_size (default: the config default)")
    ap.add_argument("--depth", type=int, help="farm.pipeline_depth (default: the config default)")
    args = ap.parse_args()
    from farm.ray_runtime.session import start_local

    start_local(os.cpu_count())  # as the CLI's local Ray
    farm = campaign_config(2, args.batch, args.depth).farm
    print(f"machine: {os.cpu_count()} cores; Ray {ray.__version__}, local; lead-follow idm, uniform Gamma, "
          f"delta 2 -> 0.5, numpy back end, 2 workers, batch_size {farm.batch_size}, pipeline_depth "
          f"{farm.pipeline_depth}")
    rates = []
    for _ in range(args.repeat):
        r = run_campaign(campaign_config(2, args.batch, args.depth, backend="numpy", delta_min=0.5))
        rates.append(r["committed"] / r["cpu_s"])
        print(f"{r['committed']:,} committed runs in {r['wall_s']:.1f} s wall, coordinator {r['cpu_s']:.2f} CPU-s "
              f"({r['main_cpu_s']:.2f} in its main thread, the rest Ray's own threads), workers busy "
              f"{r['worker_busy_s']:.1f} s: "
              f"{rates[-1]:,.0f} committed runs per coordinator-CPU-second (result {r['hash']})", flush=True)
    median = sorted(rates)[len(rates) // 2]
    verdict = check("committed runs per coordinator-CPU-second >= 300,000", median >= 300_000)
    print(f"median: {median:,.0f} committed runs per coordinator-CPU-second (target 300,000: {verdict})")
    ray.shutdown()
    finish()


if __name__ == "__main__":
    main()
