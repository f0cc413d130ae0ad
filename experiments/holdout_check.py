"""Do the holdout's intervals and the validation of sets with a half-width per axis hold?
(issue 52: the statistical claims of margin refinement, re-measured.)

For each case, one margin-refined campaign (Gamma*, deterministic, the default refinement):
  - the holdout (summary.json ``holdout``) says P(a run from a uniform start in the set
    fails within K steps) lies in an exact 95 % interval. Its true value is measured on
    ``--truth`` fresh uniform starts; the holdout is then redrawn with ``--repeats`` other
    seeds (``quantify.holdout_runs`` = 1,000 starts each, as in a campaign), and the
    share of intervals that contain the true value should be at least 95 %;
  - a fresh ``validate`` of the exported set (delta, then eps-delta with its own seed)
    certifies it: the boxes' per-axis half-widths plus the covering margin are its delta.

    python experiments/holdout_check.py            # docs/holdout_check.json and its block in docs/guarantee.md
    python experiments/holdout_check.py --render   # the block from the JSON only
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from coordinator.binomial import clopper_pearson
from coordinator.holdout import holdout_report, holdout_starts
from farm import api
from scenarios.base import FAILURE
from scenarios.simulator import SimSpec, Simulator
from scenarios.streams import PURPOSE_START, RunStreams

ROOT = Path(__file__).resolve().parents[1]
JSON = ROOT / "docs" / "holdout_check.json"
DOC = ROOT / "docs" / "guarantee.md"
BEGIN, END = "<!-- holdout-check:begin", "<!-- holdout-check:end -->"
ACTIONS = {"mode": "adversarial"}
CASES = {"lead-follow idm": ({"name": "lead-follow", "sv_policy": "idm"}, 0.25),
         "fleet3 idm": ({"name": "fleet3", "sv_policy": "idm"}, 0.5),
         "platoon k=4 idm": ({"name": "platoon", "sv_policy": "idm", "vehicles": 4}, 1.0)}
QUANTIFY = {"delta0": 2.0, "epsilon": 0.001, "beta": 0.1, "horizon": 50, "sides": False}
TRUTH_SEED = 10**9  # apart from every campaign, holdout and validation seed
HOLDOUT_RUNS = 1000


def outcomes(sim: Simulator, starts: np.ndarray, indices: np.ndarray, batch: int = 50_000) -> np.ndarray:
    parts = [sim.simulate(0, starts[lo: lo + batch], indices=indices[lo: lo + batch]).outcomes
             for lo in range(0, len(starts), batch)]
    return np.concatenate(parts)


def one_case(label: str, scenario: dict, delta_min: float, truth_runs: int, repeats: int, workdir: Path) -> dict:
    t = time.time()
    out = workdir / label.replace(" ", "_").replace("=", "")
    result = api.quantify({"scenario": scenario, "actions": ACTIONS,
                           "quantify": {**QUANTIFY, "delta_min": delta_min},
                           "farm": {"executor": "local", "seed": 0}}, out=out)
    safe_set = result.safe_set
    sim = Simulator(SimSpec(scenario, ACTIONS, QUANTIFY["horizon"], TRUTH_SEED))
    scenario_obj = sim.scenario
    idx = np.arange(truth_runs, dtype=np.uint64)
    u = RunStreams.of(TRUTH_SEED, idx).uniform(0, PURPOSE_START, scenario_obj.n)
    starts = scenario_obj.lower + u * (scenario_obj.upper - scenario_obj.lower)
    inside = safe_set.contains(starts)
    failed = outcomes(sim, starts, idx.astype(np.int64)) == FAILURE
    claimed, over = int(inside.sum()), int((inside & failed).sum())
    true_share = over / claimed
    covered, shares = 0, []
    for seed in range(1, repeats + 1):
        sim_r = Simulator(SimSpec(scenario, ACTIONS, QUANTIFY["horizon"], seed))
        indices, hs = holdout_starts(scenario_obj, seed, HOLDOUT_RUNS)
        report = holdout_report(safe_set.contains(hs), outcomes(sim_r, hs, indices.astype(np.int64)), True)
        low, high = report["overclaim_interval"]
        covered += low <= true_share <= high
        shares.append(report["overclaim_share"])
    parquet = str(out / "safe_set.parquet")
    validations = {}
    for algorithm in ("delta", "eps-delta"):
        cert = api.validate({"scenario": scenario, "actions": ACTIONS,
                             "validate": {"algorithm": algorithm, "epsilon": 0.001, "beta": 0.1, "delta": delta_min,
                                          "horizon": QUANTIFY["horizon"], "domain_set": parquet},
                             "farm": {"executor": "local", "seed": 10_000}})
        validations[algorithm] = {"certified": bool(cert.certified), "runs": int(cert.n_run)}
    row = {"case": label, "delta_min": delta_min, "boxes": len(safe_set), "anisotropic": bool(safe_set.anisotropic),
           "runs": result.summary.runs_committed, "truth_runs": truth_runs, "truth_in_set": claimed,
           "truth_overclaims": over, "true_overclaim_share": true_share,
           "true_overclaim_interval": list(clopper_pearson(over, claimed)),
           "repeats": repeats, "holdout_runs": HOLDOUT_RUNS, "intervals_covering": covered,
           "holdout_share_mean": float(np.mean(shares)), "validate": validations,
           "seconds": round(time.time() - t, 1)}
    print(json.dumps(row), flush=True)
    return row


def render(data: dict) -> str:
    lines = [
        f"{BEGIN} (generated by experiments/holdout_check.py --render) -->",
        f"`python experiments/holdout_check.py` ({data['date']}): one margin-refined campaign per row (Gamma*, "
        f"delta0 2, eps 0.001, beta 0.1, K = {QUANTIFY['horizon']}); the true share of starts in the set whose "
        f"run fails within K steps, from {data['rows'][0]['truth_runs']:,} fresh uniform starts; the holdout "
        f"redrawn with {data['rows'][0]['repeats']} seeds of {HOLDOUT_RUNS:,} starts each, and how many of its "
        f"95 % intervals contain the true share; a fresh `validate` of the exported set.",
        "",
        "| case | delta_min | boxes | per-axis widths | true overclaim share | holdout mean | intervals covering "
        "| validate delta | validate eps-delta |",
        "| --- | ---: | ---: | :---: | ---: | ---: | ---: | :---: | :---: |",
    ]
    for r in data["rows"]:
        v = r["validate"]
        lines.append(f"| {r['case']} | {r['delta_min']:g} | {r['boxes']:,} | {'yes' if r['anisotropic'] else 'no'} | "
                     f"{r['true_overclaim_share']:.4%} ({r['truth_overclaims']} of {r['truth_in_set']:,}) | "
                     f"{r['holdout_share_mean']:.4%} | {r['intervals_covering']} of {r['repeats']} | "
                     f"{'certified' if v['delta']['certified'] else 'counterexample'} | "
                     f"{'certified' if v['eps-delta']['certified'] else 'counterexample'} "
                     f"({v['eps-delta']['runs']:,} runs) |")
    lines.append(END)
    return "\n".join(lines)


def write_doc(data: dict) -> None:
    text = DOC.read_text()
    block = render(data)
    if BEGIN in text:
        text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END):]
    else:
        text = text.rstrip() + "\n\n### The holdout's intervals, re-measured\n\n" + block + "\n"
    DOC.write_text(text)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", type=int, default=400_000)
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--render", action="store_true", help="only rewrite the block of docs/guarantee.md from the JSON")
    args = ap.parse_args()
    if not args.render:
        with tempfile.TemporaryDirectory() as d:
            rows = [one_case(label, sc, dmin, args.truth, args.repeats, Path(d)) for label, (sc, dmin) in CASES.items()]
        JSON.write_text(json.dumps({"date": time.strftime("%Y-%m-%d"), "rows": rows}, indent=1) + "\n")
    write_doc(json.loads(JSON.read_text()))
    print(render(json.loads(JSON.read_text())))
