"""A 7-D campaign as a user runs it: the platoon of four (shared/spec/scenarios.md,
section platoon; examples/platoon4_idm.toml) with uniform Gamma, delta 2 -> 1, eps
0.001, beta 0.1, certified, in-process on 2 workers (the "local" executor): ~250,000
boxes at delta 1 and ~1.2 M committed runs. It prints the whole `quantify` process's
wall time, CPU and peak memory, the round end's CPU (the children of 2,000 boxes
checked against the failures) and the closing edge's (``SPECertification._edge_mask``,
once per change of a closing round), and the result hash.

    python benchmarks/bench_high_dimension.py [--vehicles 4] [--delta-min 1] [--refine all|band] [--vs CHECKOUT]

``--refine band``: boundary refinement (mixed box sizes, the leveled index) instead of
"all", what ``refine = "auto"`` resolves to for this stochastic system.

``--vs CHECKOUT``: another checkout of this repository (``git worktree add /tmp/before
<commit>``), run the same way after this one: the before/after of a change, with the
same result hash expected. Needs ~4 GB (~9 GB before 2026-12-07's changes); run it with
nothing else on the machine.
"""

from __future__ import annotations

import argparse
import os
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
refine = "{refine}"
budget = {budget}
[farm]
executor = "local"
workers = 2
seed = 0
"""

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from profile_driver import profile  # noqa: E402

TIMED = "coordinator.spe:SPE.end_round,coordinator.spe_certification:SPECertification._edge_mask"


def measure(checkout: str, config: str, out: str) -> dict:
    """One `quantify` with thread-CPU timers on the round end and the closing edge."""
    return profile(config, out, TIMED, checkout=checkout, who="bench_high_dimension")


def line(label: str, m: dict) -> str:
    return (f"{label}: {m['committed']:,} committed runs, {m['boxes']:,} boxes, wall {m['wall_s']:.1f} s, process CPU "
            f"{m['cpu_s']:.1f} s (system {m['system_s']:.1f}), peak {m['max_rss_mb']:,.0f} MB; round end "
            f"{m['cpu'].get('SPE.end_round', 0.0):.2f} CPU-s; closing edge "
            f"{m['cpu'].get('SPECertification._edge_mask', 0.0):.2f} CPU-s over "
            f"{m['calls'].get('SPECertification._edge_mask', 0):,} calls; result {m['hash']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vehicles", type=int, default=4, help="platoon size: 2 + 1 + followers; 4 is 7-D")
    ap.add_argument("--delta-min", type=float, default=1.0)
    ap.add_argument("--refine", choices=("all", "band"), default="all", help="quantify.refine")
    ap.add_argument("--vs", help="another checkout, run the same way after this one")
    args = ap.parse_args()
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory() as tmp:
        config = os.path.join(tmp, "case.toml")
        with open(config, "w") as f:
            f.write(CONFIG.format(vehicles=args.vehicles, delta_min=args.delta_min, refine=args.refine, budget=4000000))
        print(f"machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; platoon of {args.vehicles} "
              f"({2 * args.vehicles - 1}-D), uniform Gamma, delta 2 -> {args.delta_min:g}, refine {args.refine}, "
              f"certified, in-process on "
              f"2 workers; whole `scenario-farm quantify` processes")
        this = measure(here, config, os.path.join(tmp, "this"))
        print(line("this checkout", this), flush=True)
        if args.vs:
            other = measure(os.path.abspath(args.vs), config, os.path.join(tmp, "other"))
            print(line(args.vs, other))
            same = "the same result" if other["hash"] == this["hash"] else "DIFFERENT results"
            print(f"{args.vs} / this checkout: wall {other['wall_s'] / this['wall_s']:.2f}x, process CPU "
                  f"{other['cpu_s'] / this['cpu_s']:.2f}x, peak memory {other['max_rss_mb'] / this['max_rss_mb']:.2f}x; "
                  f"{same}")


if __name__ == "__main__":
    main()
