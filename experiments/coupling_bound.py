"""How few replacements any exact sampler could make: a lower bound on the discarded runs
of the windows in experiments/window.py, against what coupled counting discards.

Under coupled counting a run drawn from the law at its launch is committed only if its
stream draws the same start from the law at its commit. For ANY exact sampler (each draw
distributed exactly by the law of its time) the two draws differ with probability at
least TV(law at launch, law at commit), so the sum of that distance over the committed
indices bounds the expected discarded runs from below. The law of every state version is
recorded as the campaign runs (coordinator/stable_sampler.py ``probabilities``); an
index's launch is its last batch drawn (a dropped batch's indices are drawn again), its
commit the last exactness check at the head. The recording changes no result (same
hashes as docs/window.json).

lead-follow idm, uniform Gamma, delta 2 -> 1, certified, sequential counting, seeds 0-3,
2,048 / 8,192 / 32,768 runs in flight (issue 32's target: committed + replaced <= 1.3x the
sequential count at each).

    python experiments/coupling_bound.py            # runs it (~4 min): docs/coupling_bound.json, .md
    python experiments/coupling_bound.py --render   # docs/coupling_bound.md from the JSON only
"""

from __future__ import annotations

import contextlib
import json
from collections import Counter
from pathlib import Path

import numpy as np

import coordinator.driver.campaign as campaign_mod
import coordinator.driver.pipeline as pipeline_mod
import coordinator.spe as spe_mod
from coordinator.stable_sampler import probabilities, total_variation
from experiment import machine_stamp, main, run_in_process, write_doc
from window import config

DOCS = Path(__file__).resolve().parents[1] / "docs"
WINDOWS = [(1024, 2), (2048, 4), (8192, 4)]  # 2,048 / 8,192 / 32,768 in flight
SEEDS = [0, 1, 2, 3]
TARGET = 1.3


@contextlib.contextmanager
def recording():
    """Record each state version's law, each batch's launch version and each index's
    commit version while a campaign runs (wrapping three methods; restored after)."""
    laws: dict[int, np.ndarray] = {}
    batches: list[tuple[int, int, int]] = []  # (first index, size, version drawn at)
    commits: dict[int, int] = {}
    law, init, verify = spe_mod.SPE._law, pipeline_mod.Pending.__init__, campaign_mod.verify

    def recorded_law(self):
        out = law(self)
        if self.version not in laws:
            laws[self.version] = probabilities(out).astype(np.float32)
        return out

    def recorded_init(self, first_index, draws, *args, **kwargs):
        init(self, first_index, draws, *args, **kwargs)
        if not draws.fixed and len(draws):
            batches.append((first_index, len(draws), int(draws.versions[0])))

    def recorded_verify(launcher, p, lo, hi):
        v = launcher.algorithm.version
        for i in range(p.first_index + lo, p.first_index + hi):
            commits[i] = v  # the last check before the commit is the one at its version
        return verify(launcher, p, lo, hi)

    spe_mod.SPE._law, pipeline_mod.Pending.__init__, campaign_mod.verify = (
        recorded_law, recorded_init, recorded_verify)
    try:
        yield laws, batches, commits
    finally:
        spe_mod.SPE._law, pipeline_mod.Pending.__init__, campaign_mod.verify = law, init, verify


def bound(laws: dict, batches: list, commits: dict) -> float:
    """Sum over committed indices of TV(law at launch, law at commit)."""
    launch: dict[int, int] = {}
    for first, size, version in batches:
        for i in range(first, first + size):
            launch[i] = version
    pairs = Counter((launch[i], v) for i, v in commits.items() if i in launch)
    return float(sum(n * total_variation(laws[a], laws[b]) for (a, b), n in pairs.items()))


def run(batch: int, depth: int, seed: int) -> dict:
    with recording() as (laws, batches, commits):
        c, algo, _, seconds = run_in_process(config(batch, depth, "sequential", True, seed))
    lower = bound(laws, batches, commits)
    return {"seed": seed, "batch_size": batch, "pipeline_depth": depth, "in_flight": batch * depth,
            "committed": c.committed, "replaced": c.runs_replaced, "discarded": c.runs_discarded,
            "bound": round(lower, 1), "cost": round((c.committed + c.runs_replaced) / c.committed, 4),
            "bound_cost": round((c.committed + lower) / c.committed, 4), "result_hash": algo.result().result_hash,
            "seconds_in_process": round(seconds, 1)}


def study() -> list[dict]:
    rows = []
    for seed in SEEDS:
        for batch, depth in WINDOWS:
            rows.append(run(batch, depth, seed))
            print(json.dumps(rows[-1]), flush=True)
    return rows


def write(rows: list[dict]) -> None:
    (DOCS / "coupling_bound.json").write_text(json.dumps({"meta": machine_stamp(), "rows": rows}, indent=1) + "\n")
    print(render())


def render() -> Path:
    """docs/coupling_bound.md from docs/coupling_bound.json."""
    data = json.loads((DOCS / "coupling_bound.json").read_text())
    rows, meta = data["rows"], data["meta"]
    out = [
        "# How few replacements any exact sampler could make",
        "",
        "<!-- rendered by `python experiments/coupling_bound.py --render` from docs/coupling_bound.json: edit the "
        "script, not this file -->",
        "",
        f"`python experiments/coupling_bound.py` ({meta['date']}, {meta['machine']}, Python {meta['python']}, "
        f"numpy {meta['numpy']}): the campaign of docs/window.md (lead-follow idm, uniform Gamma, delta 2 -> 1,",
        "certified), sequential counting. `replaced`: what coupled counting discarded and ran again. `bound`: the",
        "sum over committed indices of TV(law at the run's launch, law at its commit), below which no exact",
        "sampler's expected discards can go (a draw from one law and a draw from the other differ with",
        "probability at least their TV distance, however they are coupled). `cost` and `bound cost`:",
        "(committed + replaced) and (committed + bound) over committed.",
        "",
        "| seed | in flight | committed | replaced | bound | replaced / bound | cost | bound cost | result hash |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        out.append(f"| {r['seed']} | {r['in_flight']:,} | {r['committed']:,} | {r['replaced']:,} | "
                   f"{r['bound']:,.0f} | {r['replaced'] / max(r['bound'], 1):.2f} | {r['cost']:.2f} | "
                   f"{r['bound_cost']:.2f} | `{r['result_hash']}` |")
    out += ["", "## Reading it", ""]
    for batch, depth in WINDOWS:
        sel = [r for r in rows if (r["batch_size"], r["pipeline_depth"]) == (batch, depth)]
        costs, bounds = [r["cost"] for r in sel], [r["bound_cost"] for r in sel]
        ratio = [r["replaced"] / max(r["bound"], 1) for r in sel]
        verdict = ("no exact sampler can meet it (in expectation, at this window)" if min(bounds) > TARGET else
                   "met" if max(costs) <= TARGET else "not met, though the bound allows it")
        out.append(f"- {batch * depth:,} in flight: cost {min(costs):.2f}-{max(costs):.2f}x, bound "
                   f"{min(bounds):.2f}-{max(bounds):.2f}x (seeds {', '.join(map(str, SEEDS))}); coupled counting "
                   f"discards {min(ratio):.2f}-{max(ratio):.2f}x the bound. Target <= {TARGET}x: {verdict}.")
    out += ["- Why the bound grows with the window: a run is drawn a window before its commit, and every change",
            "  in between moves the law; with 32,768 in flight most of a round is drawn at once, so a run",
            "  launched early in a round is committed after most of the round's changes (the closing rounds",
            "  of certification change their edge every ~130 runs).",
            "- The bound counts one draw per index, its last launch in a batch; the discards also count",
            "  replacements moved again before their commit. For a single change the stream-keyed sampler moves",
            "  the TV share and no more (tests/coordinator/test_stable_sampler.py), once its slot space is the",
            "  law's: until 2026-11-29 the closing rounds drew over every vertex id, of which their edge is a",
            "  small share, and most draws fell back to the direct draw that every change moves (then 1.45-1.47x",
            "  the bound at 2,048 in flight, 1.34-1.39x at 8,192, 1.16-1.18x at 32,768; docs/benchmarks.md).",
            "  What is left to gain is fewer runs in flight per change (the batch that follows the workers",
            "  already stops at a round's quiet-run need, README)."]
    return write_doc(DOCS / "coupling_bound.md", out)


if __name__ == "__main__":
    main(lambda args: write(study()), render)
