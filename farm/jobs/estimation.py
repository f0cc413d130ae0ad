"""An estimate in a campaign directory (`scenario-farm estimate DIR`): P(failure) of runs
started from the scenario distribution D, with an interval, beside the campaign's set.

``run`` reads top to bottom: the campaign and its [estimate] section (farm/jobs/estimate_setup.py),
the estimate's own directory ``DIR/estimates/<name>/`` (refused if it holds one, unless
``force``; continued with ``resume``), the stages on the campaign's executors
(coordinator/estimation/stages.py), checkpointing every ``farm.checkpoint_every``
seconds, then estimate.json and failures.png. A resumed estimate (after a signal or
kill -9) reaches the very estimate an uninterrupted one does, on any number of workers.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pyarrow.compute as pc
import pyarrow.parquet as pq

from coordinator.estimation import StageRun, Tally
from farm import config as config_mod, lazy
from farm.config import Config
from farm.directory.estimate_ledger import EstimateLedger
from farm.directory.files import write_json
from farm.directory.journal import Journal
from farm.directory.storage import CampaignDir, CampaignError
from farm.execution.factory import make_executor
from farm.execution.waiting import Interrupted
from farm.jobs.estimate_setup import EstimateSetup, setup as build_setup
from farm.jobs.signals import stop_on_signals
from farm.reports.estimate_report import EstimateReport, report_of
from farm.reports.progress import Progress
from farm.reports.summary import Summary
from scenarios.errors import ConfigError, Stopped

KIND = "estimate"


def estimate_config(campaign: Path, source=None, overrides: dict | None = None) -> Config:
    """The campaign's frozen config with its [estimate] table replaced by ``source``'s (a
    TOML path or string, or a dict, holding an [estimate] table and nothing else) and
    ``overrides`` applied (``{"estimate.runs": 5000, "farm.workers": 2}``)."""
    CampaignDir(campaign).open("quantify")
    Summary.read(campaign)  # a finished campaign: its set and its action law are final
    cfg = CampaignDir(campaign).frozen_config()
    if source is not None:
        raw = source if isinstance(source, dict) else \
            config_mod.parse_tables(config_mod.read_text(source), str(source)) if _is_file(source) else \
            config_mod.parse_tables(str(source), "estimate config")
        other = sorted(set(raw) - {"estimate"})
        if other:
            raise ConfigError(f"estimate config: holds [{other[0]}]; an estimate uses the campaign's; allowed: "
                              f"[estimate] only")
        cfg = config_mod.normalize({**cfg.model_dump(), "estimate": raw.get("estimate", {})})
    return cfg.with_overrides(overrides or {})


def _is_file(source) -> bool:
    try:
        return Path(source).is_file()
    except (OSError, ValueError):
        return False


def default_name(cfg: Config, labels) -> str:
    name = "plain" if cfg.estimate.strata == "none" else "stratified"
    return f"{name}-vs-{re.sub(r'[^A-Za-z0-9_.-]+', '-', labels[1])}" if len(labels) > 1 else name


def run(cfg: Config, campaign: Path, *, name: str | None = None, resume: bool = False, force: bool = False,
        progress: Progress | None = None) -> EstimateReport:
    """Estimate P(failure) for ``cfg`` (``estimate_config``) beside the campaign in
    ``campaign``, in ``campaign/estimates/<name>``; -> estimate.json. Everything is checked
    before a file is written; ``resume`` continues a stopped or killed estimate (or one
    whose budget ``estimate.runs`` was raised); ``force`` replaces one."""
    campaign = Path(campaign)
    progress = progress or Progress(enabled=False)
    parts = build_setup(cfg, campaign)
    name = name or default_name(cfg, parts.labels)
    if not name or "/" in name or name.startswith("."):
        raise ConfigError(f"--name: {name!r} is not a directory name; allowed: letters, digits, '-', '_'")
    directory = CampaignDir(campaign / "estimates" / name)
    ledger = EstimateLedger(directory.path / "ledger", parts.scenario.state_names)
    journal = Journal(directory.path)
    if resume and directory.nothing_started():
        resume, force = False, True
    try:
        tally = _open(directory, parts, ledger, journal, resume, force)
        t0 = time.monotonic()
        stage_run, clock = _run(parts, tally, ledger, journal, progress, directory.path)
        if clock is None and (directory.path / "estimate.json").exists():
            before = EstimateReport.read(directory.path)
            if (before.runs, before.confidence) == (stage_run.committed, parts.settings.confidence):
                return before  # resumed when finished, nothing changed: the estimate as written
        report = report_of(name, parts, stage_run, time.monotonic() - t0,
                           None if clock is None else clock.elapsed_s)
        report.write(directory.path)
        _figure(directory.path, parts, report)
        return report
    finally:
        directory.unlock()


def _open(directory: CampaignDir, parts: EstimateSetup, ledger, journal, resume: bool, force: bool) -> Tally | None:
    """The estimate's directory, locked: a new one, or a resumed one's tally."""
    if not resume:
        if (directory.path / "estimate.json").exists() and not force:
            raise CampaignError(f"{directory.path}/estimate.json exists; pass --force to replace it or --resume to "
                                f"continue (a larger estimate.runs extends it)")
        directory.create(KIND, force=force)
        write_json(directory.path / "estimate_config.json", {
            "estimate": parts.cfg.estimate.model_dump(mode="json"), "estimate_hash": parts.estimate_hash,
            "labels": list(parts.labels), "distribution": parts.law.describe(), "seed": parts.seed})
        return None
    directory.open(KIND)
    directory.lock()
    if not journal.exists():
        if any(ledger.dir.glob("segment-*.parquet")):
            raise CampaignError(f"{directory.path}: ledger segments exist but checkpoint.npz is missing; refusing to "
                                f"start the estimate over them")
        return None
    arrays, meta = journal.load()
    if meta.get("estimate_hash") != parts.estimate_hash:
        raise CampaignError(f"{directory.path}: an estimate of another distribution, set or settings (hash "
                            f"{meta.get('estimate_hash')}, this one {parts.estimate_hash}); only estimate.runs, "
                            f"estimate.relative_error, estimate.confidence and [farm] may change on resume")
    ledger.verify_and_trim(meta["ledger_digests"], meta["ledger_rows"])
    directory.remove_stale_temp_files()
    return Tally.from_arrays(arrays, len(parts.strata), parts.paired)


def _save(stage_run: StageRun, ledger: EstimateLedger, journal: Journal, parts: EstimateSetup) -> None:
    ledger.flush()
    journal.save(stage_run.tally.arrays(), set(), 0, {"estimate_hash": parts.estimate_hash,
                                                      "ledger_digests": ledger.digests, "ledger_rows": ledger.rows})


def _executors(parts: EstimateSetup, stop) -> list:
    """One executor per controller; a comparison splits the workers between the two."""
    farm_cfg = parts.cfg.farm
    if parts.paired:
        farm_cfg = farm_cfg.model_copy(update={"workers": max(1, farm_cfg.workers // 2)})
    executors = []
    try:
        for spec in parts.specs:
            executors.append(make_executor(farm_cfg, spec, stop=stop.event))
    except BaseException:
        for executor in executors:
            executor.close()
        raise
    return executors


def _run(parts: EstimateSetup, tally, ledger, journal, progress: Progress, out: Path):
    """-> the finished stages and the virtual farm's clock (None on a real executor)."""
    if tally is not None and tally.stages and tally.stage_complete():
        over = StageRun(parts.strata, parts.settings, parts.seed, [], tally)
        over.stopped_by = over.finished()
        if over.stopped_by:  # a finished estimate resumed with its own budget: nothing to run (no Ray)
            return over, None
    every = parts.cfg.farm.checkpoint_every
    last = [time.monotonic()]
    t0 = time.monotonic()

    def observe(stage_run: StageRun, batch) -> None:
        ledger.add(batch)
        rate = stage_run.rate()
        speed = (stage_run.committed - start) / max(time.monotonic() - t0, 1e-9)
        progress.count(f"estimate stage {batch.stage}: P(failure) {rate.estimate:.4g} +-{rate.half_width:.2g}, "
                       f"{speed:,.0f} runs/s; runs", stage_run.committed, parts.settings.runs)
        if time.monotonic() - last[0] >= every:
            _save(stage_run, ledger, journal, parts)
            last[0] = time.monotonic()

    stop = stop_on_signals()
    with stop:
        executors = _executors(parts, stop)
        stage_run = StageRun(parts.strata, parts.settings, parts.seed, executors, tally, parts.actions, [observe])
        start = stage_run.committed
        stop.campaign = stage_run
        try:
            stage_run.run()
        except Interrupted:
            pass  # a wait for a chunk woke for the stop: the tally is as after the last commit
        finally:
            for executor in executors:
                executor.close()
    _save(stage_run, ledger, journal, parts)
    if stage_run.stopped_by is not None:
        progress.line(f"estimate: {stage_run.committed:,} runs in {stage_run.tally.stages} stages (stopped by "
                      f"{stage_run.stopped_by}); writing estimate.json and failures.png")
    else:
        raise Stopped(f"estimate stopped at {stage_run.committed:,} runs; checkpointed (continue with `scenario-farm "
                      f"estimate {out.parent.parent} --name {out.name} --resume`)")
    return stage_run, executors[0].report()


def _figure(out: Path, parts: EstimateSetup, report: EstimateReport) -> None:
    names = list(parts.scenario.state_names)
    table = pq.read_table(out / "ledger", columns=[*names, "outcome"])
    starts = np.column_stack([table.column(n).to_numpy() for n in names])
    failed = pc.equal(table.column("outcome"), "failure").to_numpy(zero_copy_only=False)
    lazy.estimate_figure.draw_estimate(out / "failures.png", names, {n: parts.scenario.label(n) for n in names},
                                       starts, failed, report)

