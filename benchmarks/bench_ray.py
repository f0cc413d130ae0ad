"""Committed runs/s of a quantification campaign on the in-process executor and on 1 and
2 Ray workers (local two-core mode), the per-batch overhead of Ray, worker idle
fraction, and the scaling of a slow simulator.

    python benchmarks/bench_ray.py
"""

from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

from farm import config as config_mod  # noqa: E402


def campaign_config(name="lead-follow", executor="local", workers=1, batch=1024, delta_min=0.5):
    return config_mod.normalize({
        "scenario": {"name": name, "sv_policy": "idm"}, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50},
        "farm": {"executor": executor, "workers": workers, "batch_size": batch, "pipeline_depth": 2, "seed": 0}})


def run_campaign(cfg):
    """-> (summary, wall seconds, worker stats or None)."""
    from coordinator.baselines import make_algorithm
    from coordinator.campaign import Campaign
    from coordinator.covering import n_eps
    from farm.quantification import settings_of, spec_of
    from farm.ray_executor import make_executor

    spec = spec_of(cfg)
    from farm.executors import build_simulator

    scenario, _ = build_simulator(spec)
    q, farm = cfg["quantify"], cfg["farm"]
    algo = make_algorithm("spe", scenario, settings_of(q), farm["seed"])
    ex = make_executor(farm["executor"], spec, farm["workers"], "local", 3)
    t0 = time.perf_counter()
    c = Campaign(algo, ex, n_eps=n_eps(q["epsilon"], q["beta"]), budget=q["budget"], batch_size=farm["batch_size"],
                 pipeline_depth=farm["pipeline_depth"], seed=farm["seed"]).run()
    wall = time.perf_counter() - t0
    stats = ex.worker_stats() if hasattr(ex, "worker_stats") else None
    ex.close()
    return c, wall, stats


def main() -> None:
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": os.path.dirname(os.path.abspath(__file__))}})
    print(f"machine: {os.cpu_count()} cores; Ray {ray.__version__} local two-core mode")
    base = None
    for label, executor, workers in [("in-process", "local", 1), ("Ray, 1 worker", "ray", 1),
                                     ("Ray, 2 workers", "ray", 2)]:
        c, wall, stats = run_campaign(campaign_config(executor=executor, workers=workers))
        rate = c.committed / wall
        base = base or rate
        idle = ""
        if stats:
            busy = np.array([s["busy_s"] for s in stats])
            idle = f", worker idle fraction {1 - busy.mean() / wall:.2f}"
        print(f"lead-follow idm SPE (delta 2 -> 0.5, uniform Gamma): {label:15s} {rate:9,.0f} committed runs/s "
              f"({c.committed} runs, {wall:.1f} s; {rate / base:.2f}x in-process{idle})")
    # per-batch overhead: tiny batches, where simulation time is negligible
    from scenarios.simulator import SimSpec
    from farm.ray_executor import RayExecutor

    spec = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 2, 0)
    ex = RayExecutor(spec, 1, "local")
    starts = np.tile([[10.0, 10.0, 30.0]], (8, 1))
    ex.result(ex.submit(0, starts))
    t0 = time.perf_counter()
    for i in range(200):
        ex.result(ex.submit(i * 8, starts))
    per_batch = (time.perf_counter() - t0) / 200
    ex.close()
    print(f"Ray per-batch round trip (8 runs, K = 2, submit + result): {per_batch * 1e3:.2f} ms")
    # a slow simulator: 20 us per run-step; the coordinator is then a small share
    rates = {}
    for workers in (1, 2):
        cfg = campaign_config("slow_scenario:SlowLeadFollow", "ray", workers, batch=256, delta_min=1.0)
        cfg["quantify"]["budget"] = 20_000
        c, wall, stats = run_campaign(cfg)
        rates[workers] = c.committed / wall
        busy = np.array([s["busy_s"] for s in stats])
        print(f"slow simulator (20 us per run-step), Ray {workers} worker(s): {rates[workers]:,.0f} committed runs/s, "
              f"worker idle fraction {1 - busy.mean() / wall:.2f}")
    print(f"slow simulator speed-up, 2 workers over 1: {rates[2] / rates[1]:.2f}x")
    ray.shutdown()


if __name__ == "__main__":
    main()
