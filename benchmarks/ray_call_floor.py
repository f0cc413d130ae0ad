"""Ray's own cost per actor call, as the driver process pays it (every thread of it: the
main thread's ``.remote`` and ``ray.get``, and Ray's io threads), with a bare actor shaped
like the farm's replacement call (one tuple argument; two returns, a small pickled summary
and a visited-states tuple). What the farm adds around its calls is not in it: this is the
floor under ``benchmarks/bench_coordinator_cpu.py``'s case, whose ~1,300 calls it prices
(issue 54 point 2: 150,000 committed runs per CPU-second leave ~2.5 CPU-s for that case).

    python benchmarks/ray_call_floor.py [--calls 1000] [--repeat 3]

"one at a time": each call waited for before the next (the commit head waiting for a
replacement); "pipelined": all sent, then all read (a fill's chunks). The compiled-graph
rows (Ray's ``experimental_compile``, "< 50 us of system overhead") price the other way to
call an actor: once bare, then both ways around a run that takes ``--wait-ms`` (the head
waits for a replacement's run): what the driver pays while it waits is why the farm does
not use it (docs/benchmarks.md, "2026-12-07").
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


def _row(mode: str, calls: int, cpu: float, main: float) -> dict:
    """Per call, since (``cpu``, ``main``) were read."""
    return {"mode": mode, "process_ms": 1e3 * (process_cpu() - cpu) / calls,
            "main_ms": 1e3 * (time.thread_time() - main) / calls}


def measure(calls: int, repeat: int, wait_ms: float) -> list[dict]:
    import ray
    from ray.dag import InputNode

    def summary() -> bytes:  # a small pickled summary, as the farm's actors return
        return pickle.dumps({"lengths": np.zeros(2), "last": np.zeros((2, 3)), "outcomes": np.zeros(2, dtype=np.int8)})

    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
    try:
        @ray.remote(num_cpus=0)
        class Bare:
            @ray.method(num_returns=2)
            def run(self, chunk):
                return summary(), (np.zeros((100, 3)), np.arange(3))

        @ray.remote(num_cpus=0)
        class Sleeping:  # a compiled graph's actor returns one value: the summary alone
            def run(self, chunk):
                time.sleep(chunk[0])
                return summary()

        actors = [Bare.remote() for _ in range(2)]
        ray.get([a.run.remote(None)[0] for a in actors])
        chunk = (5, np.zeros((2, 3)), ("changes", [pickle.dumps([np.zeros(40)] * 3)], 7), None, np.arange(2))
        # the plain calls go to an actor of their own: one in a compiled graph should run nothing else
        plain, in_graph = Sleeping.remote(), Sleeping.remote()
        with InputNode() as given:
            compiled = in_graph.run.bind(given).experimental_compile()
        waits = max(1, min(calls, int(1000 / max(wait_ms, 1.0))))  # about a second of waiting per row
        instant, slow = (0.0, *chunk[1:]), (wait_ms / 1e3, *chunk[1:])
        rows = []
        try:
            for _ in range(repeat):
                cpu, main = process_cpu(), time.thread_time()
                for i in range(calls):
                    ref, _ = actors[i % 2].run.remote(chunk)
                    pickle.loads(ray.get(ref))
                rows.append(_row("one at a time", calls, cpu, main))
                cpu, main = process_cpu(), time.thread_time()
                refs = [actors[i % 2].run.remote(chunk)[0] for i in range(calls)]
                for blob in ray.get(refs):
                    pickle.loads(blob)
                rows.append(_row("pipelined", calls, cpu, main))
                cpu, main = process_cpu(), time.thread_time()
                for _ in range(calls):
                    pickle.loads(ray.get(compiled.execute(instant)))
                rows.append(_row("compiled", calls, cpu, main))
                for label, call in ((f"plain, {wait_ms:g} ms run", lambda: ray.get(plain.run.remote(slow))),
                                    (f"compiled, {wait_ms:g} ms run", lambda: ray.get(compiled.execute(slow)))):
                    cpu, main = process_cpu(), time.thread_time()
                    for _ in range(waits):
                        pickle.loads(call())
                    rows.append(_row(label, waits, cpu, main))
            return rows
        finally:
            compiled.teardown()
    finally:
        ray.shutdown()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--wait-ms", type=float, default=5.0, help="the waited-for run of the last two rows")
    args = ap.parse_args()
    rows = measure(args.calls, args.repeat, args.wait_ms)
    print(f"Ray's floor per actor call, {args.calls} calls x {args.repeat} (machine: {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f})")
    print(f"{'mode':<22} {'process CPU-ms':>14} {'main thread':>12}")
    for row in rows:
        print(f"{row['mode']:<22} {row['process_ms']:>14.3f} {row['main_ms']:>12.3f}")
    waiting = sorted(r["process_ms"] for r in rows if r["mode"] == "one at a time")
    median = waiting[len(waiting) // 2]
    print(f"the bench case's ~{CASE_CALLS:,} calls at the one-at-a-time median: {median * CASE_CALLS / 1e3:.2f} CPU-s "
          f"of the {CASE_RUNS / TARGET:.1f} the {TARGET:,} bar allows it")


if __name__ == "__main__":
    main()
