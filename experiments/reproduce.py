"""Rerun the paper's case studies (Sec. 4.4) and write docs/reproduction_results.json.

lead-follow brake and idm at the paper's delta = 1 and at delta = 0.5; fleet3 brake and
idm at the paper's delta = 1.5 and at delta = 0.75 (lead side, rear side, total); the N
values of Lemma 2. Campaigns use the example configs, in-process, as the paper runs
them: without the certification round this tool adds by default (quantify.certify).

    python experiments/reproduce.py            # campaigns -> docs/reproduction_results.json, then --render
    python experiments/reproduce.py --render   # the tables of docs/reproduction.md from the JSON only
"""

from __future__ import annotations

import datetime
import json
import re
import sys
import tempfile
import tomllib
from pathlib import Path

from coordinator.sample_size import n_eps
from farm import config as config_mod
from farm.jobs.quantification import run

ROOT = Path(__file__).resolve().parents[1]
KEYS = ["volume_union", "volume_hull", "boxes", "runs_committed", "rounds", "converged", "elapsed_s", "result_hash",
        "volume_lead_side", "volume_rear_side", "volume_hull_lead_side", "volume_hull_rear_side"]


def campaign(example: str, delta_min: float, tmp: Path) -> dict:
    raw = tomllib.loads((ROOT / "examples" / example).read_text())
    raw["quantify"]["delta_min"] = delta_min
    raw["quantify"]["certify"] = False  # the paper's SPE: no certification round
    raw["farm"]["executor"] = "local"
    cfg = config_mod.normalize(raw)
    s = run(cfg, tmp / f"{example}-{delta_min}", resume=False).to_json()
    return {k: s[k] for k in KEYS if k in s}


PAPER_HULL = {"brake": "26,734", "idm": "19,793"}  # paper Fig. 2, delta = 1
PAPER_FLEET3 = ["| paper, brake (hull, 3-D views) | 1.5 | 1149.2 | 949.5 | 2098.7 (sum) | |",
                "| paper, idm | 1.5 | 1054.8 | 1123.5 | 2178.3 (sum) | |"]
RESULTS = ROOT / "docs" / "reproduction_results.json"
DOC = ROOT / "docs" / "reproduction.md"


def main() -> None:
    out = {"date": datetime.date.today().isoformat(),
           "lemma2": {"eps=0.001, beta=0.01": n_eps(0.001, 0.01), "eps=0.001, beta=0.1": n_eps(0.001, 0.1)}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for example, deltas in [("lead_follow_brake.toml", (1.0, 0.5)), ("lead_follow_idm.toml", (1.0, 0.5)),
                                ("fleet3_brake.toml", (1.5, 0.75)), ("fleet3_idm.toml", (1.5, 0.75))]:
            for d in deltas:
                key = f"{example.removesuffix('.toml')} delta={d}"
                out[key] = campaign(example, d, tmp)
                print(key, json.dumps(out[key]), flush=True)
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    render()


def _tables(results: dict) -> dict[str, list[str]]:
    lf = ["| SV policy | delta | boxes | volume (union) | volume (hull) | paper (hull, delta = 1) | runs | time |",
          "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for sv in ("brake", "idm"):
        for d in (1.0, 0.5):
            r = results[f"lead_follow_{sv} delta={d}"]
            lf.append(f"| {sv} | {d} | {r['boxes']:,} | {r['volume_union']:,.0f} | {r['volume_hull']:,.0f} | "
                      f"{PAPER_HULL[sv] if d == 1.0 else ''} | {r['runs_committed']:,} | {r['elapsed_s']:.1f} s |")
    f3 = ["| SV policy | delta | lead side | rear side | total | runs (all three) |",
          "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for d in (1.5, 0.75):
        for sv in ("brake", "idm"):
            r = results[f"fleet3_{sv} delta={d}"]
            f3.append(f"| {sv} | {d} | {r['volume_lead_side']:,.0f} | {r['volume_rear_side']:,.0f} | "
                      f"{r['volume_union']:,.0f} | {r['runs_committed']:,} |")
    lemma = ["| eps | confidence | N (paper) | N (here, `coordinator.sample_size.n_eps`) |",
             "| --- | --- | ---: | ---: |",
             f"| 0.001 | 0.99 | 4603 | {results['lemma2']['eps=0.001, beta=0.01']} |",
             f"| 0.001 | 0.9 | - | {results['lemma2']['eps=0.001, beta=0.1']} |"]
    return {"lemma2": lemma, "lead-follow": lf, "fleet3": f3 + PAPER_FLEET3}


def render() -> Path:
    """Replace the tables between the doc's ``<!-- table NAME -->`` and ``<!-- end -->``
    markers (and the date) with those of the JSON: the doc cannot drift from it."""
    results = json.loads(RESULTS.read_text())
    text = DOC.read_text()
    for name, rows in _tables(results).items():
        pattern = re.compile(rf"(<!-- table {re.escape(name)} -->\n).*?(<!-- end -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"{DOC}: no '<!-- table {name} -->' ... '<!-- end -->' markers")
        text = pattern.sub(lambda m: m.group(1) + "\n".join(rows) + "\n" + m.group(2), text)
    text = re.sub(r"All\s+figures below were produced on \S+", f"All figures below were produced on "
                  f"{results.get('date', '?')}", text)
    DOC.write_text(text)
    return DOC


if __name__ == "__main__":
    if sys.argv[1:] == ["--render"]:
        print(render())
    else:
        main()
