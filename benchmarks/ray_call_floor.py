"""Ray's own cost per actor call, as the driver process pays it (every thread of it: the
main thread's ``.remote`` and ``ray.get``, and Ray's io threads), with a bare actor shaped
like the farm's replacement call (one tuple argument; two returns, a small pickled summary
and a visited-states tuple). What the farm adds around its calls is not in it: this is the
floor under ``benchmarks/bench_coordinator_cpu.py``'s case, whose ~1,300 calls it prices
(issue 54 point 2: 150,000 committed runs per CPU-second leave ~2.5 CPU-s for that case).

    python benchmarks/ray_call_floor.py [--calls 1000] [--repeat 3]

"one at a time": each call waited for before the next (the commit head waiting for a
replacement); "pipelined": all sent, then all read (a fill's chunks).
"""

from __future__ import annotations

import argparse
import os
import pickle
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_coordinator_cpu import TARGET  # noqa: E402  (the bar: committed runs per CPU-second)

CASE_CALLS = 1_300  # Ray calls of the bench case (docs/benchmarks.md, "2026-11-29, night")
CASE_RUNS = 377_407  # its committed runs less its tiny run's (the same entry)


def process_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)  # every thread of this process, no child
    return usage.ru_utime + usage.ru_stime


def measure(calls: int, repeat: int) -> list[dict]:
    import ray

    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
    try:
        @ray.remote(num_cpus=0)
        class Bare:
            @ray.method(num_returns=2)
            def run(self, chunk):
                summary = {"lengths": np.zeros(2), "last": np.zeros((2, 3)), "outcomes": np.zeros(2, dtype=np.int8)}
                return pickle.dumps(summary), (np.zeros((100, 3)), np.arange(3))

        actors = [Bare.remote() for _ in range(2)]
        ray.get([a.run.remote(None)[0] for a in actors])
        chunk = (5, np.zeros((2, 3)), ("changes", [pickle.dumps([np.zeros(40)] * 3)], 7), None, np.arange(2))
        rows = []
        for _ in range(repeat):
            cpu, main = process_cpu(), time.thread_time()
            for i in range(calls):
                ref, _ = actors[i % 2].run.remote(chunk)
                pickle.loads(ray.get(ref))
            rows.append({"mode": "one at a time", "process_ms": 1e3 * (process_cpu() - cpu) / calls,
                         "main_ms": 1e3 * (time.thread_time() - main) / calls})
            cpu, main = process_cpu(), time.thread_time()
            refs = [actors[i % 2].run.remote(chunk)[0] for i in range(calls)]
            for blob in ray.get(refs):
                pickle.loads(blob)
            rows.append({"mode": "pipelined", "process_ms": 1e3 * (process_cpu() - cpu) / calls,
                         "main_ms": 1e3 * (time.thread_time() - main) / calls})
        return rows
    finally:
        ray.shutdown()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = measure(args.calls, args.repeat)
    print(f"Ray's floor per actor call, {args.calls} calls x {args.repeat} (machine: {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f})")
    print(f"{'mode':<14} {'process CPU-ms':>14} {'main thread':>12}")
    for row in rows:
        print(f"{row['mode']:<14} {row['process_ms']:>14.3f} {row['main_ms']:>12.3f}")
    waiting = sorted(r["process_ms"] for r in rows if r["mode"] == "one at a time")
    median = waiting[len(waiting) // 2]
    print(f"the bench case's ~{CASE_CALLS:,} calls at the one-at-a-time median: {median * CASE_CALLS / 1e3:.2f} CPU-s "
          f"of the {CASE_RUNS / TARGET:.1f} the {TARGET:,} bar allows it")


if __name__ == "__main__":
    main()
