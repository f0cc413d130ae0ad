"""Domains of 3 to 9 dimensions (issue 52): committed runs, boxes, peak memory, seconds
and accuracy of the margin refinement (``refine = "margin"``, the default for a
deterministic system) against the earlier boundary refinement (``"band"``).

Each case is one CLI campaign (``python -m farm quantify``, in-process executor, results,
holdout and plots included) in a child process under a 16 GB address-space cap, so its
peak resident memory (``wait4``'s ru_maxrss) and wall time are the whole command's. Gamma*
(deterministic), eps = 0.001, beta = 0.1, K = 50, delta0 = 2, certified, seed 0. Accuracy:
precision, recall and IoU of the written safe_set.parquet against 200,000 Monte-Carlo truth
points per scenario (uniform in Sigma, seed 7), each simulated to its end by
experiments/truth.py, a copy of the dynamics that imports nothing of the farm.

    python experiments/dimensions.py [CASE ...]   # runs it: docs/dimensions.json, docs/dimensions.md
    python experiments/dimensions.py --render     # docs/dimensions.md from the JSON only

CASE: ``name/delta_min/refine`` from CASES (e.g. ``platoon4/0.5/margin``) runs only those
and merges them into the JSON.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


from experiment import machine_stamp, main, write_doc

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
JSON = DOCS / "dimensions.json"
TRUTH_POINTS, TRUTH_SEED = 200_000, 7
MEMORY_CAP = 16 * 2**30  # [bytes] address space of a campaign: over it, a one-line failure instead of the kernel's kill
SCENARIOS = {  # name -> (the config's [scenario] table, experiments/truth.py's case, axes)
    "lead-follow": ({"name": "lead-follow", "sv_policy": "idm"}, "lead-follow/idm", 3),
    "lead-follow-params": ({"name": "lead-follow-params", "sv_policy": "idm"}, "lead-follow-params/idm", 5),
    "fleet3": ({"name": "fleet3", "sv_policy": "idm"}, "fleet3/idm", 5),
    "platoon4": ({"name": "platoon", "sv_policy": "idm", "vehicles": 4}, "platoon4/idm", 7),
    "platoon5": ({"name": "platoon", "sv_policy": "idm", "vehicles": 5}, "platoon5/idm", 9),
}
# K in steps of 0.1 s: long enough for every run to end or stand still, as the truth's do
# (at mu = 0.4 braking from 20 m/s takes 20 / (0.4 x 4.67) = 10.7 s; the others within 5 s)
HORIZONS = {"lead-follow-params": 120}
# the targets (runs, seconds, GB, precision, IoU) at the new refinement's cases
TARGETS = {("lead-follow", 0.125): (25_000, 12, 0.8, 0.998, 0.997), ("fleet3", 0.25): (150_000, 150, 2, 0.99, 0.98),
           ("platoon4", 0.5): (500_000, 1200, 4, 0.995, 0.97), ("platoon5", 1.0): (1_000_000, 1800, 6, 0.985, 0.955)}
CASES = [("lead-follow", 0.125, "margin"), ("lead-follow", 0.125, "band"),
         ("lead-follow-params", 0.25, "margin"), ("lead-follow-params", 0.25, "band"),
         ("lead-follow-params", 0.125, "margin"),
         ("fleet3", 0.25, "margin"), ("fleet3", 0.25, "band"),
         ("platoon4", 0.5, "margin"), ("platoon4", 1.0, "band"),
         ("platoon5", 1.0, "margin"), ("platoon5", 2.0, "band")]


def _scenario_text(name: str) -> str:
    """The [scenario] and [actions] tables of a case (Gamma*)."""
    table = "\n".join(f"{k} = {json.dumps(v)}" for k, v in SCENARIOS[name][0].items())
    return f"[scenario]\n{table}\n[actions]\nmode = \"adversarial\"\n"


def config_text(name: str, delta_min: float, refine: str) -> str:
    return (_scenario_text(name) +
            f"[quantify]\ndelta0 = 2.0\ndelta_min = {delta_min}\nepsilon = 0.001\nbeta = 0.1\nhorizon = {HORIZONS.get(name, 50)}\n"
            f"budget = 40000000\nrefine = \"{refine}\"\nsides = false\n"
            f"[farm]\nexecutor = \"local\"\nseed = 0\n")


def _capped():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def validation_text(name: str, delta_min: float, safe_set: Path) -> str:
    """A fresh VAL^delta of the exported set at the campaign's delta_min (its own covering)."""
    return (_scenario_text(name) +
            f"[validate]\nalgorithm = \"delta\"\nepsilon = 0.001\nbeta = 0.1\ndelta = {delta_min}\n"
            f"horizon = {HORIZONS.get(name, 50)}\n"
            f"domain_set = {json.dumps(str(safe_set))}\n[farm]\nexecutor = \"local\"\nseed = 7\n")


def campaign(name: str, delta_min: float, refine: str, out: Path) -> dict:
    """Run the CLI on the case; -> exit code, wall seconds, peak GB (and the stderr's tail on failure)."""
    cfg = out.parent / f"{out.name}.toml"
    cfg.write_text(config_text(name, delta_min, refine))
    return _command("quantify", cfg, out)


def validation(name: str, delta_min: float, out: Path) -> dict:
    """``validate`` (delta) of the campaign's safe_set.parquet: -> verdict, runs, wall seconds, peak GB."""
    cfg = out.parent / "validate.toml"
    cfg.write_text(validation_text(name, delta_min, out / "safe_set.parquet"))
    row = _command("validate", cfg, out.parent / "validation")
    if row["exit"] == 0:
        certificate = json.loads((out.parent / "validation" / "certificate.json").read_text())
        row.update(verdict=certificate["verdict"], runs=certificate["n_run"])
    return row


def _command(command: str, cfg: Path, out: Path) -> dict:
    start = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "farm", command, str(cfg), "--out", str(out), "--quiet"],
                             cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=_capped)
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    row = {"exit": code, "wall_s": round(seconds, 1), "peak_gb": round(usage.ru_maxrss * 1024 / 1e9, 2)}
    if code != 0:
        row["error"] = child.stderr.read().decode(errors="replace").strip().splitlines()[-1:]
    return row


def accuracy(name: str, out: Path, truths: dict) -> dict:
    from coordinator.safe_set import SafeSet
    from truth import truth_points

    if name not in truths:
        truths[name] = truth_points(SCENARIOS[name][1], TRUTH_POINTS, TRUTH_SEED)
    points, safe = truths[name]
    summary = json.loads((out / "summary.json").read_text())
    names = tuple(summary["state_names"]) if "state_names" in summary else None
    safe_set = SafeSet.from_parquet(out / "safe_set.parquet", names or _state_names(name))
    got = safe_set.contains(points)
    tp, fp, fn = int((got & safe).sum()), int((got & ~safe).sum()), int((~got & safe).sum())
    return {"runs": summary["runs_committed"], "boxes": summary["boxes"], "campaign_s": summary["elapsed_s"],
            "precision": tp / max(tp + fp, 1), "recall": tp / max(tp + fn, 1), "iou": tp / max(tp + fp + fn, 1),
            "holdout_overclaim": (summary.get("holdout") or {}).get("overclaim_share"),
            "result_hash": summary["result_hash"]}


def _state_names(name: str) -> tuple[str, ...]:
    from scenarios.registry import make_backend

    return make_backend(dict(SCENARIOS[name][0])).scenario.state_names


def run(name: str, delta_min: float, refine: str, truths: dict) -> dict:
    with tempfile.TemporaryDirectory(prefix="dimensions-") as tmp:
        out = Path(tmp) / "out"
        row = {"scenario": name, "axes": SCENARIOS[name][2], "delta_min": delta_min, "refine": refine,
               **campaign(name, delta_min, refine, out)}
        if row["exit"] == 0:
            row.update(accuracy(name, out, truths))
            row["validate"] = validation(name, delta_min, out)
    row["load_average"] = round(os.getloadavg()[0], 1)
    row["date"] = time.strftime("%Y-%m-%d")
    return row


def _key(row: dict) -> tuple:
    return row["scenario"], row["delta_min"], row["refine"]


def study(args: list[str]) -> None:
    sys.path.insert(0, str(ROOT))
    wanted = CASES if not args else [(n, float(d), r) for n, d, r in (a.split("/") for a in args)]
    data = json.loads(JSON.read_text()) if JSON.exists() else {"rows": []}
    rows = data["rows"]
    # a run of some cases keeps the stamp of the run they join (each row carries its own date)
    meta = data["meta"] if args and "meta" in data else machine_stamp(truth_points=TRUTH_POINTS, truth_seed=TRUTH_SEED)
    truths: dict = {}
    for case in wanted:
        row = run(*case, truths)
        print(json.dumps(row), flush=True)
        rows = [r for r in rows if _key(r) != case] + [row]
        rows.sort(key=lambda r: (r["axes"], r["scenario"], -r["delta_min"], r["refine"]))
        JSON.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    print(render())


def _cell(row: dict, key: str, fmt: str) -> str:
    return format(row[key], fmt) if row.get(key) is not None else "-"


def _target(row: dict) -> str:
    target = TARGETS.get((row["scenario"], row["delta_min"]))
    if target is None or row["refine"] != "margin" or row["exit"] != 0:
        return ""
    runs, seconds, gb, precision, iou = target
    missed = [what for what, ok in [(f"runs <= {runs:,}", row["runs"] <= runs),
                                    (f"<= {seconds} s", row["wall_s"] <= seconds), (f"<= {gb} GB", row["peak_gb"] <= gb),
                                    (f"precision >= {precision}", row["precision"] >= precision),
                                    (f"IoU >= {iou}", row["iou"] >= iou)] if not ok]
    return "all met" if not missed else "missed: " + ", ".join(missed)


def render() -> Path:
    """docs/dimensions.md from docs/dimensions.json."""
    data = json.loads(JSON.read_text())
    rows, meta = data["rows"], data["meta"]
    out = [
        "# Domains of 3 to 9 dimensions: margin refinement against band",
        "",
        "<!-- rendered by `python experiments/dimensions.py --render` from docs/dimensions.json: edit the script, "
        "not this file -->",
        "",
        f"`python experiments/dimensions.py` ({meta['date']}, {meta['machine']}, Python {meta['python']}, numpy "
        f"{meta['numpy']}): one CLI campaign per row (`scenario-farm quantify`, in-process executor, results, holdout",
        "and plots included; a 16 GB address-space cap), Gamma*, eps = 0.001, beta = 0.1, K = 50, delta0 = 2,",
        "certified, seed 0, the SV's IDM. `margin` is the margin refinement (the default for a deterministic",
        "system: docs/margin_refinement.md), `band` the earlier boundary refinement (Theorem 3's band). Accuracy of the",
        f"written set against {meta['truth_points']:,} Monte-Carlo truth points (uniform in Sigma, seed "
        f"{meta['truth_seed']}) simulated to their end by `experiments/truth.py`, which imports nothing of the farm.",
        "`holdout` is the campaign's own check (summary.json `holdout`: the share of 1,000 fresh starts in the set",
        "that fail). Seconds are the whole command's wall time on a shared 2-core machine; peak memory is its",
        "resident peak.",
        "",
        "| scenario | axes | delta_min | refine | runs | boxes | s | peak GB | precision | recall | IoU | holdout | targets |",
        "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        if r["exit"] != 0:
            out.append(f"| {r['scenario']} | {r['axes']} | {r['delta_min']:g} | {r['refine']} | - | - | {r['wall_s']:g} | "
                       f"{r['peak_gb']:g} | - | - | - | - | exit {r['exit']}: {' '.join(r.get('error', [])).split(';')[0]} |")
            continue
        out.append(f"| {r['scenario']} | {r['axes']} | {r['delta_min']:g} | {r['refine']} | {r['runs']:,} | "
                   f"{r['boxes']:,} | {r['wall_s']:g} | {r['peak_gb']:g} | {r['precision']:.4f} | {r['recall']:.4f} | "
                   f"{r['iou']:.4f} | {_cell(r, 'holdout_overclaim', '.2%')} | {_target(r)} |")
    checked = [r for r in rows if r.get("validate")]
    if checked:
        out += ["", "Each exported set validated afresh (`scenario-farm validate`, algorithm `delta` at the row's "
                "delta_min, the set's own covering, seed 7; in-process, the whole command):", "",
                "| scenario | delta_min | refine | boxes | verdict | runs | s | peak GB |",
                "| --- | ---: | --- | ---: | --- | ---: | ---: | ---: |"]
        for r in checked:
            v = r["validate"]
            verdict = v.get("verdict") or f"exit {v['exit']}: {' '.join(v.get('error', [])).split(';')[0]}"
            out.append(f"| {r['scenario']} | {r['delta_min']:g} | {r['refine']} | {r['boxes']:,} | {verdict} | "
                       f"{_cell(v, 'runs', ',')} | {v['wall_s']:g} | {v['peak_gb']:g} |")
    loads = [r["load_average"] for r in rows]
    out += ["", f"1-minute load average {min(loads):g}-{max(loads):g} at the end of the rows."]
    later = [r for r in rows if r.get("date", meta["date"]) != meta["date"]]
    for date in sorted({r["date"] for r in later}):
        cases = " ".join(f"{r['scenario']}/{r['delta_min']:g}/{r['refine']}" for r in later if r["date"] == date)
        out += ["", f"Rows re-run on {date} (`python experiments/dimensions.py {cases}`, the same machine); the "
                f"others are of {meta['date']}."]
    if any(r["exit"] == 130 for r in data["rows"]):
        out += ["", "Exit 130: a campaign still running after the seconds shown was stopped with SIGTERM (it "
                "checkpointed; the table gives its runs so far), to leave the machine to the other rows."]
    return write_doc(DOCS / "dimensions.md", out)


if __name__ == "__main__":
    main(study, render)
