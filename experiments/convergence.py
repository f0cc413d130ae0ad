"""Convergence study on lead-follow / brake, whose safe set is known exactly (the
adversary rollout of coordinator.reference): IoU and volume error of the quantified set
against committed runs, for SPE with and without prioritized sampling and experience
replay, with Gamma* and with uniform Gamma, and for AE, delta-pruning and VS.

    python experiments/convergence.py            # writes docs/convergence.md and .png
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from coordinator.baselines import make_algorithm
from coordinator.campaign import Campaign
from coordinator.covering import n_eps
from coordinator.spe import SPESettings
from farm.executors import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios import make_scenario
from scenarios.backend import NumpyBackend

DOCS = Path(__file__).resolve().parents[1] / "docs"
VARIANTS = [
    # label, algorithm, actions, prioritized, replay
    ("SPE (prio + replay, Gamma*)", "spe", "adversarial", True, True),
    ("SPE (no prio, Gamma*)", "spe", "adversarial", False, True),
    ("SPE (no replay, Gamma*)", "spe", "adversarial", True, False),
    ("SPE (prio + replay, U(Gamma))", "spe", "uniform", True, True),
    ("SPE (plain, U(Gamma))", "spe", "uniform", False, False),
    ("AE (Gamma*)", "ae", "adversarial", False, False),
    ("delta-pruning (Gamma*)", "delta-pruning", "adversarial", False, False),
    ("VS (Gamma*)", "vs", "adversarial", False, False),
]


def study(delta_min: float = 0.5, budget: int = 1_500_000, snapshots: int = 12, grid: int = 60):
    from coordinator.reference import compare_boxes

    scenario = make_scenario("lead-follow", sv_policy="brake")
    rows = []
    curves = {}
    for label, algorithm, actions, prio, replay in VARIANTS:
        settings = SPESettings(delta0=2.0, gamma=0.5, delta_min=delta_min, prioritized=prio, replay=replay)
        algo = make_algorithm(algorithm, scenario, settings, 0)
        ex = LocalExecutor(SimSpec({"name": "lead-follow", "sv_policy": "brake"}, {"mode": actions}, 50, 0))
        marks = np.unique(np.geomspace(2_000, min(budget, 60_000) if algorithm == 'vs' else budget, snapshots).astype(int))
        curve = []

        def on_batch(c, algo=algo, curve=curve, marks=marks):
            if len(curve) < len(marks) and c.counters.committed >= marks[len(curve)]:
                centres, h = algo.result()
                m = compare_boxes(NumpyBackend(scenario), centres, h, grid_points_per_axis=grid)
                curve.append((c.counters.committed, m["iou"], m["claimed_volume"], m["reference_volume"]))

        t0 = time.perf_counter()
        # VS draws a new box after every failure: most runs change its state, so it is
        # given a smaller budget (it is incomplete anyway: Theorem 5)
        run_budget = min(budget, 60_000) if algorithm == "vs" else budget
        counters = Campaign(algo, ex, n_eps=n_eps(0.001, 0.1), budget=run_budget, batch_size=1024, pipeline_depth=2,
                            seed=0, on_batch=on_batch).run()
        wall = time.perf_counter() - t0
        centres, h = algo.result()
        m = compare_boxes(NumpyBackend(scenario), centres, h, grid_points_per_axis=grid)
        curve.append((counters.committed, m["iou"], m["claimed_volume"], m["reference_volume"]))
        curves[label] = curve
        rows.append({"variant": label, "runs": counters.committed, "converged": counters.converged,
                     "iou": m["iou"], "precision": m["precision"], "recall": m["recall"],
                     "volume_error": (m["claimed_volume"] - m["reference_volume"]) / m["reference_volume"],
                     "boxes": len(centres), "delta": h, "seconds": wall})
        print(json.dumps(rows[-1]), flush=True)
    return rows, curves


def write(rows, curves):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    DOCS.mkdir(exist_ok=True)
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.5))
    for label, curve in curves.items():
        runs, iou, claimed, ref = map(np.array, zip(*curve))
        a.plot(runs, iou, marker="o", ms=3, label=label)
        b.plot(runs, np.abs(claimed - ref) / ref, marker="o", ms=3, label=label)
    for ax, name in ((a, "IoU against the exact safe set"), (b, "|volume error| / true volume")):
        ax.set_xscale("log")
        ax.set_xlabel("committed runs")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.3)
    b.set_yscale("log")
    a.legend(fontsize=7)
    fig.suptitle("lead-follow / brake, delta 2 -> 0.5, eps = 0.001, beta = 0.1", fontsize=10)
    fig.tight_layout()
    fig.savefig(DOCS / "convergence.png", dpi=110)
    lines = ["| variant | runs | converged | IoU | precision | recall | volume error | boxes | s |",
             "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['variant']} | {r['runs']:,} | {r['converged']} | {r['iou']:.4f} | {r['precision']:.4f} | "
                     f"{r['recall']:.4f} | {r['volume_error']:+.4f} | {r['boxes']:,} | {r['seconds']:.1f} |")
    (DOCS / "convergence_table.md").write_text("\n".join(lines) + "\n")
    (DOCS / "convergence.json").write_text(json.dumps({"rows": rows, "curves": curves}, indent=1))


if __name__ == "__main__":
    rows, curves = study(**({"budget": int(sys.argv[1])} if len(sys.argv) > 1 else {}))
    write(rows, curves)
