"""Rerun the paper's case studies (Sec. 4.4) and write docs/reproduction_results.json.

lead-follow brake and idm at the paper's delta = 1 and at delta = 0.5; fleet3 brake and
idm at the paper's delta = 1.5 and at delta = 0.75 (lead side, rear side, total); the N
values of Lemma 2. Campaigns use the example configs, in-process.

    python experiments/reproduce.py
"""

from __future__ import annotations

import json
import tempfile
import tomllib
from pathlib import Path

from coordinator.covering import n_eps
from farm import config as config_mod
from farm.quantification import run

ROOT = Path(__file__).resolve().parents[1]
KEYS = ["volume_union", "volume_hull", "boxes", "runs_committed", "rounds", "converged", "elapsed_s", "result_hash",
        "volume_lead_side", "volume_rear_side", "volume_hull_lead_side", "volume_hull_rear_side"]


def campaign(example: str, delta_min: float, tmp: Path) -> dict:
    raw = tomllib.loads((ROOT / "examples" / example).read_text())
    raw["quantify"]["delta_min"] = delta_min
    raw["farm"]["executor"] = "local"
    cfg = config_mod.normalize(raw)
    s = run(cfg, tmp / f"{example}-{delta_min}", resume=False)
    return {k: s[k] for k in KEYS if k in s}


def main() -> None:
    out = {"lemma2": {"eps=0.001, beta=0.01": n_eps(0.001, 0.01), "eps=0.001, beta=0.1": n_eps(0.001, 0.1)}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for example, deltas in [("lead_follow_brake.toml", (1.0, 0.5)), ("lead_follow_idm.toml", (1.0, 0.5)),
                                ("fleet3_brake.toml", (1.5, 0.75)), ("fleet3_idm.toml", (1.5, 0.75))]:
            for d in deltas:
                key = f"{example.removesuffix('.toml')} delta={d}"
                out[key] = campaign(example, d, tmp)
                print(key, json.dumps(out[key]), flush=True)
    (ROOT / "docs" / "reproduction_results.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
