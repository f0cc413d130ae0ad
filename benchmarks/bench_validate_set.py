"""`scenario-farm validate` (algorithm delta) of a 9-D margin set, as a user runs it: the
platoon of five (platoon k = 5, IDM SV, Gamma*) quantified from delta 2 to 1 by margin
refinement (about 20 k boxes with a half-width per axis), then validated at delta 1 on its
own covering: one run per box centre, each state screened against the covering, whose
boxes are widened by delta and overlap heavily. Prints the validation's seconds and its
milliseconds per run (the whole command, Python's start included).

    python benchmarks/bench_validate_set.py
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from targets import check, finish

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = '[scenario]\nname = "platoon"\nvehicles = 5\nsv_policy = "idm"\n[actions]\nmode = "adversarial"\n'
QUANTIFY = SCENARIO + ('[quantify]\ndelta0 = 2.0\ndelta_min = 1.0\nhorizon = 50\nholdout_runs = 0\n'
                       '[farm]\nexecutor = "local"\n')
MS_PER_RUN = 2.0  # issue 52: a stage linear in the boxes; before the covering's index was fixed, ~19 ms a run


def cli(*args: str) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "farm", *args, "--quiet"], cwd=ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench-validate-") as tmp:
        tmp = Path(tmp)
        (tmp / "q.toml").write_text(QUANTIFY)
        cli("quantify", str(tmp / "q.toml"), "--out", str(tmp / "q"))
        boxes = json.loads((tmp / "q" / "summary.json").read_text())["boxes"]
        (tmp / "v.toml").write_text(SCENARIO + f'[validate]\nalgorithm = "delta"\ndelta = 1.0\nhorizon = 50\n'
                                    f'domain_set = "{tmp / "q" / "safe_set.parquet"}"\n[farm]\nexecutor = "local"\n')
        seconds = cli("validate", str(tmp / "v.toml"), "--out", str(tmp / "v"))
        certificate = json.loads((tmp / "v" / "certificate.json").read_text())
    runs = certificate["n_run"]
    per_run = 1e3 * seconds / runs
    print(f"validate delta of a 9-D margin set ({boxes:,} boxes): {certificate['verdict']}, {runs:,} runs in "
          f"{seconds:.1f} s, {per_run:.2f} ms per run (target <= {MS_PER_RUN:g}: "
          f"{check(f'validate <= {MS_PER_RUN:g} ms per run', per_run <= MS_PER_RUN)})")
    check("the set certifies", certificate["verdict"] == "certified")
    finish()


if __name__ == "__main__":
    main()
