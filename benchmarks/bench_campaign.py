"""End to end: the lead-follow idm SPE campaign (Gamma*, eps = 0.001, beta = 0.1), in-process
executor, through the same code path as `scenario-farm quantify`: wall time including the
result files and plots, and the process's peak resident memory.

    python benchmarks/bench_campaign.py                                    # delta_min 0.25
    python benchmarks/bench_campaign.py --delta-min 0.125 --no-certify    # the scale-out target
    python benchmarks/bench_campaign.py --delta-min 0.125 --refine band   # issue 36's target
    python benchmarks/bench_campaign.py --scenario fleet3 --delta-min 0.25 --refine band
    python benchmarks/bench_campaign.py --delta-min 0.125 --refine band --executor ray   # 2 Ray workers
    python benchmarks/bench_campaign.py --delta-min 0.125 --refine band --executor ray --whole-command

The second is issue 11's target (<= 45 s, <= 1.5 GB on a 2-core machine): 1.8 M boxes,
1.8 M runs, the campaign as it was specified (before certification was the default).
Run it in a fresh process: peak memory is the process's, imports included.
``--whole-command`` times ``python -m farm quantify`` on the same config as a process of its
own, from its start to its exit (issue 36's "end to end": the interpreter, Ray's start and
end, result files and plots), and its peak memory.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from farm import config as config_mod
from farm.jobs.quantification import run
from targets import check, finish

TARGETS = {0.25: (120.0, None), 0.125: (45.0, 1.5)}  # delta_min -> (s, GB)
WHOLE_TARGET = (12.0, 0.8)  # issue 36, lead-follow band 0.125 end to end: (s, GB)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--delta-min", type=float, default=0.25)
    ap.add_argument("--no-certify", action="store_true", help="quantify.certify = false")
    ap.add_argument("--refine", choices=["all", "band"], default="all", help="quantify.refine")
    ap.add_argument("--scenario", choices=["lead-follow", "fleet3"], default="lead-follow")
    ap.add_argument("--sv-policy", default="idm")
    ap.add_argument("--executor", choices=["local", "ray"], default="local", help="farm.executor (ray: farm.workers 2)")
    ap.add_argument("--whole-command", action="store_true", help="time `python -m farm quantify` as a process")
    args = ap.parse_args()
    quantify = {"delta0": 2.0, "delta_min": args.delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                "budget": 40_000_000, "refine": args.refine}
    if args.no_certify:
        quantify["certify"] = False
    cfg = config_mod.normalize({
        "scenario": {"name": args.scenario, "sv_policy": args.sv_policy}, "actions": {"mode": "adversarial"},
        "quantify": quantify, "farm": {"executor": args.executor, "seed": 0}})
    if args.whole_command:
        whole_command(cfg, args)
        return
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        s = run(cfg, Path(tmp) / "c", resume=False)
        wall = time.perf_counter() - t0
    peak_bytes = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux
    peak_gb = peak_bytes / 1e9  # the target's unit: decimal GB (1 GiB = 1.074 GB)
    target_s, target_gb = TARGETS.get(args.delta_min, (None, None)) if args.scenario == "lead-follow" else (None, None)
    verdict = []
    if target_s:
        verdict.append(f"target <= {target_s:.0f} s: {target_s / wall:.2f}x margin, "
                       f"{check(f'delta_min {args.delta_min:g}: <= {target_s:.0f} s', wall <= target_s)}")
    if target_gb:
        verdict.append(f"target <= {target_gb} GB: "
                       f"{check(f'delta_min {args.delta_min:g}: <= {target_gb} GB', peak_gb <= target_gb)}")
    print(f"{args.scenario} {args.sv_policy} SPE campaign, delta 2 -> {args.delta_min:g}, certify "
          f"{not args.no_certify}, refine {args.refine}, executor {args.executor}: "
          f"{wall:.1f} s wall including result files and plots, peak memory {peak_gb:.2f} GB = "
          f"{peak_bytes / 2**30:.2f} GiB "
          f"({'; '.join(verdict) or 'no target'}); {s.runs_committed:,} committed runs, {s.boxes:,} boxes, "
          f"volume {s.volume_union:.0f}, result {s.result_hash}")
    finish()


def whole_command(cfg, args) -> None:
    """``python -m farm quantify`` on ``cfg`` in a process of its own: its wall time from
    start to exit and its peak resident memory (the largest child waited for)."""
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "campaign.toml"
        config.write_text(config_mod.to_toml(cfg))
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "farm", "quantify", str(config), "--out", str(Path(tmp) / "c"),
                               "--quiet"], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            sys.exit(f"the campaign failed (exit {done.returncode}): {done.stderr.strip()}")
        summary = json.loads((Path(tmp) / "c" / "summary.json").read_text())
    peak_gb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024 / 1e9
    verdict = ""
    if args.scenario == "lead-follow" and args.delta_min == 0.125 and args.refine == "band" and not args.no_certify:
        target_s, target_gb = WHOLE_TARGET
        verdict = (f" (target <= {target_s:.0f} s: {check(f'whole command <= {target_s:.0f} s', wall <= target_s)}; "
                   f"<= {target_gb} GB: {check(f'whole command <= {target_gb} GB', peak_gb <= target_gb)})")
    print(f"{args.scenario} {args.sv_policy} SPE campaign, delta 2 -> {args.delta_min:g}, refine {args.refine}, executor "
          f"{args.executor}, `python -m farm quantify` start to exit: {wall:.1f} s, peak memory {peak_gb:.2f} GB"
          f"{verdict}; {summary['runs_committed']:,} committed runs, {summary['boxes']:,} boxes, result "
          f"{summary['result_hash']}")
    finish()


if __name__ == "__main__":
    main()
