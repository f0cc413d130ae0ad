"""A campaign as one self-contained HTML page (``scenario-farm report DIR --html``):
the guarantee in both forms, the figures (embedded), the summary, and the campaign round
by round from its ledger. Opens in any browser, offline; no script, no external asset."""

from __future__ import annotations

import base64
import html
from pathlib import Path

import pyarrow.compute as pc

from farm.directory.files import atomic_write_bytes
from farm.directory.storage import read_ledger
from farm.reports.estimate_report import EstimateReport, describe as describe_estimate, estimate_dirs
from farm.reports.summary import Summary
from farm.reports.truncations import shares

STYLE = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ddd}
.plain{font-size:1.1em;background:#eef7ee;border-left:4px solid #3a3;padding:.6em 1em}
.formal{color:#555;font-size:.92em;padding:.2em 1em}table{border-collapse:collapse;font-size:.9em}
td,th{border:1px solid #ddd;padding:.25em .6em;text-align:right}th{background:#f4f4f4}
td.k{text-align:left;color:#555}img{max-width:100%;border:1px solid #eee;margin:.5em 0}"""


def rounds_table(directory: Path) -> list[dict]:
    """Committed runs, changes and N_eps-counted runs per round, from the ledger; beside
    them the discarded runs the ledger also holds (simulated, never looked at: not in
    summary.json's runs_committed)."""
    table = read_ledger(directory, columns=["round", "delta", "changed", "counted", "discarded"])
    out = []
    for rnd in sorted(set(table.column("round").to_pylist())):
        rows = table.filter(pc.equal(table.column("round"), rnd))
        discarded = pc.sum(rows.column("discarded").cast("int64")).as_py() or 0
        out.append({"round": rnd, "delta": rows.column("delta")[0].as_py(), "committed": rows.num_rows - discarded,
                    "discarded": discarded, "changes": pc.sum(rows.column("changed").cast("int64")).as_py() or 0,
                    "counted": pc.sum(rows.column("counted").cast("int64")).as_py() or 0})
    return out


def _table(rows: list[dict]) -> str:
    if not rows:
        return "<p>(none)</p>"
    head = "".join(f"<th>{html.escape(k)}</th>" for k in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{v:,}</td>" if isinstance(v, int) else f"<td>{html.escape(str(v))}</td>"
                                    for v in r.values()) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _image(png: Path, label: str) -> str:
    data = base64.b64encode(png.read_bytes()).decode()
    return (f"<p>{html.escape(label)}<br><img alt='{html.escape(png.stem)}' "
            f"src='data:image/png;base64,{data}'></p>")


def _estimates(directory: Path) -> str:
    """The failure rates estimated beside the set (DIR/estimates/*): each against plain
    Monte Carlo's interval at the same runs, its strata, and where its failures fell."""
    parts = []
    for folder in estimate_dirs(directory):
        report = EstimateReport.read(folder)
        parts.append(f"<h3>{html.escape(folder.name)}</h3><p>"
                     + "<br>".join(map(html.escape, describe_estimate(report))) + "</p>")
        parts.append(_table([{"stratum": s["name"], "mass": f"{s['mass']:.4g}", "runs": s["runs"],
                              "failures": s["failures"], "rate": f"{s['rate']:.4g}",
                              "contribution": f"{s['contribution']:.4g}"} for s in report.strata]))
        png = folder / "failures.png"
        if png.exists():
            parts.append(_image(png, str(png.relative_to(directory))))
    if not parts:
        return ""
    return ("<h2>Failure rate</h2><p>P(failure) of runs started from the scenario distribution D (`scenario-farm "
            "estimate`), stratified around the safe set, against plain Monte Carlo's interval at the same runs.</p>"
            + "".join(parts))


def write_html(directory, out: Path | None = None) -> Path:
    """Write DIR/report.html (or ``out``) for a finished campaign; -> its path."""
    directory = Path(directory)
    summary = Summary.read(directory)
    title = f"{summary.scenario} / {summary.sv_policy} / {summary.algorithm}"
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{STYLE}</style></head><body><h1>Scenario Farm: {html.escape(title)}</h1>",
             f"<p class='plain'>{html.escape(summary.guarantee)}</p>",
             f"<p class='formal'>{html.escape(summary.guarantee_formal)}</p>"]
    parts.append("<h2>Figures</h2>")
    for png in sorted((directory / "plots").rglob("*.png")):
        parts.append(_image(png, str(png.relative_to(directory))))
    parts.append("<h2>Rounds</h2>" + _table(rounds_table(directory)))
    parts.append(_estimates(directory))
    parts.append("<h2>Truncated runs</h2><p>Committed runs that left Sigma through a truncating facet: they "
                 "end quietly and count as safe. A large share through a facet the study did not expect (a "
                 "vehicle reversing through a speed's lower bound) hides failures.</p>"
                 + _table([{"facet": facet, "runs": runs, "share of committed runs": f"{share:.2%}"}
                           for facet, runs, share in shares(summary)]))
    shown = {k: v for k, v in summary.to_json().items() if not isinstance(v, (list, dict))
             and not k.startswith("guarantee")}
    parts.append("<h2>Summary</h2><table>" + "".join(
        f"<tr><td class='k'>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>" for k, v in shown.items())
        + "</table>")
    recordings = sorted((directory / "recordings").glob("*.mcap")) if (directory / "recordings").is_dir() else []
    if recordings:
        parts.append("<h2>Recordings</h2><p>" + ", ".join(html.escape(p.name) for p in recordings)
                     + " (open in Foxglove with the .layout.json beside each file)</p>")
    parts.append("</body></html>")
    path = Path(out) if out is not None else directory / "report.html"
    atomic_write_bytes(path, "\n".join(parts).encode())
    return path
