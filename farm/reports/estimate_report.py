"""estimate.json: a failure rate beside the set, built, written and read here only, and
the lines that show it (``estimate``, ``report``) and its section of report.html.

Its keys are a public interface (README, "A failure rate beside the set"): ``estimate``,
``interval`` [low, high] at ``confidence``, ``half_width``, ``method``, ``runs``,
``failures``, ``strata`` (name, mass, runs, failures, rate, contribution), ``stages``,
``plain_mc`` (plain Monte Carlo's half-width at the same runs, the width ratio, and the
runs plain Monte Carlo needs for this width), ``zero_failures`` (the exact bound read as
the N_eps rule, when nothing failed), ``versus`` (a second controller: its rate and the
paired difference), ``distribution`` (D and its ``hash``), ``set``, the hashes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from coordinator.estimation import Interval, plain_half_width
from coordinator.estimation.intervals import z_value
from coordinator.sample_size import n_eps
from farm.config.hashing import config_hash
from farm.directory.json_record import JsonFile, record_from_json, record_to_json
from scenarios.version import __version__

FILE = "estimate.json"
REQUIRED = ("estimate", "interval", "confidence", "runs", "strata")


@dataclass(frozen=True, kw_only=True)
class EstimateReport(JsonFile):
    FILE: ClassVar[str] = FILE
    MISSING: ClassVar[str] = "{directory}: no {file} (the estimate has not finished; `scenario-farm estimate " \
                             "CAMPAIGN --resume --name NAME` continues it)"

    name: str = ""  # its directory: DIR/estimates/<name>
    scenario: str = ""
    controller: str = ""
    actions: str = ""
    action_weights: list | None = None  # the search's final mixture (family weights, adversary.json's order)
    horizon: int = 0
    seed: int = 0
    confidence: float
    estimate: float
    interval: list
    half_width: float = 0.0
    relative_half_width: float | None = None
    method: str = ""
    runs: int
    failures: int = 0
    stopped_by: str = ""
    runs_budget: int = 0
    relative_error: float | None = None
    strata: list
    stages: list = field(default_factory=list)
    plain_mc: dict = field(default_factory=dict)
    zero_failures: dict | None = None
    versus: dict | None = None
    distribution: dict = field(default_factory=dict)
    set: dict | None = None
    campaign_config_hash: str = ""
    estimate_hash: str = ""
    elapsed_s: float = 0.0
    virtual_elapsed_s: float | None = None  # a virtual farm's simulated time to the result
    scenario_farm_version: str = __version__
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return record_to_json(self)

    @classmethod
    def from_json(cls, data, source: str = FILE) -> "EstimateReport":
        return record_from_json(cls, data, source, REQUIRED)


def _interval_json(iv: Interval) -> dict:
    return {"estimate": iv.estimate, "interval": [iv.low, iv.high], "half_width": iv.half_width, "method": iv.method,
            "standard_error": iv.standard_error}


def _plain(rate: float, half_width: float, runs: int, confidence: float) -> dict:
    """What plain Monte Carlo gives at the same runs: its half-width, how much wider it is,
    and how many runs it would need for this estimate's half-width."""
    plain = plain_half_width(rate, runs, confidence)
    ratio = plain / half_width if half_width > 0 else None
    return {"half_width": plain, "width_ratio": ratio,
            "runs_for_same_width": int(np.ceil(runs * ratio**2)) if ratio else None}


def _zero(iv: Interval, runs: int) -> dict | None:
    """No failure: the exact bound, and the N_eps rule it is (N = ln alpha / ln(1 - bound))."""
    if iv.estimate > 0 or iv.low < 0:
        return None
    alpha = 1 - iv.confidence
    return {"upper_bound": iv.high, "n_eps_reading": (
        f"no failure in {runs:,} runs: P(failure) <= {iv.high:.3g} with confidence {iv.confidence:g} "
        f"(N_eps({iv.high:.3g}, {alpha:g}) = {n_eps(iv.high, alpha):,} runs)")}


def _unpaired(rate: Interval, other: Interval, diff: Interval) -> tuple[float, float | None]:
    """The difference's half-width had the two controllers run apart, and how many times
    wider that is than the paired one. From standard errors where all three intervals are
    normal: a half-width clipped at 0 (a rate near zero) would understate the unpaired
    width and show pairing as a loss."""
    if None not in (rate.standard_error, other.standard_error, diff.standard_error):
        se = float(np.hypot(rate.standard_error, other.standard_error))
        return se * z_value(rate.confidence), (se / diff.standard_error if diff.standard_error > 0 else None)
    unpaired = float(np.hypot(rate.half_width, other.half_width))
    return unpaired, (unpaired / diff.half_width if diff.half_width > 0 else None)


def report_of(name: str, setup, run, elapsed_s: float, virtual_elapsed_s: float | None = None) -> EstimateReport:
    """estimate.json of a finished ``StageRun`` over ``setup`` (farm/jobs/estimate_setup.py);
    ``virtual_elapsed_s``: the virtual farm's simulated time to the result, if it ran there."""
    tally, strata, s = run.tally, setup.strata, setup.settings
    rate = run.rate()
    n_h, x_h = tally.runs.sum(axis=0), tally.failures.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        stratum_rate = np.where(n_h > 0, x_h / np.maximum(n_h, 1), 0.0)
    rows = [{"name": name, "mass": float(w), "runs": int(n), "failures": int(x), "rate": float(r),
             "contribution": float(w * r)} for name, w, n, x, r in zip(strata.names, strata.masses, n_h, x_h,
                                                                       stratum_rate)]
    stages = [{"stage": t, "runs": int(tally.runs[t].sum()), "failures": int(tally.failures[t].sum()),
               "allocation": tally.planned[t].tolist()} for t in range(tally.stages)]
    versus = None
    if setup.paired:
        other, diff = run.rate(versus=True), tally.difference(strata.masses, s.confidence)
        unpaired, gain = _unpaired(rate, other, diff)
        versus = {"controller": setup.labels[1], **_interval_json(other),
                  "failures": int(tally.versus_failures.sum()),
                  "difference": {"of": f"{setup.labels[0]} - {setup.labels[1]}", **_interval_json(diff),
                                 "unpaired_half_width": unpaired,
                                 "two_plain_half_width": float(np.hypot(
                                     plain_half_width(rate.estimate, tally.committed, s.confidence),
                                     plain_half_width(other.estimate, tally.committed, s.confidence))),
                                 "pairing_gain": gain,
                                 "runs_only_first_failed": int(tally.a_only.sum()),
                                 "runs_only_second_failed": int(tally.b_only.sum())},
                  "zero_failures": _zero(other, tally.committed)}
    cfg = setup.cfg
    return EstimateReport(
        name=name, scenario=setup.scenario.name, controller=setup.labels[0], actions=cfg.actions.mode,
        action_weights=None if setup.actions is None else list(setup.actions["schedule"][0][1]),
        horizon=setup.specs[0].horizon, seed=setup.seed, confidence=s.confidence, estimate=rate.estimate,
        interval=[rate.low, rate.high], half_width=rate.half_width,
        relative_half_width=rate.half_width / rate.estimate if rate.estimate > 0 else None, method=rate.method,
        runs=tally.committed, failures=int(x_h.sum()), stopped_by=run.stopped_by or "", runs_budget=s.runs,
        relative_error=s.relative_error, strata=rows, stages=stages,
        plain_mc=_plain(rate.estimate, rate.half_width, tally.committed, s.confidence),
        zero_failures=_zero(rate, tally.committed), versus=versus,
        distribution={**setup.law.describe(), "hash": setup.law.digest},
        set=None if setup.set_hash is None else {"result_hash": setup.set_hash, "band": cfg.estimate.band,
                                                  "grid": list(strata.shape)},
        campaign_config_hash=config_hash(cfg), estimate_hash=setup.estimate_hash,
        elapsed_s=round(elapsed_s, 3), virtual_elapsed_s=virtual_elapsed_s)


def describe(report: EstimateReport) -> list[str]:
    """The estimate in a few lines (``scenario-farm estimate``, ``scenario-farm report``)."""
    label = f"estimate {report.name}".strip()
    level = f"{report.confidence:.0%}"
    lines = [f"{label}: P(failure) = {report.estimate:.4g}, {level} interval [{report.interval[0]:.4g}, "
             f"{report.interval[1]:.4g}] ({report.method}), {report.runs:,} runs, {report.failures:,} failures"]
    plain = report.plain_mc
    if plain.get("width_ratio") and len(report.strata) > 1:  # (plain Monte Carlo itself: nothing to compare)
        lines.append(f"  plain Monte Carlo at {report.runs:,} runs: +-{plain['half_width']:.3g} "
                     f"({plain['width_ratio']:.1f}x wider; it needs ~{plain['runs_for_same_width']:,} runs for "
                     f"+-{report.half_width:.3g})")
    if report.zero_failures:
        lines.append(f"  {report.zero_failures['n_eps_reading']}")
    if report.versus:
        v, d = report.versus, report.versus["difference"]
        lines.append(f"  {v['controller']}: P(failure) = {v['estimate']:.4g} [{v['interval'][0]:.4g}, "
                     f"{v['interval'][1]:.4g}]")
        gain = f", {d['pairing_gain']:.1f}x narrower than unpaired" if d.get("pairing_gain") else ""
        lines.append(f"  difference {d['of']}: {d['estimate']:.4g} [{d['interval'][0]:.4g}, {d['interval'][1]:.4g}] "
                     f"(paired{gain})")
    return lines


def estimate_dirs(campaign: Path) -> list[Path]:
    """The estimates of a campaign directory that have finished (estimate.json written)."""
    root = Path(campaign) / "estimates"
    return sorted(p.parent for p in root.glob(f"*/{FILE}")) if root.is_dir() else []
