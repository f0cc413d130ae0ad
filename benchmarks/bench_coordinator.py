"""Coordinator throughput.

1. Trajectory-state queries/s of the spatial index (is this state covered by an alive
   box? is it within delta of PhiBar?) at 1e3, 1e4, 1e5 and 1e6 boxes, on lead-follow's
   state space with lattice-plus-explored boxes, for two query sets: points uniform over
   Sigma, and the states visited by lead-follow idm runs (stopped vehicles put many of
   them on Sigma's faces).
2. A real SPE campaign (lead-follow idm, Gamma*, delta 2 -> 0.25): coordinator time
   (draw + scan + apply + decay, simulation excluded) against committed runs, and the
   log-log slope of total coordinator time against runs (1 = linear).

    python benchmarks/bench_coordinator.py
"""

from __future__ import annotations

import time

import numpy as np

from coordinator.lattice import Lattice
from coordinator.spatial import PointIndex
from farm.execution.memory import keep_freed_memory
from targets import check, finish

TARGET_QPS = 5e6
TARGET_SLOPE = 1.15


def index_of_size(boxes: int, rng) -> tuple[PointIndex, float]:
    """About ``boxes`` alive boxes over lead-follow's Sigma: the lattice at the matching
    delta with a random 10% of its centres missing, explored (off-lattice) points in
    their place, then 5% of everything pruned. The same mix at every size."""
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([20.0, 20.0, 70.0])
    delta = (np.prod(hi - lo) / boxes) ** (1 / 3) / 2
    lattice = Lattice.tiling(lo, hi, delta)
    centres = lattice.box_centres(delta)
    keep = rng.random(len(centres)) >= 0.1
    index = PointIndex(3, 2 * delta, lattice.anchor, bounds=(lo, hi))
    index.insert(centres[keep])
    index.insert(lo + (hi - lo) * rng.random((len(centres) - int(keep.sum()), 3)))  # explored points
    index.kill(rng.choice(index.count, size=index.count // 20, replace=False))  # pruned
    return index, delta


def visited_queries(queries: int = 400_000) -> np.ndarray:
    """States visited by lead-follow idm runs (uniform Gamma) from uniform starts."""
    from scenarios import make_scenario
    from scenarios.action_modes import make_action_policy
    from scenarios.backend import NumpyBackend
    from scenarios.rollout import run_scenario
    from scenarios.streams import RunStreams

    sc = make_scenario("lead-follow", sv_policy="idm")
    rng = np.random.default_rng(0)
    starts = sc.lower + (sc.upper - sc.lower) * rng.random((queries // 20, sc.n))
    batch = run_scenario(NumpyBackend(sc), starts, 50, make_action_policy("uniform", sc),
                         RunStreams.of(0, np.arange(len(starts))))
    states, _ = batch.visited()
    return states[rng.permutation(len(states))[:queries]]


def query_rate(boxes: int, q: np.ndarray | None = None, repeats: int = 7) -> tuple[float, int, float]:
    """-> (queries/s, median of ``repeats`` passes; alive boxes; share of queries not
    settled by the home cell). ``q``: the queries (default: 400k uniform over Sigma)."""
    rng = np.random.default_rng(boxes)
    index, delta = index_of_size(boxes, rng)
    if q is None:
        q = np.array([20, 20, 70]) * rng.random((400_000, 3))
    queries = len(q)
    index.any_within(q[:1000], delta)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        index.any_within(q, delta)
        times.append(time.perf_counter() - t0)
    rate = queries / float(np.median(times))
    home = np.floor((q - index.origin) / index.cell).astype(np.int64)  # the home-cell lookup, again
    misses = float(np.mean(index._centre_point[index._flat(home)] < 0))
    return rate, index.alive_count, misses


def campaign_scaling() -> tuple[list[tuple[int, float]], float]:
    from coordinator.driver import Campaign, CampaignSettings
    from coordinator.spe import SPE, SPESettings
    from farm.execution.local import LocalExecutor
    from scenarios import make_scenario
    from scenarios.simulator import SimSpec

    sc = make_scenario("lead-follow", sv_policy="idm")
    algo = SPE(sc, SPESettings(delta0=2.0, delta_min=0.25))
    executor = LocalExecutor(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "adversarial"}, 50, 0))
    sim_time = [0.0]
    result = executor.result

    def timed_result(handle):
        t0 = time.perf_counter()
        out = result(handle)
        sim_time[0] += time.perf_counter() - t0
        return out

    executor.result = timed_result
    points = []
    t_start = time.perf_counter()

    def on_chunk(c):
        points.append((c.counters.committed, time.perf_counter() - t_start - sim_time[0]))

    Campaign(algo, executor, CampaignSettings(epsilon=0.001, beta=0.1, budget=2_000_000), observers=[on_chunk]).run()
    runs = np.array([p[0] for p in points], dtype=float)
    secs = np.array([p[1] for p in points])
    keep = runs >= runs[-1] / 30  # fit the part where fixed start-up costs are negligible
    slope = float(np.polyfit(np.log(runs[keep]), np.log(secs[keep]), 1)[0])
    marks = [points[int(i)] for i in np.linspace(0, len(points) - 1, 6)]
    return marks, slope


def main() -> None:
    keep_freed_memory()  # as the CLI's coordinator process does
    visited = visited_queries()
    for boxes in (10**3, 10**4, 10**5, 10**6):
        for label, q in (("uniform over Sigma", None), ("visited states", visited)):
            rate, alive, misses = query_rate(boxes, q)
            print(f"spatial index, {alive:>9,} boxes: {rate:.3g} trajectory-state queries/s "
                  f"(median of 7 passes; queries {label}, {misses:.0%} not settled by their home cell; "
                  f"target {TARGET_QPS:.0e}: {rate / TARGET_QPS:.2f}x, "
                  f"{check(f'{alive:,} boxes, {label}: >= {TARGET_QPS:.0e} queries/s', rate >= TARGET_QPS)})")
    marks, slope = campaign_scaling()
    for runs, secs in marks:
        print(f"  SPE coordinator time after {runs:>9,} committed runs: {secs:7.2f} s")
    print(f"SPE coordinator: log-log slope of total time against committed runs: {slope:.3f} "
          f"(target <= {TARGET_SLOPE}, {check(f'coordinator slope <= {TARGET_SLOPE}', slope <= TARGET_SLOPE)}); "
          f"{marks[-1][0] / marks[-1][1]:,.0f} committed runs/s of coordinator time")
    finish()


if __name__ == "__main__":
    main()
