"""Numpy back end throughput: lead-follow / idm, B = 100k runs, K = 50 states, with
classification and trajectory storage; scenario-steps per second on one core.

    python benchmarks/bench_numpy.py
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from farm.streams import RunStreams
from scenarios import make_scenario
from scenarios.actions import make_action_policy
from scenarios.run import run_scenario

TARGET = 3e7


def measure(mode: str, batch: int = 100_000, horizon: int = 50, repeats: int = 3) -> tuple[float, int]:
    sc = make_scenario("lead-follow", sv_policy="idm")
    policy = make_action_policy(mode, sc)
    starts = sc.lower + (sc.upper - sc.lower) * np.random.default_rng(0).random((batch, sc.n))
    streams = RunStreams.of(0, np.arange(batch))
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = run_scenario(sc, starts, horizon, policy, streams)
        best = min(best, time.perf_counter() - t0)
    return out.steps / best, out.steps


def main() -> None:
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.processor() or 'cpu'}; "
          f"numpy {np.__version__}; one process (one core)")
    for mode in ("uniform", "adversarial"):
        rate, steps = measure(mode)
        print(f"numpy back end, lead-follow idm, actions {mode:11s}: {rate:.3g} scenario-steps/s per core "
              f"({steps} steps; target {TARGET:.0e}: {rate / TARGET:.2f}x)")


if __name__ == "__main__":
    main()
