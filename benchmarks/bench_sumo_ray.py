"""SUMO back end on Ray: scenarios/s per worker (K = 50, lead-follow, Krauss, uniform
actions) with 1 and 2 workers, and the speed-up of 2 workers over 1. Each actor holds
its own libsumo simulation.

    python benchmarks/bench_sumo_ray.py
"""

from __future__ import annotations

import time

import numpy as np

from targets import check, finish


def main() -> None:
    try:
        import libsumo  # noqa: F401
    except ImportError:
        print("sumo back end: libsumo is not installed; skipped")
        return
    import ray

    from scenarios.simulator import SimSpec
    from farm.ray_runtime.executor import RayExecutor
    from farm.ray_runtime.session import start_local

    start_local(2)
    spec = SimSpec({"name": "lead-follow", "backend": "sumo", "sv_policy": "sumo",
                    "sumo": {"car_follow_model": "Krauss", "params": {"sigma": 0.0}}}, {"mode": "uniform"}, 50, 0)
    # starts where nobody crashes or leaves: every run lasts K = 50 states
    starts = np.tile([[10.0, 10.0, 60.0]], (2048, 1))
    rates = {}
    for workers in (1, 2):
        ex = RayExecutor(spec, workers, "local").start()
        for h in ex.submit(0, starts[:256]):  # warm up: one libsumo start per actor
            ex.result(h)
        t0 = time.perf_counter()
        handles = [h for i in range(6) for h in ex.submit(i * len(starts), starts)]  # a chunk per worker
        runs = sum(len(ex.result(h)) for h in handles)
        wall = time.perf_counter() - t0
        rates[workers] = runs / wall
        ex.close()
        print(f"sumo back end on Ray, {workers} worker(s): {rates[workers]:,.0f} scenarios/s "
              f"({rates[workers] / workers:,.0f} per worker; K = 50; target >= 1,200 per worker: "
              f"{check(f'{workers} worker(s): >= 1,200 scenarios/s per worker', rates[workers] / workers >= 1200)})")
    speedup = rates[2] / rates[1]
    print(f"sumo back end: speed-up of 2 workers over 1: {speedup:.2f}x "
          f"(target >= 1.8x: {check('2 workers >= 1.8x one', speedup >= 1.8)})")
    ray.shutdown()
    finish()


if __name__ == "__main__":
    main()
