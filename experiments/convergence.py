"""Convergence study on lead-follow / brake, whose safe set is known exactly (the
adversary rollout of coordinator.reference): IoU and volume error of the quantified set
against committed runs, for SPE with and without prioritized sampling and experience
replay, with Gamma* and with uniform Gamma, and for AE, delta-pruning and VS.

    python experiments/convergence.py            # runs it: docs/convergence.json, .png, .md
    python experiments/convergence.py --render   # docs/convergence.md from the JSON only

docs/convergence.md is rendered from docs/convergence.json (and the reachable() study's
docs/reachable.json, written by experiments/reachable.py): every number in it comes from
those files, so the document cannot drift from the experiment.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from coordinator.baselines import make_algorithm
from coordinator.driver import Campaign, CampaignSettings
from coordinator.spe import SPESettings
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios import make_scenario
from scenarios.backend import NumpyBackend

from experiment import machine_stamp, main

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

        def on_chunk(c, algo=algo, curve=curve, marks=marks):
            if len(curve) < len(marks) and c.counters.committed >= marks[len(curve)]:
                m = compare_boxes(NumpyBackend(scenario), algo.result(), grid_points_per_axis=grid)
                curve.append((c.counters.committed, m["iou"], m["claimed_volume"], m["reference_volume"]))

        t0 = time.perf_counter()
        # VS draws a new box after every failure: most runs change its state, so it is
        # given a smaller budget (it is incomplete anyway: Theorem 5)
        run_budget = min(budget, 60_000) if algorithm == "vs" else budget
        settings = CampaignSettings(epsilon=0.001, beta=0.1, budget=run_budget, batch_size=1024, pipeline_depth=2)
        counters = Campaign(algo, ex, settings, observers=[on_chunk]).run()
        wall = time.perf_counter() - t0
        safe_set = algo.result()
        m = compare_boxes(NumpyBackend(scenario), safe_set, grid_points_per_axis=grid)
        curve.append((counters.committed, m["iou"], m["claimed_volume"], m["reference_volume"]))
        curves[label] = curve
        rows.append({"variant": label, "runs": counters.committed, "converged": counters.converged,
                     "iou": m["iou"], "precision": m["precision"], "recall": m["recall"],
                     "volume_error": (m["claimed_volume"] - m["reference_volume"]) / m["reference_volume"],
                     "boxes": len(safe_set), "delta": safe_set.half_width, "seconds": wall})
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
    (DOCS / "convergence.json").write_text(json.dumps({"meta": _machine(), "rows": rows, "curves": curves}, indent=1))
    render()


def _machine() -> dict:
    import ray

    return machine_stamp(ray=ray.__version__,
                         settings="lead-follow / brake, delta 2 -> 0.5, eps = 0.001, beta = 0.1, K = 50, seed 0")


def _table(rows) -> list[str]:
    lines = ["| variant | runs | converged | IoU | precision | recall | volume error | boxes | s |",
             "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['variant']} | {r['runs']:,} | {r['converged']} | {r['iou']:.4f} | {r['precision']:.4f} | "
                     f"{r['recall']:.4f} | {r['volume_error']:+.4f} | {r['boxes']:,} | {r['seconds']:.1f} |")
    return lines


def _k(runs: float) -> str:
    return f"{runs / 1000:.0f}k"


def _cross_check(best: dict) -> list[str]:
    """The first row against the CLI campaign of docs/reproduction.md (same settings)."""
    try:
        cli = json.loads((DOCS / "reproduction_results.json").read_text())["lead_follow_brake delta=0.5"]
    except (OSError, ValueError, KeyError):
        return []
    same = cli["runs_committed"] == best["runs"] and cli["boxes"] == best["boxes"]
    return [f"The first row has the settings of the CLI campaign in `docs/reproduction.md` (lead-follow / "
            f"brake, delta 0.5): {cli['runs_committed']:,} runs and {cli['boxes']:,} boxes there, "
            + ("the same here." if same else f"{best['runs']:,} and {best['boxes']:,} here.")]


def render() -> Path:
    """docs/convergence.md (and docs/convergence_table.md) from docs/convergence.json and
    docs/reachable.json: numbers, table and the sentences that quote them."""
    data = json.loads((DOCS / "convergence.json").read_text())
    rows, meta = {r["variant"]: r for r in data["rows"]}, data.get("meta", {})
    table = _table(data["rows"])
    (DOCS / "convergence_table.md").write_text("\n".join(table) + "\n")
    spe = [r for k, r in rows.items() if k.startswith("SPE")]
    star = [r for k, r in rows.items() if k.startswith("SPE") and "Gamma*" in k]
    uni = [r for k, r in rows.items() if k.startswith("SPE") and "U(Gamma)" in k]
    best, plain = rows["SPE (prio + replay, Gamma*)"], rows["SPE (no prio, Gamma*)"]
    norep = rows["SPE (no replay, Gamma*)"]
    ae, dp, vs = rows["AE (Gamma*)"], rows["delta-pruning (Gamma*)"], rows["VS (Gamma*)"]
    rng = lambda rs, key: f"{min(r[key] for r in rs):.3f}-{max(r[key] for r in rs):.3f}"  # noqa: E731
    runs = lambda rs: f"{_k(min(r['runs'] for r in rs))}-{_k(max(r['runs'] for r in rs))}"  # noqa: E731
    err = lambda rs: max(abs(r["volume_error"]) for r in rs) * 100  # noqa: E731
    fewer = best["runs"] < plain["runs"]
    out = [
        "# Convergence of SPE and the paper's baselines",
        "",
        "<!-- rendered by `python experiments/convergence.py --render` from docs/convergence.json and "
        "docs/reachable.json: edit the script, not this file -->",
        "",
        f"`python experiments/convergence.py` ({meta.get('date', '?')}, {meta.get('machine', '?')}, Python "
        f"{meta.get('python', '?')}, numpy {meta.get('numpy', '?')}): lead-follow with",
        "the brake SV, whose safe set is known exactly (`coordinator/reference.py`); delta 2 ->",
        "0.5, eps = 0.001, beta = 0.1, K = 50, seed 0, in-process executor (no certification",
        "round: the campaign ends at the N_eps rule of the last round); IoU and volume error of",
        "the quantified set against committed runs (snapshots at geometric run counts, and at",
        "the end). The numbers are `docs/convergence.json`.",
        "",
        "![convergence](convergence.png)",
        "",
        *table,
        "",
        "Reading it:",
        "",
        "- **SPE** converges to the exact set up to the delta-boundary layer with every option",
        f"  (IoU {rng(spe, 'iou')}). With **Gamma\\*** it needs {runs(star)} runs against {runs(uni)} "
        f"for uniform Gamma,",
        f"  and ends within {err(star):.1f}% of the true volume (uniform: {err(uni):.1f}%): uniform lead",
        "  actions rarely produce the maximal braking that decides the boundary, the effect the",
        "  paper reports as \"five times the number of samples\".",
        f"- **Prioritized sampling** {'reduces' if fewer else 'does not reduce'} the number of runs on this "
        f"easy case ({best['runs']:,} with it,",
        f"  {plain['runs']:,} without; precision {best['precision']:.4f} vs {plain['precision']:.4f}): it "
        "concentrates the N_eps",
        "  window near PhiBar, where changes keep being found. Its value grows with the share of",
        "  interior volume; on this set most of Sigma is safe interior. **Experience replay**:",
        f"  {norep['runs']:,} runs without it against {best['runs']:,} with it (IoU {norep['iou']:.4f} vs "
        f"{best['iou']:.4f}).",
        f"- **AE** converges to one small invariant set around its first safe start ({ae['boxes']:,} boxes,",
        f"  IoU {ae['iou']:.4f}): it is complete but not optimal (Theorem 8); under Gamma* every run from a",
        "  safe start ends at a standstill, so exploration stops at once.",
        f"- **delta-pruning** does well on this monotone set (IoU {dp['iou']:.4f}) but loses true safe",
        f"  volume (recall {dp['recall']:.4f} vs {best['recall']:.4f} for SPE): the Theorem 6 effect, shown "
        "sharply on the",
        "  toy scenario (`tests/coordinator/test_quantify_toy.py`).",
        f"- **VS** {'never validates a useful box' if vs['iou'] < 0.5 else 'validates a box'} within "
        f"{vs['runs']:,} runs (IoU {vs['iou']:.4f}; random sub-boxes of Sigma",
        "  are rarely invariant): incomplete (Theorem 5).",
        "",
        *_cross_check(best),
    ]
    reach_path = DOCS / "reachable.json"
    if reach_path.exists():
        reach = json.loads(reach_path.read_text())
        reach_rows = reach["rows"] if isinstance(reach, dict) else reach
        out += ["", "## reachable(): undirected tree vs ancestors", "",
                "`python experiments/reachable.py` (`docs/reachable.json`"
                + (f", {reach['meta']['date']}" if isinstance(reach, dict) and "meta" in reach else "")
                + "): uniform Gamma (where exploration trees grow), delta",
                "2 -> 0.5, against the Gamma* reference.", "",
                "| SV | reachable | runs | boxes | IoU | precision | recall |",
                "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        out += [f"| {r['policy']} | {r['reachable']} | {r['runs']:,} | {r['boxes']:,} | {r['iou']:.4f} | "
                f"{r['precision']:.4f} | {r['recall']:.4f} |" for r in reach_rows]
        by = {(r["policy"], r["reachable"]): r for r in reach_rows}
        if ("idm", "undirected") in by and ("idm", "ancestors") in by:
            u, a = by["idm", "undirected"], by["idm", "ancestors"]
            change = 1 - a["runs"] / u["runs"]
            out += ["", f"Ancestors-only pruning needs {abs(change):.0%} {'fewer' if change > 0 else 'more'} runs "
                    f"on idm than the undirected tree ({a['runs']:,} vs {u['runs']:,}),",
                    f"at precision {a['precision']:.4f} vs {u['precision']:.4f}. The paper's undirected reading "
                    "stays the default;", "`quantify.reachable = \"ancestors\"` is available."]
    path = DOCS / "convergence.md"
    path.write_text("\n".join(out) + "\n")
    return path


if __name__ == "__main__":
    main(lambda args: write(*study(**({"budget": int(args[0])} if args else {}))), render)
