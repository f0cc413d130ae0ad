"""Committed runs/s of a quantification campaign on the in-process executor and on 1 and
2 Ray workers (local two-core mode, numpy back end), Ray's per-batch round trip, worker
idle fraction, and the same campaign with a slow simulator (benchmarks/slow_backend.py,
4 us per run-step, as SUMO) on 1 and 2 workers. Many workers: bench_scaling.py.

    python benchmarks/bench_ray.py
"""

from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402


def campaign_config(executor="local", workers=1, backend="numpy", delta_min=0.5):
    from farm import config as config_mod

    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm", "backend": backend},
        "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                     "certify": False},
        "farm": {"executor": executor, "workers": workers, "seed": 0}})


def run_campaign(cfg):
    """-> (counters, wall seconds of the campaign loop, worker stats or None, result hash)."""
    from farm.jobs.campaign_setup import build_algorithm, build_campaign
    from farm.execution.process import build_simulator, spec_of
    from farm.execution.factory import make_executor

    spec = spec_of(cfg)
    sim = build_simulator(spec)
    algo = build_algorithm(cfg, sim)
    ex = make_executor(cfg.farm, spec)
    ray_actors = cfg.farm.executor == "ray"
    if ray_actors:
        ex.pids()  # actors up: start-up is not the campaign's
    t0 = time.perf_counter()
    c = build_campaign(cfg, algo, sim, ex).run()
    wall = time.perf_counter() - t0
    stats = ex.worker_stats() if ray_actors else None
    ex.close()
    return c, wall, stats, algo.result().result_hash


def idle(stats, wall) -> str:
    if not stats:
        return ""
    busy = np.array([s["busy_s"] for s in stats])
    return f", worker idle fraction {1 - busy.mean() / wall:.2f}"


def main() -> None:
    import ray

    from farm.ray_runtime.session import start_local

    start_local(2, HERE)
    print(f"machine: {os.cpu_count()} cores; Ray {ray.__version__} local two-core mode")
    base, hashes = None, set()
    for label, executor, workers in [("in-process", "local", 1), ("Ray, 1 worker", "ray", 1),
                                     ("Ray, 2 workers", "ray", 2)]:
        c, wall, stats, h = run_campaign(campaign_config(executor, workers))
        hashes.add(h)
        rate = c.committed / wall
        base = base or rate
        print(f"numpy back end, lead-follow idm SPE (delta 2 -> 0.5, uniform Gamma): {label:15s} {rate:9,.0f} "
              f"committed runs/s ({c.committed} runs, {wall:.1f} s; {rate / base:.2f}x in-process"
              f"{idle(stats, wall)})")
    from farm.ray_runtime.executor import RayExecutor
    from scenarios.simulator import SimSpec

    spec = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 2, 0)
    ex = RayExecutor(spec, 1, "local").start()
    starts = np.tile([[10.0, 10.0, 30.0]], (8, 1))
    ex.result(ex.submit(0, starts)[0])
    t0 = time.perf_counter()
    for i in range(200):
        ex.result(ex.submit(i * 8, starts)[0])
    per_batch = (time.perf_counter() - t0) / 200
    ex.close()
    print(f"Ray per-batch round trip (8 runs, K = 2, submit + result): {per_batch * 1e3:.2f} ms")
    rates = {}
    for workers in (1, 2):
        c, wall, stats, h = run_campaign(campaign_config("ray", workers, "slow_backend:SlowBackend", delta_min=1.0))
        hashes.add(("slow", h))
        rates[workers] = c.committed / wall
        print(f"slow simulator (4 us per run-step), Ray {workers} worker(s): {rates[workers]:,.0f} committed runs/s"
              f"{idle(stats, wall)}")
    print(f"slow simulator speed-up, 2 workers over 1: {rates[2] / rates[1]:.2f}x")
    print(f"same result on every executor: {len(hashes) == 2}")
    ray.shutdown()


if __name__ == "__main__":
    main()
