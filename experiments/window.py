"""What runs in flight cost: committed runs, changes and accuracy of one campaign against
farm.batch_size x farm.pipeline_depth (the runs in flight, which decide how many
workers a farm can keep busy), in-process (the committed sequence is the same on any
executor and worker count, so this needs no Ray and has no timing noise).

lead-follow idm, uniform Gamma, eps = 0.001, beta = 0.1, K = 50, seed 0, with and
without the certification round, delta 2 -> 1 (the scaling benchmark's campaign) and
2 -> 0.5. Per row: the runs committed per round, the changes of state, and how many of
those came from runs whose start centre was pruned while they were in flight (a run the
sequential algorithm would never have drawn, whose failure is still a change: the
parallel contract uses every failure), and IoU / precision / recall against the
model-based reference on the compare grid.

    python experiments/window.py            # runs it (~3 min): docs/window.json, docs/window.md
    python experiments/window.py --render   # docs/window.md from the JSON only
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from coordinator.sample_size import n_eps
from coordinator.reference import compare_boxes, grid, reference_safe
from farm import config as config_mod
from farm.local_executor import LocalExecutor
from farm.campaign_setup import build_algorithm, build_campaign, spec_of
from farm.ray_executor import busy_at_most

from experiment import machine_stamp, main

DOCS = Path(__file__).resolve().parents[1] / "docs"
DEFAULT = (1024, 2)  # farm.batch_size, farm.pipeline_depth (farm/config.py)
WINDOWS = [(1024, 2), (2048, 2), (2048, 4), (4096, 4), (8192, 4), (1024, 32)]
CASES = [  # delta_min, certify, windows
    (1.0, True, WINDOWS), (1.0, False, WINDOWS), (0.5, True, [(1024, 2), (2048, 4), (4096, 4)])]
# one seed's ratio can mislead (seed 0 at 2048 x 2: 1.01x): the certified 2 -> 1 case again
SEEDS, SEED_WINDOWS = [1, 2, 3], [(1024, 2), (2048, 2), (4096, 4)]


def config(batch: int, depth: int, delta_min: float, certify: bool, seed: int = 0):
    return config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 2.0, "delta_min": delta_min, "epsilon": 0.001, "beta": 0.1, "horizon": 50,
                     "certify": certify, "budget": 8_000_000},
        "farm": {"executor": "local", "seed": seed, "batch_size": batch, "pipeline_depth": depth}})


def run(batch: int, depth: int, delta_min: float, certify: bool, truth: dict, seed: int = 0) -> dict:
    """One campaign; ``truth``: the reference on the compare grid, filled by the first
    call (it depends on neither delta nor the window)."""
    cfg = config(batch, depth, delta_min, certify, seed)
    executor = LocalExecutor(spec_of(cfg))
    algo = build_algorithm(cfg, executor.simulator)
    kinds: dict[str, int] = {}
    apply = algo.apply

    def counting_apply(event):  # observes only: what the run did, and whether its start was alive
        stale = not algo.vertices.alive[event.start_id]
        kind = apply(event)
        key = f"{kind}{' (start pruned in flight)' if stale else ''}"
        kinds[key] = kinds.get(key, 0) + 1
        return kind

    algo.apply = counting_apply
    campaign = build_campaign(cfg, algo, executor.simulator, executor)
    t0 = time.perf_counter()
    c = campaign.run()
    seconds = time.perf_counter() - t0
    ends = c.round_ends
    rounds = [b - a for a, b in zip([0] + ends[:-1], ends)]
    safe_set = algo.result()
    backend = executor.simulator.backend
    if "safe" not in truth:
        truth["safe"] = reference_safe(backend, grid(backend.scenario))
    metrics = compare_boxes(backend, safe_set, truth=truth["safe"])
    stale = sum(v for k, v in kinds.items() if "in flight" in k)
    return {"seed": seed, "delta_min": delta_min, "certify": certify, "batch_size": batch, "pipeline_depth": depth,
            "in_flight": batch * depth, "busy_at_most_of_32": busy_at_most(32, depth, batch),
            "committed": c.committed, "rounds": rounds, "converged": c.converged, "changes": c.changes,
            "changes_start_pruned_in_flight": stale, "changes_by_kind": dict(sorted(kinds.items())),
            "boxes": len(safe_set), "iou": metrics["iou"], "precision": metrics["precision"],
            "recall": metrics["recall"], "seconds_in_process": round(seconds, 2)}


def study() -> list[dict]:
    rows, truth = [], {}
    for delta_min, certify, windows in CASES:
        for batch, depth in windows:
            row = run(batch, depth, delta_min, certify, truth)
            rows.append(row)
            print(json.dumps({k: row[k] for k in ("delta_min", "certify", "in_flight", "committed", "changes",
                                                  "changes_start_pruned_in_flight", "iou")}), flush=True)
    for seed in SEEDS:
        for batch, depth in SEED_WINDOWS:
            row = run(batch, depth, 1.0, True, truth, seed)
            rows.append(row)
            print(json.dumps({k: row[k] for k in ("seed", "in_flight", "committed", "iou")}), flush=True)
    return rows


def write(rows: list[dict]) -> None:
    (DOCS / "window.json").write_text(json.dumps({"meta": machine_stamp(), "rows": rows}, indent=1) + "\n")
    print(render())


def _case_rows(rows, delta_min, certify, seed=0):
    return [r for r in rows if r["delta_min"] == delta_min and r["certify"] == certify and r["seed"] == seed]


def render() -> Path:
    """docs/window.md from docs/window.json: the table and the sentences quoting it."""
    data = json.loads((DOCS / "window.json").read_text())
    every, meta = data["rows"], data["meta"]
    rows = [r for r in every if r["seed"] == 0]
    out = [
        "# What runs in flight cost",
        "",
        "<!-- rendered by `python experiments/window.py --render` from docs/window.json: edit the script, "
        "not this file -->",
        "",
        f"`python experiments/window.py` ({meta['date']}, {meta['machine']}, Python {meta['python']}, numpy "
        f"{meta['numpy']}): lead-follow idm, uniform Gamma, eps = 0.001, beta = 0.1 (N_eps = "
        f"{n_eps(0.001, 0.1):,}), K = 50, seed 0, in-process. The committed sequence depends only on the config",
        "and seed, so these counts are those of a Ray campaign on any number of workers. `in flight` is",
        "`farm.batch_size` x `farm.pipeline_depth`; `busy` is how many of 32 workers the Ray executor can keep",
        "busy with it (chunks of 256 runs at least); `stale` is how many of the changes came from a run whose",
        "start centre was pruned while it was in flight. Accuracy is against the model-based reference on",
        "the compare grid.",
        "",
        "| delta | certify | batch x depth | in flight | busy | committed runs | x defaults | runs per round "
        "| changes | stale | boxes | IoU | precision | recall |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        base = next(b for b in _case_rows(rows, r["delta_min"], r["certify"])
                    if (b["batch_size"], b["pipeline_depth"]) == DEFAULT)
        per_round = " / ".join(f"{n:,}" for n in r["rounds"]) + ("" if r["converged"] else " (budget)")
        out.append(
            f"| 2 -> {r['delta_min']:g} | {'yes' if r['certify'] else 'no'} | {r['batch_size']} x "
            f"{r['pipeline_depth']} | {r['in_flight']:,} | {r['busy_at_most_of_32']} | {r['committed']:,} | "
            f"{r['committed'] / base['committed']:.2f} | {per_round} | {r['changes']:,} | "
            f"{r['changes_start_pruned_in_flight']:,} | {r['boxes']:,} | {r['iou']:.4f} | {r['precision']:.4f} | "
            f"{r['recall']:.4f} |")
    seeds = sorted({r["seed"] for r in every})
    out += ["", f"The certified delta 2 -> 1 campaign again with seeds {', '.join(map(str, seeds))}: committed runs "
            "and their ratio to the defaults with the same seed.", "",
            "| batch x depth | in flight | " + " | ".join(f"seed {s}" for s in seeds) + " |",
            "| --- | ---: | " + " | ".join("---:" for _ in seeds) + " |"]
    for batch, depth in SEED_WINDOWS:
        cells = []
        for seed in seeds:
            same = {(r["batch_size"], r["pipeline_depth"]): r for r in _case_rows(every, 1.0, True, seed)}
            r, base = same[(batch, depth)], same[DEFAULT]
            cells.append(f"{r['committed']:,} ({r['committed'] / base['committed']:.2f}x)")
        out.append(f"| {batch} x {depth} | {batch * depth:,} | " + " | ".join(cells) + " |")
    cert = {(r["batch_size"], r["pipeline_depth"]): r for r in _case_rows(rows, 1.0, True)}
    plain = {(r["batch_size"], r["pipeline_depth"]): r for r in _case_rows(rows, 1.0, False)}
    d, big = cert[DEFAULT], cert[(8192, 4)]
    pd, pbig = plain[DEFAULT], plain[(8192, 4)]
    out += [
        "",
        "## Reading it",
        "",
        f"- Keeping 32 workers busy with 1,024-run chunks takes 32,768 runs in flight (8192 x 4). On the",
        f"  scaling benchmark's campaign (delta 2 -> 1, certified) that commits {big['committed']:,} runs against",
        f"  {d['committed']:,} at the defaults ({big['committed'] / d['committed']:.1f}x), without certification "
        f"{pbig['committed']:,} against {pd['committed']:,}",
        f"  ({pbig['committed'] / pd['committed']:.1f}x), for the same accuracy (IoU {big['iou']:.4f} against "
        f"{d['iou']:.4f}).",
        "- The cost is not confined to the early rounds. A round ends after N_eps quiet runs drawn after the",
        "  last change, so every round, the certification round included, pays at least the window once more,",
        "  and a change anywhere in that stretch voids the window again.",
        f"- It feeds itself. A wider window draws more runs from centres that are pruned before they are",
        f"  committed; their failures are changes too (a failure is a failure), and each voids the window",
        f"  again: {big['changes_start_pruned_in_flight']:,} of {big['changes']:,} changes at 8192 x 4 against "
        f"{d['changes_start_pruned_in_flight']:,} of {d['changes']:,} at the defaults.",
        "- Twice the defaults is not free either: seed 0's 1.01x at 2048 x 2 is the luck of one seed; the",
        "  other seeds pay " + ", ".join(
            f"{r['committed'] / next(b for b in _case_rows(every, 1.0, True, r['seed']) if (b['batch_size'], b['pipeline_depth']) == DEFAULT)['committed']:.2f}x"
            for r in every if r["seed"] != 0 and (r["batch_size"], r["pipeline_depth"]) == (2048, 2)) + ".",
        "- A larger campaign does not amortize it: at delta 2 -> 0.5 the certified campaign's ratio is "
        + ", ".join(f"{r['committed'] / _case_rows(rows, 0.5, True)[0]['committed']:.1f}x at {r['batch_size']} x "
                    f"{r['pipeline_depth']}" for r in _case_rows(rows, 0.5, True)[1:]) + ".",
        "",
        "So the defaults stay 1024 x 2 (8 busy workers at most). A cluster user who wants more workers busy",
        "raises both settings knowing this price (README, \"Many workers\"); the time to a result is what to",
        "compare, not committed runs per second (docs/benchmarks.md, stop 29).",
    ]
    path = DOCS / "window.md"
    path.write_text("\n".join(out) + "\n")
    return path


if __name__ == "__main__":
    main(lambda args: write(study()), render)
