"""A large high-dimensional set's result phase: what a campaign spends after its last run,
on the volumes summary.json states and on the figures.

The set: the platoon of five (9-D), uniform Gamma, delta 2 -> 1, ``refine = "band"``,
stopped by ``budget = 120000`` (the case docs/benchmarks.md measured at 4.27 M boxes of
two sizes); made once by `quantify` (in-process, ~3 min, ~5 GB) unless ``--campaign``
names a finished campaign directory. Then, in a fresh process per checkout, it times:
reading safe_set.parquet, the union's volume estimate (Monte Carlo against the boxes)
and the hull's (the support function over every box), with the values they give, and
`scenario-farm report` (every figure) as a whole process.

    python benchmarks/bench_result_phase.py [--campaign DIR] [--vs CHECKOUT]

``--vs CHECKOUT``: another checkout (``git worktree add /tmp/before <commit>``), timed
the same way right after this one: the volumes must come out the same.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time


HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from bench_coordinator_cpu import checkout_env  # noqa: E402
from bench_high_dimension import CONFIG  # noqa: E402

# the child: the set from the campaign's files, then each estimate timed (the set's hash,
# which seeds them, is computed first and apart: it is the summary's result_hash anyway)
_VOLUMES = r"""
import json, sys, time
from pathlib import Path
from farm import api
t0 = time.perf_counter()
safe_set = api.open_campaign(sys.argv[1]).safe_set
t1 = time.perf_counter()
safe_set.result_hash
t2 = time.perf_counter()
union = safe_set.union_estimate(None)
t3 = time.perf_counter()
hull = safe_set.hull_estimate(None)
t4 = time.perf_counter()
print(json.dumps({"boxes": len(safe_set), "read_s": t1 - t0, "hash_s": t2 - t1, "union_s": t3 - t2,
                  "hull_s": t4 - t3, "union": union.value, "hull": hull.value}))
"""


def measure(campaign: str, checkout: str | None) -> dict:
    """The volumes' and the figures' times for ``campaign`` (with ``checkout``'s packages first)."""
    env = checkout_env(checkout)
    proc = subprocess.run([sys.executable, "-c", _VOLUMES, campaign], capture_output=True, text=True, env=env,
                          cwd=checkout)
    if proc.returncode != 0:
        sys.exit(f"bench_result_phase: the volumes of {campaign} failed: {proc.stderr.strip()[-400:]}")
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "farm", "report", campaign], capture_output=True, text=True,
                          env=env, cwd=checkout)
    if proc.returncode != 0:
        sys.exit(f"bench_result_phase: report {campaign} exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    row["report_s"] = time.perf_counter() - t0
    return row


def _line(label: str, row: dict) -> str:
    return (f"{label}{row['boxes']:,} boxes: read {row['read_s']:.1f} s, result hash {row['hash_s']:.1f} s, "
            f"union volume {row['union_s']:.1f} s ({row['union']:.6g}), hull volume {row['hull_s']:.1f} s "
            f"({row['hull']:.6g}), `report` (every figure) {row['report_s']:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", help="a finished campaign directory (default: made from the 9-D case)")
    ap.add_argument("--vs", metavar="CHECKOUT", help="another checkout, timed the same way after this one")
    args = ap.parse_args()
    if args.vs is not None and not os.path.isfile(os.path.join(args.vs, "coordinator", "__init__.py")):
        sys.exit(f"bench_result_phase: --vs {args.vs}: not a checkout of this repository (no coordinator/)")
    campaign = args.campaign
    if campaign is None:
        work = tempfile.mkdtemp(prefix="bench_result_")
        config, campaign = os.path.join(work, "platoon5_band.toml"), os.path.join(work, "campaign")
        with open(config, "w") as f:
            f.write(CONFIG.format(vehicles=5, delta_min=1.0, refine="band", budget=120000))
        print("making the set: platoon of five, band refinement, budget 120,000 runs (~3 min)", flush=True)
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "farm", "quantify", config, "--out", campaign, "--quiet"],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(f"bench_result_phase: quantify exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
        print(f"quantify: {time.perf_counter() - t0:.0f} s (campaign and result phase)", flush=True)
    print(f"machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}", flush=True)
    this = measure(campaign, None)
    print(_line("this code: ", this), flush=True)
    if args.vs is not None:
        other = measure(campaign, args.vs)
        print(_line(f"vs {args.vs}: ", other), flush=True)
        same = (this["union"], this["hull"]) == (other["union"], other["hull"])
        print(f"volumes {'the same' if same else 'DIFFER'}; union {other['union_s'] / this['union_s']:.1f}x, "
              f"hull {other['hull_s'] / this['hull_s']:.1f}x, report {other['report_s'] / this['report_s']:.1f}x "
              f"faster here", flush=True)
        if not same:
            sys.exit("bench_result_phase: the volumes differ between the checkouts")


if __name__ == "__main__":
    main()
