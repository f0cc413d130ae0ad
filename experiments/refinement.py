"""Boundary refinement (issue 36): boxes and committed runs against accuracy for
``quantify.refine = "all"`` (every box split at every round end) and ``"band"`` (only the
boxes within sigma-bar + delta of the failure-side boundary, Theorem 3), in-process (the
committed sequence does not depend on the executor, so the counts have no timing noise;
the seconds do: the machine is shared).

Gamma* (deterministic: certification runs every final centre once, VAL^delta), eps = 0.001,
beta = 0.1, K = 50, delta0 = 2, certified, seed 0: lead-follow brake and idm at delta_min
1, 0.5, 0.25, 0.125; fleet3 brake and idm at delta_min 1, 0.5, 0.25 (one campaign over
both failure facets). Accuracy: IoU / precision / recall against the model-based
reference on the compare grid (coordinator/reference.py compare_boxes).

    python experiments/refinement.py [CASE ...]   # runs it: docs/refinement.json, docs/refinement.md
    python experiments/refinement.py --render     # docs/refinement.md from the JSON only

CASE: ``scenario/policy/delta_min/refine`` (e.g. ``lead-follow/idm/0.125/band``) runs only
those and merges them into the JSON.
"""

from __future__ import annotations

import json
import os
import resource
from pathlib import Path

from coordinator.reference import compare_boxes, grid, reference_safe
from farm import config as config_mod

from experiment import machine_stamp, main, run_in_process

DOCS = Path(__file__).resolve().parents[1] / "docs"
JSON = DOCS / "refinement.json"
DELTAS = {"lead-follow": [1.0, 0.5, 0.25, 0.125], "fleet3": [1.0, 0.5, 0.25]}
CASES = [(scenario, policy, d, refine) for scenario in ("lead-follow", "fleet3") for policy in ("brake", "idm")
         for d in DELTAS[scenario] for refine in ("all", "band")]


def config(scenario: str, policy: str, delta_min: float, refine: str):
    return config_mod.normalize({
        "scenario": {"name": scenario, "sv_policy": policy}, "actions": {"mode": "adversarial"},
        "quantify": {"delta0": 2.0, "delta_min": delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                     "budget": 40_000_000, "refine": refine},
        "farm": {"executor": "local", "seed": 0}})


def run(scenario: str, policy: str, delta_min: float, refine: str, truths: dict) -> dict:
    cfg = config(scenario, policy, delta_min, refine)
    c, algo, backend, seconds = run_in_process(cfg)
    safe_set = algo.result()
    key = (scenario, policy)
    if key not in truths:
        truths[key] = reference_safe(backend, grid(backend.scenario))
    m = compare_boxes(backend, safe_set, truth=truths[key])
    return {"scenario": scenario, "sv_policy": policy, "delta_min": delta_min, "refine": refine,
            "boxes": len(safe_set), "committed": c.committed, "converged": c.converged,
            "half_width_max": safe_set.coarsest, "volume": safe_set.volume_union(),
            "iou": m["iou"], "precision": m["precision"], "recall": m["recall"],
            "result_hash": safe_set.result_hash, "seconds_in_process": round(seconds, 1),
            "peak_gb_so_far": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9, 2),
            "load_average": round(os.getloadavg()[0], 1)}


def _key(row: dict) -> tuple:
    return row["scenario"], row["sv_policy"], row["delta_min"], row["refine"]


def study(args: list[str]) -> None:
    wanted = CASES
    if args:
        wanted = [(s, p, float(d), r) for s, p, d, r in (a.split("/") for a in args)]
    rows = json.loads(JSON.read_text())["rows"] if JSON.exists() else []
    truths: dict = {}
    for case in wanted:
        row = run(*case, truths)
        print(json.dumps(row), flush=True)
        rows = [r for r in rows if _key(r) != case] + [row]
        rows.sort(key=lambda r: (r["scenario"], r["sv_policy"], -r["delta_min"], r["refine"]))
        JSON.write_text(json.dumps({"meta": machine_stamp(), "rows": rows}, indent=1) + "\n")
    print(render())


def _verdict(rows: list[dict]) -> list[str]:
    """Where band falls short of all against the reference (the default stays "all" while
    it does anywhere)."""
    pairs = []
    for r in rows:
        full = next((a for a in rows if _key(a) == _key(r)[:3] + ("all",)), None)
        if r["refine"] == "band" and full is not None:
            pairs.append((r, full))
    out = []
    for measure in ("iou", "precision"):
        below = [(r, r[measure] - full[measure]) for r, full in pairs if r[measure] < full[measure]]
        worst = min(below, key=lambda x: x[1]) if below else None
        out.append(f"- {measure}: band below all in {len(below)} of {len(pairs)} pairs"
                   + (f" (the largest gap {worst[1]:+.5f}: {worst[0]['scenario']} {worst[0]['sv_policy']} at "
                      f"delta_min {worst[0]['delta_min']:g})" if worst else "") + ".")
    return out


def _load(rows: list[dict]) -> str:
    """The machine's load while the rows ran (rows from before it was recorded: 12-16)."""
    loads = [r["load_average"] for r in rows if "load_average" in r]
    if not loads:
        return "load average 12-16 during these runs"
    older = " (12-16 for the rows without one)" if len(loads) < len(rows) else ""
    return f"1-minute load average {min(loads):g}-{max(loads):g} at the end of the rows{older}"


def render() -> Path:
    """docs/refinement.md from docs/refinement.json."""
    data = json.loads(JSON.read_text())
    rows, meta = data["rows"], data["meta"]
    out = [
        "# Boundary refinement: runs and boxes against accuracy",
        "",
        "<!-- rendered by `python experiments/refinement.py --render` from docs/refinement.json: edit the script, "
        "not this file -->",
        "",
        f"`python experiments/refinement.py` ({meta['date']}, {meta['machine']}, Python {meta['python']}, numpy "
        f"{meta['numpy']}): Gamma*, eps = 0.001, beta = 0.1, K = 50, delta0 = 2, certified (every final centre",
        "run once), seed 0, in-process. `refine = all` splits every box at every round end; `band` only the boxes",
        "within sigma-bar + delta (per axis) of the set's failure-side boundary (Theorem 3), the others keep their",
        "size (`max half-width`). Accuracy against the model-based reference on the compare grid. Seconds are",
        f"wall time on a shared 2-core machine ({_load(rows)}: noisy); the counts are exact.",
        "",
        "| scenario | SV | delta_min | refine | boxes | committed runs | max half-width | IoU | precision | "
        "recall | s |",
        "| --- | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        out.append(f"| {r['scenario']} | {r['sv_policy']} | {r['delta_min']:g} | {r['refine']} | {r['boxes']:,} | "
                   f"{r['committed']:,} | {r['half_width_max']:g} | {r['iou']:.4f} | {r['precision']:.4f} | "
                   f"{r['recall']:.4f} | {r['seconds_in_process']:g} |")
    out += ["", "## Reading it", ""]
    for r in rows:
        if r["refine"] != "band":
            continue
        full = next((a for a in rows if _key(a) == _key(r)[:3] + ("all",)), None)
        if full is None:
            continue
        out.append(f"- {r['scenario']} {r['sv_policy']} at delta_min {r['delta_min']:g}: band keeps "
                   f"{r['boxes'] / full['boxes']:.2f}x the boxes and commits {r['committed'] / full['committed']:.2f}x "
                   f"the runs of all; IoU {r['iou'] - full['iou']:+.5f}, precision "
                   f"{r['precision'] - full['precision']:+.5f}, recall {r['recall'] - full['recall']:+.5f}.")
    out += ["", "## Is band as accurate as all?", "", *_verdict(rows)]
    path = DOCS / "refinement.md"
    path.write_text("\n".join(out) + "\n")
    return path


if __name__ == "__main__":
    main(study, render)
