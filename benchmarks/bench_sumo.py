"""SUMO back end throughput: lead-follow, SV = SUMO Krauss (sigma = 0), uniform scenario
actions, K = 50 states; scenarios (runs) per second in one process, for several batch
sizes. Start states are uniform over Sigma, so many runs end early (failure or
truncation), as in a real campaign; the mean run length is printed alongside.

    python benchmarks/bench_sumo.py

Prints a message and exits 0 when libsumo is not installed.
"""

from __future__ import annotations

import importlib.util
import os
import platform
import sys
import time

import numpy as np

from targets import check, finish

TARGET = 1200.0  # scenarios/s per worker process
KRAUSS = {"car_follow_model": "Krauss", "params": {"sigma": 0.0}}


def measure(batch: int, horizon: int = 50, repeats: int = 5, full_length: bool = False) -> tuple[float, float]:
    from scenarios.actions import UniformActions
    from scenarios.registry import make_backend
    from scenarios.rollout import run_scenario
    from scenarios.streams import RunStreams

    backend = make_backend({"name": "lead-follow", "backend": "sumo", "sv_policy": "sumo", "sumo": KRAUSS})
    sc = backend.scenario
    rng = np.random.default_rng(0)
    lower, upper = sc.lower.copy(), sc.upper.copy()
    if full_length:  # a start box from which (almost) every run lasts all K states
        lower, upper = np.array([5.0, 12.0, 40.0]), np.array([8.0, 14.0, 50.0])
    best, mean_len = np.inf, 0.0
    run_scenario(backend, lower + (upper - lower) * rng.random((batch, sc.n)), horizon, UniformActions(),
                 RunStreams.of(0, np.arange(batch)))  # warm-up: loads the simulation
    for rep in range(repeats):
        starts = lower + (upper - lower) * rng.random((batch, sc.n))
        streams = RunStreams.of(1, np.arange(rep * batch, (rep + 1) * batch))
        t0 = time.perf_counter()
        out = run_scenario(backend, starts, horizon, UniformActions(), streams)
        best = min(best, time.perf_counter() - t0)
        mean_len = float(out.lengths.mean())
    return batch / best, mean_len


def main() -> int:
    if importlib.util.find_spec("libsumo") is None:
        print("bench_sumo: libsumo is not installed (pip install 'scenario-farm[sumo]'); skipped")
        return 0
    import libsumo

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; libsumo {libsumo.__version__}; one process")
    for full in (False, True):
        for batch in (256, 1024, 4096):
            rate, mean_len = measure(batch, full_length=full)
            what = "all runs K=50  " if full else "starts ~ U(Sigma)"
            print(f"sumo back end, lead-follow Krauss, uniform actions, K=50, B={batch:5d}, {what}: "
                  f"{rate:7.0f} scenarios/s per process (mean run length {mean_len:.1f} states; "
                  f"target {TARGET:.0f}: {rate / TARGET:.2f}x, "
                  f"{check(f'B={batch}, {what.strip()}: >= {TARGET:.0f} scenarios/s', rate >= TARGET)})")
    finish()
    return 0


if __name__ == "__main__":
    sys.exit(main())
