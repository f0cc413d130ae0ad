"""Runs that leave Sigma through a truncating facet are counted per facet over the
committed runs (summary.json ``truncations``), said at the end of the CLI's output when
they are a noticeable share, and tabled in the HTML report."""

import html
import json
import subprocess
import sys

import pyarrow.dataset as ds

from farm.reports.summary import Summary
from farm.reports.truncations import NOTICEABLE_SHARE, lines
from scenarios.base import OUTCOME_NAMES, TRUNCATED
from small_campaign import lead_follow_toml


def test_truncations_are_the_committed_truncated_runs_by_facet_and_the_cli_says_so(tmp_path):
    (tmp_path / "c.toml").write_text(lead_follow_toml())
    out = tmp_path / "c"
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out", str(out),
                        "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    table = ds.dataset(out / "ledger").to_table(columns=["outcome", "discarded"])
    ledger = table.column("outcome").to_numpy(zero_copy_only=False)[~table.column("discarded").to_numpy(
        zero_copy_only=False)]  # runs discarded unseen (coupled counting) were never counted
    truncations = summary["truncations"]
    assert sum(truncations.values()) == int((ledger == OUTCOME_NAMES[TRUNCATED]).sum()) > 0
    assert set(truncations) <= {"v0 > 20", "v1 > 20", "p10 > 70", "v0 < 0", "v1 < 0"}  # never the failure facet
    shown = [f"{n} runs left through {facet} (truncated, counted safe" for facet, n in truncations.items()
             if n >= NOTICEABLE_SHARE * summary["runs_committed"]]
    assert shown and all(s in r.stdout for s in shown)
    r = subprocess.run([sys.executable, "-m", "farm", "report", str(out), "--html"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    page = (out / "report.html").read_text()
    assert "Truncated runs" in page and all(f"<td>{html.escape(facet)}</td><td>{n:,}</td>" in page
                                            for facet, n in truncations.items())


def test_only_a_noticeable_share_is_said():
    base = {"scenario": "s", "algorithm": "spe", "boxes": 1, "result_hash": "h", "guarantee": "g"}
    summary = Summary.from_json({**base, "runs_committed": 10_000, "truncations": {"v1 < 0": 412, "p10 > 70": 99}})
    assert lines(summary) == ["412 runs left through v1 < 0 (truncated, counted safe; 4.1% of committed runs)"]
    assert lines(Summary.from_json({**base, "runs_committed": 5})) == []  # finished before the key existed
