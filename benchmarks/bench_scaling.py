"""Scaling of the farm: committed runs/s of a quantification campaign against the number
of Ray workers, with a simulator of realistic speed (4 us per run-step, a sleep standing
in for a remote core: benchmarks/slow_backend.py), on a local Ray.

lead-follow idm, uniform Gamma, delta 2 -> 1, the default batch size and pipeline depth.
Ray start-up and actor creation are left out (they are reported apart); the coordinator's
CPU time per committed run is printed too.

    python benchmarks/bench_scaling.py [--workers 1 2 4 8 16 32]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402


def campaign_config(workers: int, batch: int | None = None, depth: int | None = None,
                    backend: str = "slow_backend:SlowBackend", delta_min: float = 1.0):
    from farm import config as config_mod

    farm = {"executor": "ray", "workers": workers, "seed": 0}
    farm.update({k: v for k, v in (("batch_size", batch), ("pipeline_depth", depth)) if v})
    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm", "backend": backend},
        "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                     "certify": False},
        "farm": farm})


def run_campaign(cfg) -> dict:
    from farm.campaign_setup import build_algorithm, build_campaign, spec_of
    from farm.executors import make_executor
    from farm.simulators import build_simulator

    spec = spec_of(cfg)
    sim = build_simulator(spec)
    algo = build_algorithm(cfg, sim)
    t0 = time.perf_counter()
    ex = make_executor(cfg.farm, spec)
    pids = ex.pids()  # the actors are up
    startup = time.perf_counter() - t0
    workers_cpu0 = _cpu_seconds(pids)
    campaign = build_campaign(cfg, algo, sim, ex)
    cpu0, main0, t0 = time.process_time(), time.thread_time(), time.perf_counter()
    c = campaign.run()
    wall, cpu, main_cpu = time.perf_counter() - t0, time.process_time() - cpu0, time.thread_time() - main0
    workers_cpu = _cpu_seconds(pids) - workers_cpu0
    stats = ex.worker_stats()
    busy = np.array([s["busy_s"] for s in stats])
    ex.close()
    return {"workers": cfg.farm.workers, "committed": c.committed, "wall_s": wall, "cpu_s": cpu, "main_cpu_s": main_cpu, "startup_s": startup,
            "rate": c.committed / wall, "idle": 1 - busy.mean() / wall,
            "worker_busy_s": float(busy.sum()), "workers_cpu_s": workers_cpu, "hash": algo.result().result_hash}


def _cpu_seconds(pids: list[int]) -> float:
    """User + system CPU seconds of local processes so far (Linux /proc; NaN elsewhere)."""
    total = 0.0
    try:
        for pid in pids:
            fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")
    return total


def main() -> None:
    import ray

    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    ap.add_argument("--batch", type=int, help="farm.batch_size (default: the config default)")
    ap.add_argument("--depth", type=int, help="farm.pipeline_depth (default: the config default)")
    args = ap.parse_args()
    from farm.ray_session import start_local

    start_local(os.cpu_count(), HERE)
    cfg0 = campaign_config(1, args.batch, args.depth)
    print(f"machine: {os.cpu_count()} cores; Ray {ray.__version__}, local; simulator 4 us per run-step (sleep); "
          f"batch_size {cfg0.farm.batch_size}, pipeline_depth {cfg0.farm.pipeline_depth}")
    base = None
    hashes = set()
    for w in args.workers:
        r = run_campaign(campaign_config(w, args.batch, args.depth))
        base = base or r["rate"]
        hashes.add(r["hash"])
        print(f"{w:3d} workers: {r['rate']:9,.0f} committed runs/s  speed-up {r['rate'] / base:5.2f}x  "
              f"({r['committed']} runs in {r['wall_s']:.1f} s; worker idle {r['idle']:.2f}; coordinator "
              f"{r['committed'] / max(r['cpu_s'], 1e-9):,.0f} runs per CPU-s; workers' CPU "
              f"{r['workers_cpu_s'] / r['wall_s']:.2f} cores; actors up in {r['startup_s']:.1f} s)",
              flush=True)
    print(f"same result for every worker count: {len(hashes) == 1}")
    ray.shutdown()


if __name__ == "__main__":
    main()
