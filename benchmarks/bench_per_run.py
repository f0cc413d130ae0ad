"""Per-run simulator throughput (scenarios/per_run.py): runs per second in one process,
lead-follow from uniform starts, K = 50, adversarial actions, for highway-env's IDM
vehicle (examples/highway/highway_idm.py) and for a simulator that does nothing
(tests/per_run_simulators.py: ``Still``), which is the cost the farm adds per run and
step (action draw, classification, checks). Median of ``repeats``; this VM is shared
and its timings swing, so compare the ratios.

    pip install -e '.[highway]'
    python benchmarks/bench_per_run.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "examples" / "highway"), str(ROOT / "tests")]

from scenarios.action_modes import make_action_policy  # noqa: E402
from scenarios.registry import make_backend  # noqa: E402
from scenarios.rollout import run_scenario  # noqa: E402
from scenarios.streams import RunStreams  # noqa: E402

BACKENDS = {"highway-env IDM (per-run)": "highway_idm:HighwayIDM",
            "nothing (per-run, Still)": "per_run_simulators:Still"}


def measure(backend_name: str, runs: int = 400, horizon: int = 50, repeats: int = 5) -> tuple[float, float]:
    """-> (median runs/s, steps per run)."""
    backend = make_backend({"name": "lead-follow", "backend": backend_name})
    sc = backend.scenario
    starts = sc.lower + (sc.upper - sc.lower) * np.random.default_rng(0).random((runs, sc.n))
    policy = make_action_policy("adversarial", sc)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        batch = run_scenario(backend, starts, horizon, policy, RunStreams.of(0, np.arange(runs)))
        times.append(time.perf_counter() - t0)
    return runs / float(np.median(times)), batch.steps / runs


def main() -> None:
    for label, name in BACKENDS.items():
        rate, steps = measure(name)
        print(f"{label:28s}: {rate:8.1f} runs/s per process ({steps:.1f} steps a run, {rate * steps:9.0f} steps/s)")


if __name__ == "__main__":
    main()
