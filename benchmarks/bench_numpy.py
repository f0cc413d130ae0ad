"""Numpy back end throughput: lead-follow / idm, B = 100k runs, K = 50 states, with
classification and trajectory storage; scenario-steps per second on one core.

The back end is built as a farm worker builds it (``build_simulator``, which also tunes
the allocator for batch numerics). One warm-up rollout, then the median and the best of
``repeats``: this VM's timings swing by 2x from run to run, the median is the figure.

    python benchmarks/bench_numpy.py
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from farm.execution.process import build_simulator
from scenarios.simulator import SimSpec
from scenarios.streams import RunStreams
from scenarios.rollout import run_scenario
from targets import check, finish

TARGET = 3e7


def measure(mode: str, batch: int = 100_000, horizon: int = 50, repeats: int = 9) -> tuple[float, float, int]:
    """-> (median, best) scenario-steps/s and the steps of one rollout."""
    sim = build_simulator(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": mode}, horizon, 0))
    sc, policy = sim.backend, sim.policy
    lo, hi = sim.scenario.lower, sim.scenario.upper
    starts = lo + (hi - lo) * np.random.default_rng(0).random((batch, sim.scenario.n))
    streams = RunStreams.of(0, np.arange(batch))
    run_scenario(sc, starts, horizon, policy, streams)  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = run_scenario(sc, starts, horizon, policy, streams)
        times.append(time.perf_counter() - t0)
    return out.steps / float(np.median(times)), out.steps / min(times), out.steps


def main() -> None:
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.processor() or 'cpu'}; "
          f"numpy {np.__version__}; one process (one core)")
    for mode in ("uniform", "adversarial"):
        median, best, steps = measure(mode)
        print(f"numpy back end, lead-follow idm, actions {mode:11s}: {median:.3g} scenario-steps/s per core "
              f"(median of 9; best {best:.3g}; {steps} steps per rollout; target {TARGET:.0e}: {median / TARGET:.2f}x, "
              f"{check(f'numpy back end, actions {mode}: >= {TARGET:.0e} steps/s', median >= TARGET)})")
    finish()


if __name__ == "__main__":
    main()
