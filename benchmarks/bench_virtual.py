"""Time to the result on a farm of slow simulators, from the virtual farm: the real
coordinator on a simulated clock (farm/execution/virtual.py). 1 / 32 / 256 / 1000 virtual
workers, a run of 1 s or 0.1 s (full horizon; a run that ends early takes its share),
a call cost of 1 ms per chunk, seeds 0-3; the campaign is the scaling campaign
(lead-follow idm, uniform Gamma, eps 0.001, beta 0.1, delta 2 -> 1, certified) with the
defaults (sequential counting: the window follows the workers). Prints the simulated time
to the result, the workers' utilisation and the speed-up over one worker, and writes
docs/virtual.json (rendered into docs/virtual.md).

    python benchmarks/bench_virtual.py [--seeds 0 1 2 3] [--workers 1 32 256 1000] [--run-time 1.0 0.1]
    python benchmarks/bench_virtual.py --seeds 1 --merge    # adds seed 1's rows to docs/virtual.json
    python benchmarks/bench_virtual.py --render
    python benchmarks/bench_virtual.py --no-write    # print only (benchmarks/run_all.py); exit 1 on a missed target

``--free-coordinator`` asks what the counting rule itself allows: the same campaigns with a
coordinator that costs no simulated time (no CPU charged, no call cost) and applies changes
past holds at any run time (``--outstanding`` at once); speed-ups against the rows' one
worker (docs/virtual.json "free"):

    python benchmarks/bench_virtual.py --free-coordinator [--workers 1000] [--outstanding 4 8]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "experiments"))

from experiment import machine_stamp  # noqa: E402
from targets import check, finish  # noqa: E402

DOCS = HERE.parent / "docs"
TARGETS = {(1.0, 32): 28, (1.0, 256): 200, (1.0, 1000): 600, (0.1, 1000): 500}  # issue 32


def config(workers: int, run_time: float, seed: int, counting: str = "sequential", call_cost: float = 0.001):
    from farm import config as config_mod

    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": 1.0, "epsilon": 0.001, "beta": 0.1, "horizon": 50},
        "farm": {"executor": "virtual", "workers": workers, "seed": seed, "counting": counting,
                 "virtual": {"run_time": run_time, "call_cost": call_cost}}})


def run(workers: int, run_time: float, seed: int, free: bool = False, outstanding: int | None = None) -> dict:
    """One campaign on the virtual farm. ``free``: the coordinator costs no simulated time
    (its CPU not charged, no call cost) and applies up to ``outstanding`` changes past
    holds at any run time (a copy costs it nothing)."""
    from coordinator.driver import speculation
    from farm.jobs.campaign_setup import build_algorithm, build_campaign
    from farm.execution.process import build_simulator, spec_of
    from farm.execution.factory import make_executor

    cfg = config(workers, run_time, seed, call_cost=0.0 if free else 0.001)
    simulator = build_simulator(spec_of(cfg))
    algorithm = build_algorithm(cfg, simulator)
    executor = make_executor(cfg.farm, spec_of(cfg))
    executor.charge_coordinator = not free
    kept = speculation.RUN_S, speculation.MAX_OUTSTANDING
    if free:
        speculation.RUN_S = 0.0
        speculation.MAX_OUTSTANDING = outstanding or speculation.MAX_OUTSTANDING
    t0 = time.perf_counter()
    try:
        campaign = build_campaign(cfg, algorithm, simulator, executor)
        c = campaign.run()
    finally:
        speculation.RUN_S, speculation.MAX_OUTSTANDING = kept
    return {"workers": workers, "run_time": run_time, "seed": seed, "result_hash": algorithm.result().result_hash,
            "committed": c.committed, "replaced": c.runs_replaced, "simulated": c.runs_simulated,
            "virtual_elapsed_s": round(executor.clock, 2), "utilisation": round(executor.utilisation, 4),
            "coordinator_cpu_s": round(executor.coordinator_s, 2), "chunks": executor.chunks,
            "waited_s": round(executor.waited_s, 2), "waited_replacements_s": round(executor.waited_replacements_s, 2),
            "lanes": executor.lanes, "held": campaign.held.passed,
            "rewound": campaign.held.rewound, "wall_s": round(time.perf_counter() - t0, 1),
            **({"outstanding": outstanding or speculation.MAX_OUTSTANDING} if free else {})}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--workers", type=int, nargs="+", default=None, help="default 1 32 256 1000 (free: 1000)")
    ap.add_argument("--run-time", type=float, nargs="+", default=[1.0, 0.1])
    ap.add_argument("--render", action="store_true")
    ap.add_argument("--free-coordinator", action="store_true",
                    help="the coordinator free (no CPU, no call cost): what the counting rule allows; "
                         "rows to docs/virtual.json's 'free' (default --workers 1000)")
    ap.add_argument("--outstanding", type=int, nargs="+", default=None,
                    help="with --free-coordinator: changes applied past holds at once (default: the campaign's)")
    ap.add_argument("--no-write", action="store_true", help="print only (no docs/virtual.json)")
    ap.add_argument("--merge", action="store_true",
                    help="keep docs/virtual.json's other rows (runs of other seeds or run times, e.g. in parallel)")
    args = ap.parse_args()
    if args.render:
        print(render())
        return
    if args.free_coordinator:
        free_rows(args, args.workers or [1000])
        return
    rows = []
    for run_time in args.run_time:
        for seed in args.seeds:
            one = None
            for workers in args.workers or [1, 32, 256, 1000]:
                row = run(workers, run_time, seed)
                one = one or row
                row["speedup"] = round(one["virtual_elapsed_s"] / row["virtual_elapsed_s"], 1)
                rows.append(row)
                target = TARGETS.get((run_time, workers))
                verdict = check(f"{run_time:g} s runs, {workers} workers, seed {seed}: >= {target}x one worker",
                                row["speedup"] >= target) if target else None
                print(f"run {run_time:g} s, seed {seed}, {workers:>4} workers: {row['virtual_elapsed_s']:>10,.1f} s "
                      f"to the result ({row['speedup']:.1f}x one worker"
                      f"{f'; target >= {target}x: {verdict}' if target else ''}), utilisation {row['utilisation']:.2f}, "
                      f"coordinator {row['coordinator_cpu_s']:.1f} CPU-s, {row['committed']:,} committed "
                      f"(result {row['result_hash']})", flush=True)
    if args.no_write:
        finish()
        return
    path = DOCS / "virtual.json"
    before = json.loads(path.read_text()) if path.exists() else {}
    if args.merge and before:
        mine = {(r["workers"], r["run_time"], r["seed"]) for r in rows}
        rows = [r for r in before["rows"] if (r["workers"], r["run_time"], r["seed"]) not in mine] + rows
    free = before.get("free", [])  # the --free-coordinator rows: kept (re-run them after a change of the rule)
    path.write_text(json.dumps({"meta": machine_stamp(cpus=os.cpu_count()), "rows": rows,
                                **({"free": free} if free else {})}, indent=1) + "\n")
    print(render())
    finish()


def free_rows(args, workers: list[int]) -> None:
    """The --free-coordinator rows, against the one-worker rows already in docs/virtual.json."""
    from coordinator.driver import speculation

    path = DOCS / "virtual.json"
    data = json.loads(path.read_text())
    one = {(r["run_time"], r["seed"]): r for r in data["rows"] if r["workers"] == 1}
    outstanding = args.outstanding or [speculation.MAX_OUTSTANDING]
    missing = [(t, s) for t in args.run_time for s in args.seeds if (t, s) not in one]
    if missing:
        raise SystemExit(f"--free-coordinator: docs/virtual.json has no one-worker row for (run time, seed) {missing}; "
                         "run them first: python benchmarks/bench_virtual.py --workers 1 --merge")
    rows = []
    for run_time in args.run_time:
        for seed in args.seeds:
            for n in outstanding:
                for w in workers:
                    row = run(w, run_time, seed, free=True, outstanding=n)
                    base = one[(run_time, seed)]
                    if row["result_hash"] != base["result_hash"]:
                        raise SystemExit(f"free coordinator, seed {seed}: result {row['result_hash']} differs from "
                                         f"the one-worker row's {base['result_hash']}")
                    row["speedup"] = round(base["virtual_elapsed_s"] / row["virtual_elapsed_s"], 1)
                    rows.append(row)
                    print(f"free coordinator, run {run_time:g} s, seed {seed}, {w:>4} workers, {n} changes past "
                          f"holds: {row['virtual_elapsed_s']:,.1f} s ({row['speedup']:.1f}x one worker), head "
                          f"waiting {row['waited_s']:,.1f} s, {row['waited_replacements_s']:,.1f} s of it for "
                          "replacements", flush=True)
    mine = {(r["workers"], r["run_time"], r["seed"], r["outstanding"]) for r in rows}
    data["free"] = [r for r in data.get("free", [])
                    if (r["workers"], r["run_time"], r["seed"], r["outstanding"]) not in mine] + rows
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(render())


def render() -> Path:
    """docs/virtual.md from docs/virtual.json."""
    import numpy as np

    from coordinator.driver import speculation

    data = json.loads((DOCS / "virtual.json").read_text())
    rows, meta = data["rows"], data["meta"]
    run_times = sorted({r["run_time"] for r in rows}, reverse=True)
    workers = sorted({r["workers"] for r in rows})
    seeds = sorted({r["seed"] for r in rows})
    out = ["# Time to the result on many workers: the virtual farm", "",
           "<!-- rendered by `python benchmarks/bench_virtual.py --render` from docs/virtual.json: edit the script, "
           "not this file -->", "",
           f"`python benchmarks/bench_virtual.py` ({meta['date']}, {meta['machine']}): the real coordinator on a "
           "simulated clock (farm/execution/virtual.py). lead-follow idm, uniform Gamma, eps 0.001, beta 0.1, "
           "delta 2 -> 1, certified, the defaults (sequential counting; the window follows the workers; "
           "replacements to fast lanes, one per 16 workers, as on Ray), a call "
           f"cost of 1 ms per chunk, seeds {', '.join(map(str, seeds))}. The coordinator's own CPU time is "
           "charged to the clock (as measured on this machine). Every worker count gives the same result hash "
           "per seed (checked below).", "",
           "| run time | workers | time to the result, median | speed-up over 1 worker, median (min-max) | "
           "utilisation | coordinator CPU-s | target |",
           "| ---: | ---: | ---: | --- | ---: | ---: | ---: |"]
    for run_time in run_times:
        for w in workers:
            sel = [r for r in rows if r["run_time"] == run_time and r["workers"] == w]
            if not sel:
                continue
            speed = [r["speedup"] for r in sel]
            target = TARGETS.get((run_time, w))
            out.append(f"| {run_time:g} s | {w:,} | {np.median([r['virtual_elapsed_s'] for r in sel]):,.0f} s | "
                       f"{np.median(speed):.0f}x ({min(speed):.0f}-{max(speed):.0f}) | "
                       f"{np.median([r['utilisation'] for r in sel]):.2f} | "
                       f"{np.median([r['coordinator_cpu_s'] for r in sel]):.1f} | "
                       f"{'>= %dx' % target if target else ''} |")
    same = all(len({r["result_hash"] for r in rows if r["seed"] == s}) == 1 for s in seeds)
    out += ["", f"One result hash per seed across worker counts and run times: {'yes' if same else 'NO'}.", "",
            "Where a target is missed: the coordinator's own CPU and one call per chunk are on the clock, "
            "in series, however many workers wait; and so are the head's waits for runs that the counting "
            "rule orders (below: with the coordinator free, these alone miss the targets)."]
    for r in rows:
        target = TARGETS.get((r["run_time"], r["workers"]))
        if target and r["speedup"] < target:
            one = next(o for o in rows if o["seed"] == r["seed"] and o["run_time"] == r["run_time"]
                       and o["workers"] == 1)
            out.append(f"- {r['run_time']:g} s runs, {r['workers']:,} workers, seed {r['seed']}: "
                       f"{r['virtual_elapsed_s']:,.1f} s to the result against {one['virtual_elapsed_s'] / r['workers']:,.1f} s "
                       f"with every worker busy; the coordinator's CPU {r['coordinator_cpu_s']:.1f} s and "
                       f"{r['chunks']:,} chunk calls at 1 ms ({r['chunks'] / 1000:.1f} s) are on the clock; the head "
                       f"waited {r['waited_s']:,.1f} s for runs, {r['waited_replacements_s']:,.1f} s of it for "
                       "replacements (they may change the set: a round's end waits for all of them, a change for those "
                       f"before it, for runs of {speculation.RUN_S:g} s or more only once "
                       f"{speculation.MAX_OUTSTANDING} changes are applied past holds, "
                       "coordinator/driver/speculation.py), the rest for batch runs not back yet (after a round end the "
                       "pipeline refills).")
    out += free_table(data)
    path = DOCS / "virtual.md"
    path.write_text("\n".join(out) + "\n")
    return path


def free_table(data: dict) -> list[str]:
    """The --free-coordinator rows: what sequential counting allows whatever the coordinator costs."""
    import numpy as np

    free = data.get("free", [])
    if not free:
        return []
    one = {(r["run_time"], r["seed"]): r["virtual_elapsed_s"] for r in data["rows"] if r["workers"] == 1}
    costed = {(r["run_time"], r["seed"], r["workers"]): r["virtual_elapsed_s"] for r in data["rows"]}
    out = ["", "## What the counting rule allows: the coordinator free", "",
           "`python benchmarks/bench_virtual.py --free-coordinator --outstanding 4 8`: the same campaigns with a "
           "coordinator that costs no simulated time (its CPU not charged, no call cost) and applies changes past "
           "holds (coordinator/driver/speculation.py) at any run time, 4 or 8 at once; speed-ups against the one-worker "
           "rows above. What is left (all of the time) is the head waiting for runs the rule orders: a replacement that may change "
           "the set before the change after it, a round's end for its streak's replacements, a new round for "
           "its first runs. A target that this table misses cannot be met by a faster coordinator or cheaper "
           "calls, only by fewer such waits.", "",
           "| run time | workers | changes past holds | time to the result, median | speed-up, median (min-max) | "
           "head waiting for replacements, median | with the coordinator's costs (above), median | target |",
           "| ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: |"]
    for key in sorted({(r["run_time"], r["workers"], r["outstanding"]) for r in free}, key=lambda k: (-k[0], k[1], k[2])):
        run_time, w, n = key
        sel = [r for r in free if (r["run_time"], r["workers"], r["outstanding"]) == key]
        speed = [one[(r["run_time"], r["seed"])] / r["virtual_elapsed_s"] for r in sel]
        paid = [costed[(r["run_time"], r["seed"], w)] for r in sel if (r["run_time"], r["seed"], w) in costed]
        target = TARGETS.get((run_time, w))
        out.append(f"| {run_time:g} s | {w:,} | {n} | {np.median([r['virtual_elapsed_s'] for r in sel]):,.1f} s | "
                   f"{np.median(speed):.0f}x ({min(speed):.0f}-{max(speed):.0f}) | "
                   f"{np.median([r['waited_replacements_s'] for r in sel]):,.1f} s | "
                   f"{f'{np.median(paid):,.1f} s' if paid else ''} | {'>= %dx' % target if target else ''} |")
    seeds = sorted({r["seed"] for r in free})
    out += ["", f"Seeds {', '.join(map(str, seeds))}; every free row's result hash is its one-worker row's (checked "
            "when the row is run)."]
    return out


if __name__ == "__main__":
    main()
