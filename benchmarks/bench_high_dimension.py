"""A 7-D campaign as a user runs it: the platoon of four (shared/spec/scenarios.md,
section platoon; examples/platoon4_idm.toml) with uniform Gamma, delta 2 -> 1, eps
0.001, beta 0.1, certified, in-process on 2 workers (the "local" executor): ~250,000
boxes at delta 1 and ~1.2 M committed runs. It prints the whole `quantify` process's
wall time, CPU and peak memory, the round end's CPU (the children of 2,000 boxes
checked against the failures) and the closing edge's (``SPECertification._edge_mask``,
once per change of a closing round), and the result hash.

    python benchmarks/bench_high_dimension.py [--vehicles 4] [--delta-min 1] [--vs CHECKOUT]

``--vs CHECKOUT``: another checkout of this repository (``git worktree add /tmp/before
<commit>``), run the same way after this one: the before/after of a change, with the
same result hash expected. Needs ~4 GB (~9 GB before 2026-12-07's changes); run it with
nothing else on the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

CONFIG = """[scenario]
name = "platoon"
vehicles = {vehicles}
followers = 1
sv_policy = "idm"
[actions]
mode = "uniform"
[quantify]
algorithm = "spe"
epsilon = 0.001
beta = 0.1
delta0 = 2.0
gamma = 0.5
delta_min = {delta_min}
horizon = 50
sides = false
budget = 4000000
[farm]
executor = "local"
workers = 2
seed = 0
"""

# the child: thread-CPU timers on the driver's main thread, then the CLI's own entry
_CHILD = r"""
import functools, json, resource, sys, threading, time
from coordinator.spe import SPE
from coordinator.spe_certification import SPECertification
cpu = {"end_round": 0.0, "edge": 0.0}
calls = {"end_round": 0, "edge": 0}
main = threading.main_thread()

def timed(owner, name, label):
    f = getattr(owner, name)
    @functools.wraps(f)
    def wrapper(*a, **k):
        if threading.current_thread() is not main:
            return f(*a, **k)
        t = time.thread_time()
        try:
            return f(*a, **k)
        finally:
            cpu[label] += time.thread_time() - t
            calls[label] += 1
    setattr(owner, name, wrapper)

timed(SPE, "end_round", "end_round")
timed(SPECertification, "_edge_mask", "edge")
from farm.cli.commands import main as cli
started = time.monotonic()
code = cli(["quantify", sys.argv[1], "--out", sys.argv[2], "--force"])
wall = time.monotonic() - started
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"code": code, "wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "sys": usage.ru_stime,
                  "peak_mb": usage.ru_maxrss / 1024, "cpu_parts": cpu, "calls": calls}))
"""


def measure(checkout: str, config: str, out: str) -> dict:
    env = dict(os.environ, PYTHONPATH=checkout)
    done = subprocess.run([sys.executable, "-c", _CHILD, config, out], cwd=checkout, env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{checkout}: quantify failed (exit {done.returncode}): {done.stderr.strip().splitlines()[-1:]}")
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    figures.update(result=summary["result_hash"], runs=summary["runs_committed"], boxes=summary["boxes"])
    return figures


def line(label: str, m: dict) -> str:
    edge = m["cpu_parts"]["edge"]
    return (f"{label}: {m['runs']:,} committed runs, {m['boxes']:,} boxes, wall {m['wall']:.1f} s, process CPU "
            f"{m['cpu']:.1f} s (system {m['sys']:.1f}), peak {m['peak_mb']:,.0f} MB; round end "
            f"{m['cpu_parts']['end_round']:.2f} CPU-s; closing edge {edge:.2f} CPU-s over {m['calls']['edge']:,} "
            f"calls; result {m['result']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vehicles", type=int, default=4, help="platoon size: 2 + 1 + followers; 4 is 7-D")
    ap.add_argument("--delta-min", type=float, default=1.0)
    ap.add_argument("--vs", help="another checkout, run the same way after this one")
    args = ap.parse_args()
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory() as tmp:
        config = os.path.join(tmp, "case.toml")
        with open(config, "w") as f:
            f.write(CONFIG.format(vehicles=args.vehicles, delta_min=args.delta_min))
        print(f"machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; platoon of {args.vehicles} "
              f"({2 * args.vehicles - 1}-D), uniform Gamma, delta 2 -> {args.delta_min:g}, certified, in-process on "
              f"2 workers; whole `scenario-farm quantify` processes")
        this = measure(here, config, os.path.join(tmp, "this"))
        print(line("this checkout", this), flush=True)
        if args.vs:
            other = measure(os.path.abspath(args.vs), config, os.path.join(tmp, "other"))
            print(line(args.vs, other))
            same = "the same result" if other["result"] == this["result"] else "DIFFERENT results"
            print(f"{args.vs} / this checkout: wall {other['wall'] / this['wall']:.2f}x, process CPU "
                  f"{other['cpu'] / this['cpu']:.2f}x, peak memory {other['peak_mb'] / this['peak_mb']:.2f}x; {same}")


if __name__ == "__main__":
    main()
