"""The driver's cost as a user pays it: committed runs per CPU-second of the whole
`scenario-farm quantify` process (issue 54: >= 150,000; issue 11's bare-coordinator
figure was >= 300,000).

The case: lead-follow idm, uniform Gamma, delta 2 -> 0.5, eps 0.001, beta 0.1, K = 50,
certified, the numpy back end on 2 Ray workers, with everything a campaign does (ledger,
checkpoints, holdout, result files, plots). The CPU is the CLI process's own (every
thread of it; the Ray workers' and Ray's daemons' are not the driver's). Ray's start,
the imports and the fixed part of finishing are taken out by a tiny run of the same
config (delta_min = delta0: one round), so the figure is the marginal CPU per committed
run:

    rate = (runs(case) - runs(tiny)) / (cpu(case) - cpu(tiny))

    python benchmarks/bench_coordinator_cpu.py [--repeat 3] [--keep DIR] [--vs CHECKOUT]

``--vs CHECKOUT``: another checkout of this repository (``git worktree add /tmp/before
<commit>``), measured back to back with this code in every repeat (a pair, in alternating
order): on a host whose speed drifts by more than a change gains, compare within pairs (the
median of the pairs' ratios), not figures taken minutes apart. ``--vs`` naming this very
checkout measures the pairs' own spread (docs/benchmarks.md: 0.81-1.06 at --repeat 3).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from targets import check, finish  # noqa: E402

TARGET = 150_000

CASE = """[scenario]
name = "lead-follow"
sv_policy = "idm"
[actions]
mode = "uniform"
[quantify]
delta0 = 2.0
delta_min = {delta_min}
epsilon = 0.001
beta = 0.1
horizon = 50
[farm]
executor = "ray"
workers = 2
seed = 0
"""

# the CLI's own entry (farm/cli/commands.py main), then the process's CPU from getrusage
# (RUSAGE_SELF: every thread, no child) on stdout's last line
_MEASURED = """
import json, resource, sys, time
t0 = time.perf_counter()
from farm.cli.commands import main
code = main(sys.argv[1:])
r = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"code": code, "cpu_s": r.ru_utime + r.ru_stime, "wall_s": time.perf_counter() - t0,
                  "max_rss_mb": r.ru_maxrss / 1024}))
"""


def quantify_child(child: str, config: str, out: str, who: str, first_args=(), env=None, cwd=None) -> dict:
    """Run ``child`` (Python source that calls the CLI's entry on ``sys.argv[1 + len(first_args):]``
    and prints a JSON row with the exit "code" last) on ``quantify config --out out --force``:
    its row, with the campaign's committed runs, result hash and boxes; ``who`` names the tool in
    the one-line error a failed run ends with."""
    proc = subprocess.run([sys.executable, "-c", child, *first_args, "quantify", config, "--out", out, "--force"],
                          capture_output=True, text=True, env=env, cwd=cwd)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        sys.exit(f"{who}: quantify {config} exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    row = json.loads(lines[-1])
    if row["code"] != 0:
        sys.exit(f"{who}: quantify {config} returned {row['code']}: {proc.stderr.strip()[-400:]}")
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    row.update(committed=summary["runs_committed"], hash=summary["result_hash"], boxes=summary["boxes"])
    return row


def checkout_env(checkout: str | None) -> dict:
    """This process's environment, with ``checkout``'s packages first on the path if given."""
    env = dict(os.environ)
    if checkout is not None:
        env["PYTHONPATH"] = os.pathsep.join([checkout, *filter(None, [env.get("PYTHONPATH")])])
    return env


def measure(config: str, out: str, checkout: str | None = None) -> dict:
    """One `quantify` of ``config`` into ``out``: the process's CPU, wall, exit and runs
    (``checkout``: with that checkout's packages first on the path)."""
    return quantify_child(_MEASURED, config, out, "bench_coordinator_cpu", env=checkout_env(checkout), cwd=checkout)


def _rate(configs: dict, work: str, checkout: str | None, label: str) -> float:
    """The tiny run and the case, once: committed runs per marginal CPU-second (printed)."""
    tiny = measure(configs["tiny"], os.path.join(work, "tiny"), checkout)
    case = measure(configs["case"], os.path.join(work, "case"), checkout)
    rate = (case["committed"] - tiny["committed"]) / max(case["cpu_s"] - tiny["cpu_s"], 1e-9)
    print(f"{label}tiny: {tiny['committed']:,} runs, {tiny['cpu_s']:.2f} CPU-s, {tiny['wall_s']:.1f} s; case: "
          f"{case['committed']:,} runs, {case['cpu_s']:.2f} CPU-s, {case['wall_s']:.1f} s, "
          f"{case['max_rss_mb']:.0f} MB (result {case['hash']}): {rate:,.0f} committed runs per CPU-second "
          f"of the process", flush=True)
    return rate


def main() -> None:
    import ray

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="pairs of (tiny, case) runs; the median rate is the figure")
    ap.add_argument("--keep", help="write the configs and campaigns here (default: a temporary directory)")
    ap.add_argument("--vs", metavar="CHECKOUT", help="another checkout, measured back to back with this code")
    args = ap.parse_args()
    if args.vs is not None and not os.path.isfile(os.path.join(args.vs, "coordinator", "__init__.py")):
        sys.exit(f"bench_coordinator_cpu: --vs {args.vs}: not a checkout of this repository (no coordinator/)")
    work = args.keep or tempfile.mkdtemp(prefix="bench_cpu_")
    os.makedirs(work, exist_ok=True)
    configs = {}
    for name, delta_min in (("tiny", 2.0), ("case", 0.5)):
        configs[name] = os.path.join(work, f"{name}.toml")
        with open(configs[name], "w") as f:
            f.write(CASE.format(delta_min=delta_min))
    print(f"machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; Ray {ray.__version__}, local; "
          "lead-follow idm, uniform Gamma, delta 2 -> 0.5, certified, numpy back end, 2 Ray workers; "
          "whole `scenario-farm quantify` processes", flush=True)
    rates, ratios = [], []
    for repeat in range(args.repeat):
        if args.vs is None:
            rates.append(_rate(configs, work, None, ""))
            continue
        # the order alternates within pairs (A B, B A, ...): were running second dearer or
        # cheaper (another process's Ray still shutting down), a fixed order would tilt
        # every pair the same way
        if repeat % 2 == 0:
            other = _rate(configs, work, args.vs, f"vs {args.vs}: ")
            rate = _rate(configs, work, None, "this code: ")
        else:
            rate = _rate(configs, work, None, "this code: ")
            other = _rate(configs, work, args.vs, f"vs {args.vs}: ")
        rates.append(rate)
        ratios.append(rate / other)
        print(f"pair {len(ratios)}: this code / {args.vs} = {ratios[-1]:.2f}", flush=True)
    median = sorted(rates)[len(rates) // 2]
    if ratios:
        print(f"median of the pairs' ratios: {sorted(ratios)[len(ratios) // 2]:.2f} (this code ahead in "
              f"{sum(r > 1 for r in ratios)} of {len(ratios)})")
    verdict = check(f"committed runs per CPU-second of the whole CLI process >= {TARGET:,}", median >= TARGET)
    print(f"median: {median:,.0f} committed runs per CPU-second of the whole CLI process "
          f"(target {TARGET:,}: {verdict})")
    finish()


if __name__ == "__main__":
    main()
