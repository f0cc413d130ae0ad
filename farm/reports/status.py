"""Live status of a campaign, from its files alone.

``StatusWriter`` rewrites ``DIR/status.json`` atomically every ``EVERY_S`` seconds while a
campaign runs (independent of checkpoints): state, side, round, delta, boxes, the N_eps
counter, committed runs, runs/s. ``describe`` (``scenario-farm status DIR``) reads it,
and tells a live campaign from a dead one by the directory lock, not by a heartbeat.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from farm.directory.files import read_json, write_json
from farm.directory.storage import MARKER, CampaignDir, CampaignError
from farm.reports.certificate import FILE as CERTIFICATE_FILE, Certificate
from farm.reports.summary import FILE as SUMMARY_FILE, Summary

EVERY_S = 2.0


class StatusWriter:
    def __init__(self, directory: Path):
        self.dir = Path(directory)
        self._last = 0.0
        self._started = time.time()

    def write(self, fields: dict) -> None:
        write_json(self.dir / "status.json", {**fields, "updated": time.time(), "started": self._started})

    def update(self, side: str, campaign, *, state: str = "running", force: bool = False):
        now = time.monotonic()
        if not force and now - self._last < EVERY_S:
            return
        self._last = now
        self.write({"state": state, "side": side, **snapshot(campaign)})


def snapshot(campaign) -> dict:
    """Where a running campaign stands (coordinator.driver.Campaign)."""
    c, algorithm, n_eps = campaign.counters, campaign.algorithm, campaign.n_eps
    counts = algorithm.counts()
    return {"round": counts.get("round", 0), "delta": counts.get("delta"), "boxes": counts.get("boxes"),
            "n_eps_counter": c.quiet, "n_eps": n_eps, "runs_committed": c.committed,
            "runs_simulated": c.runs_simulated, "changes": c.changes, "elapsed_s": round(c.elapsed_s, 1),
            "runs_per_s": round(c.committed / c.elapsed_s, 1) if c.elapsed_s > 0 else None,
            "n_eps_needed": campaign.quiet_needed(), **_certification(campaign, counts), **_search(campaign)}


def _search(campaign) -> dict:
    """actions.mode = "search": the mixture the current round samples."""
    if campaign.adversary is None:
        return {}
    policy = campaign.adversary.policy
    return {"search_weights": {f.label(): round(w, 4) for f, w in zip(policy.families, policy.weights)}}


def _certification(campaign, counts) -> dict:
    """A deterministic certification counts centres run, not runs in a row; a sampled one
    is in a closing round or a check (its attempt)."""
    algorithm, c = campaign.algorithm, campaign.counters
    if "splits" in counts:  # margin refinement: its waves, and the boxes it split
        return {"splits": counts["splits"], "leaves": counts["leaves"]}
    if not algorithm.certifying:
        return {}
    if algorithm.enumerates:  # no checks: every centre once (summary.json's certification_attempts is 0)
        return {"runs_certification": c.runs_certification, "certified": counts.get("certified", 0),
                "centres": counts.get("boxes", 0)}
    return {"certification_attempts": c.attempts, "runs_certification": c.runs_certification,
            "certification_phase": "closing" if algorithm.closing else "check",
            "certification_check_violations": c.check_violations}


def read_status(directory: Path) -> dict | None:
    try:
        data = json.loads((Path(directory) / "status.json").read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def describe(directory: Path) -> str:
    directory = Path(directory)
    if not (directory / MARKER).exists() or not (directory / "config.json").exists():
        raise CampaignError(f"{directory}: not a campaign directory (no {MARKER} or config.json)")
    kind = (CampaignDir(directory).marker() or {}).get("kind")
    lines = [f"{'validation' if kind == 'validate' else 'campaign'} {directory}"]
    frozen = read_json(directory / "config.json", ("config", "config_hash"))
    try:
        c = frozen["config"]
        lines.append(f"  scenario {c['scenario']['name']} / {c['scenario'].get('sv_policy')} / "
                     f"{c['validate' if kind == 'validate' else 'quantify']['algorithm']}, config hash "
                     f"{frozen['config_hash']}")
    except (KeyError, TypeError) as exc:
        raise CampaignError(f"{directory}/config.json: lacks {exc} (damaged?)") from None
    holder = CampaignDir(directory).holder()
    if kind == "validate":
        return "\n".join(lines + [_validation(directory, holder)])
    st = read_status(directory)
    if st is None:
        lines.append("  not started" if holder is None else f"  starting (pid {holder})")
    else:
        state = st.get("state", "?")
        if state in ("running", "finishing") and holder is None:
            state = f"stopped while {state} (process gone; continue with `scenario-farm resume {directory}`)"
        elif state == "stopped" and holder is None:  # by a signal, checkpointed
            state = f"stopped (continue with `scenario-farm resume {directory}`)"
        elif holder is not None:
            state = f"{state} (pid {holder}, updated {time.time() - st.get('updated', 0):.0f} s ago)"
        fields = ["side", "round", "delta", "boxes", "n_eps_counter", "n_eps", "runs_committed", "runs_simulated",
                  "runs_per_s", "elapsed_s", "result_hash"]
        detail = ", ".join(f"{k} {st[k]}" for k in fields if st.get(k) is not None)
        lines.append(f"  {state}" + (f": {detail}" if detail else ""))
        if st.get("search_weights"):
            lines.append("  search mixture: " + ", ".join(f"{k} {v:.3f}" for k, v in st["search_weights"].items()))
    if (directory / SUMMARY_FILE).exists():
        s = Summary.read(directory)
        lines.append(f"  finished: {s.boxes} boxes, volume {s.volume_union:.6g}, result hash {s.result_hash}")
        lines.append(f"  {s.guarantee}")
    return "\n".join(lines)


def _validation(directory: Path, holder: int | None) -> str:
    """A validation's line: its verdict (certificate.json), or that it is being written. Its
    directory is made once the runs are done: without a certificate it holds no result."""
    if (directory / CERTIFICATE_FILE).exists():
        cert = Certificate.read(directory)
        if cert.counterexample:
            ce = cert.counterexample
            return (f"  done: counterexample at sample {ce['sample_index']} after {cert.n_run} runs: {ce.get('reason')} "
                    f"(`scenario-farm replay {directory} --sample {ce['sample_index']}` re-runs it)")
        return f"  done: {cert.verdict} after {cert.n_run} runs: {cert.guarantee}"
    if holder is not None:
        return f"  writing its certificate (pid {holder})"
    return "  no certificate: the validation ended before writing it (run `scenario-farm validate` again)"


def watch(directory: Path, every: float = EVERY_S, stream=None, max_s: float | None = None) -> str:
    """Print ``describe`` each time the status changes, until the campaign is done or no
    process works on it any more (``scenario-farm status DIR --watch``); -> the last text."""
    stream = stream or sys.stdout
    shown, start = None, time.monotonic()
    while True:
        text = describe(directory)
        body = "\n".join(line for line in text.splitlines() if "updated" not in line) + \
            str((read_status(directory) or {}).get("runs_committed"))
        if body != shown:
            stream.write(text + "\n")
            stream.flush()
            shown = body
        ended = CampaignDir(directory).holder() is None and (read_status(directory) or {}).get("state") != "starting"
        if ended or (max_s is not None and time.monotonic() - start > max_s):
            return text
        time.sleep(every)

