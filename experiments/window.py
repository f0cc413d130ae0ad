"""What runs in flight cost under coupled counting: committed + replaced runs of one
campaign against farm.batch_size x farm.pipeline_depth (the runs in flight, which decide
how many workers a farm can keep busy), for both counting modes, in-process (the
committed sequence does not depend on the executor or the worker count, so this needs no
Ray and has no timing noise).

lead-follow idm, uniform Gamma, eps = 0.001, beta = 0.1, K = 50, delta 2 -> 1 (the scaling
campaign), certified, seeds 0-3 (and seed 0 without certification). Per seed: the
sequential count (`farm.counting = "sequential"`: the one-run-at-a-time campaign's, at any
window; checked at 16 x 1, 1024 x 2 and 8192 x 4), and `"deferred"` at 2,048, 8,192 and
32,768 runs in flight (its replacements applied that many indices later: its result
depends on the window). Accuracy: IoU / precision / recall against the model-based
reference on the compare grid.

    python experiments/window.py            # runs it (~7 min): docs/window.json, docs/window.md
    python experiments/window.py --render   # docs/window.md from the JSON only
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from coordinator.reference import compare_boxes, grid, reference_safe
from coordinator.sample_size import n_eps
from farm import config as config_mod

from experiment import machine_stamp, main, run_in_process, write_doc

DOCS = Path(__file__).resolve().parents[1] / "docs"
DEFERRED = [(1024, 2), (2048, 4), (8192, 4)]  # 2,048 / 8,192 / 32,768 in flight
SEQUENTIAL_CHECK = [(16, 1), (1024, 2), (8192, 4)]  # one result for all of them
SEEDS = [0, 1, 2, 3]


def config(batch: int, depth: int, counting: str, certify: bool, seed: int):
    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": 1.0, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                     "certify": certify, "budget": 20_000_000},
        "farm": {"executor": "local", "seed": seed, "batch_size": batch, "pipeline_depth": depth,
                 "counting": counting}})


def run(batch: int, depth: int, counting: str, certify: bool, seed: int, truth: dict) -> dict:
    cfg = config(batch, depth, counting, certify, seed)
    c, algo, backend, seconds = run_in_process(cfg)
    safe_set = algo.result()
    if "safe" not in truth:  # the reference depends on neither the window nor the seed
        truth["safe"] = reference_safe(backend, grid(backend.scenario))
    metrics = compare_boxes(backend, safe_set, truth=truth["safe"])
    return {"seed": seed, "certify": certify, "counting": counting, "batch_size": batch, "pipeline_depth": depth,
            "in_flight": batch * depth, "committed": c.committed, "replaced": c.runs_replaced,
            "discarded": c.runs_discarded, "changes": c.changes, "attempts": c.attempts,
            "result_hash": safe_set.result_hash, "boxes": len(safe_set), "iou": metrics["iou"],
            "precision": metrics["precision"], "recall": metrics["recall"], "seconds_in_process": round(seconds, 1)}


def study() -> list[dict]:
    rows, truth = [], {}
    cases = [(seed, True) for seed in SEEDS] + [(0, False)]
    for seed, certify in cases:
        windows = SEQUENTIAL_CHECK if seed == 0 else [(1024, 2)]
        for batch, depth in windows:
            rows.append(run(batch, depth, "sequential", certify, seed, truth))
        for batch, depth in DEFERRED:
            rows.append(run(batch, depth, "deferred", certify, seed, truth))
        for r in rows[-len(windows) - len(DEFERRED):]:
            print(json.dumps({k: r[k] for k in ("seed", "certify", "counting", "in_flight", "committed", "replaced",
                                                "attempts", "iou", "result_hash")}), flush=True)
    return rows


def write(rows: list[dict]) -> None:
    (DOCS / "window.json").write_text(json.dumps({"meta": machine_stamp(), "rows": rows}, indent=1) + "\n")
    print(render())


def _sequential(rows, seed, certify) -> dict:
    return next(r for r in rows if r["seed"] == seed and r["certify"] == certify and r["counting"] == "sequential")


def cost(row: dict, rows: list[dict]) -> float:
    """Committed + replaced runs against the same seed's sequential count."""
    return (row["committed"] + row["replaced"]) / _sequential(rows, row["seed"], row["certify"])["committed"]


def render() -> Path:
    """docs/window.md from docs/window.json: the tables and the sentences quoting them."""
    data = json.loads((DOCS / "window.json").read_text())
    rows, meta = data["rows"], data["meta"]
    seq0 = [r for r in rows if r["seed"] == 0 and r["certify"] and r["counting"] == "sequential"]
    out = [
        "# What runs in flight cost",
        "",
        "<!-- rendered by `python experiments/window.py --render` from docs/window.json: edit the script, "
        "not this file -->",
        "",
        f"`python experiments/window.py` ({meta['date']}, {meta['machine']}, Python {meta['python']}, numpy "
        f"{meta['numpy']}): lead-follow idm, uniform Gamma, eps = 0.001, beta = 0.1 (N_eps = {n_eps(0.001, 0.1):,}),",
        "K = 50, delta 2 -> 1, in-process (the committed sequence does not depend on the executor or the worker",
        "count). Coupled counting (shared/spec/algorithms.md point 3): a run whose start is still its stream's",
        "draw when it is committed is used as the one-run-at-a-time campaign would use it; a mispredicted one is",
        "discarded unseen and replaced. `sequential` waits for a replacement at the head; `deferred` applies it",
        "`in flight` indices later. `cost` is committed + replaced runs against the same seed's sequential count.",
        "",
        "## Sequential counting: one result at any window",
        "",
        "| batch x depth | in flight | committed | replaced | result hash |",
        "| --- | ---: | ---: | ---: | --- |",
    ]
    for r in seq0:
        out.append(f"| {r['batch_size']} x {r['pipeline_depth']} | {r['in_flight']:,} | {r['committed']:,} | "
                   f"{r['replaced']:,} | `{r['result_hash']}` |")
    out += ["", "## Deferred counting against sequential, seed by seed", "",
            "| seed | certify | counting | in flight | committed | replaced | cost | attempts | IoU | precision | "
            "recall |",
            "| ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        if r["counting"] == "sequential" and (r["batch_size"], r["pipeline_depth"]) != (1024, 2):
            continue
        out.append(f"| {r['seed']} | {'yes' if r['certify'] else 'no'} | {r['counting']} | {r['in_flight']:,} | "
                   f"{r['committed']:,} | {r['replaced']:,} | {cost(r, rows):.2f} | {r['attempts']} | "
                   f"{r['iou']:.4f} | {r['precision']:.4f} | {r['recall']:.4f} |")
    certified = [r for r in rows if r["certify"]]
    same = len({r["result_hash"] for r in seq0}) == 1
    out += ["", "## Reading it", ""]
    seq_cost = [cost(r, rows) for r in certified if r["counting"] == "sequential"]
    out.append(f"- Sequential counting gives {'one result hash' if same else 'DIFFERENT result hashes'} for "
               + ", ".join(f"{r['batch_size']} x {r['pipeline_depth']}" for r in seq0)
               + f"; its replacements cost {min(seq_cost) - 1:.1%}-{max(seq_cost) - 1:.1%} of the runs (seeds "
               + ", ".join(map(str, SEEDS)) + ").")
    for batch, depth in DEFERRED:
        costs = [cost(r, rows) for r in certified if r["counting"] == "deferred"
                 and (r["batch_size"], r["pipeline_depth"]) == (batch, depth)]
        out.append(f"- Deferred at {batch * depth:,} in flight: {np.median(costs):.2f}x the sequential runs "
                   f"(median; {min(costs):.2f}-{max(costs):.2f} over seeds).")
    out += ["- Why deferred grows with the window: a replacement that turns out to change the state is applied",
            "  `in flight` indices late, so the runs committed in between were decided at the old state and the",
            "  streak starts again after them: each such replacement voids up to a window of runs.",
            "- So the default is sequential: its count is the sequential campaign's whatever the window, the",
            "  window follows the workers (resume may change it), and a replacement launched when a change",
            "  moves an in-flight draw near the head is usually back before the head needs it",
            "  (benchmarks/bench_virtual.py measures the time to the result on many workers).",
            "- These rows are in process; deferred counting gives the same on Ray. A batch its head drew while it",
            "  stood past a replacement not yet back (a hold) is drawn again if that replacement changes the state",
            "  (the head goes back), when the head is where it drew it first: which runs a change mispredicts",
            "  then never depends on the workers' timing (docs/benchmarks.md, \"2026-11-29, last\")."]
    return write_doc(DOCS / "window.md", out)


if __name__ == "__main__":
    main(lambda args: write(study()), render)
