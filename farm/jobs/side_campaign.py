"""One side's campaign in its directory: a side is the set of failure facets that count,
the configured ones ("total", in the campaign directory) or a scenario's named side
(fleet3's "lead" and "rear", in ``DIR/sides/<side>``). It owns its algorithm, its ledger
and its checkpoint; its executor lives while it runs.
"""

from __future__ import annotations

import gc
import time
from pathlib import Path

import numpy as np

from coordinator.driver import Campaign
from coordinator.holdout import holdout_report, holdout_starts
from farm.directory import checkpoint
from farm.directory.checkpoint import Stamp
from farm.directory.files import read_json, write_json
from farm.jobs.campaign_setup import build_algorithm, build_campaign
from farm.jobs.resources import MemoryGuard
from farm.execution.process import build_simulator, close_simulator, spec_of
from farm.config import Config, config_hash
from farm.execution.factory import make_executor
from farm.directory.journal import Journal
from farm.execution.memory import release_freed_memory
from farm.reports.progress import Progress
from farm.jobs.signals import stop_on_signals
from farm.reports.status import StatusWriter
from farm.directory.storage import CampaignError, Ledger
from farm.execution.waiting import Interrupted
from scenarios.errors import Stopped

LARGE_CHECKPOINT_MB = 100  # a checkpoint from this size on gets a line before and after it is read
HOLDOUT_FILE = "holdout.json"  # a finished campaign's holdout, so that a resume before summary.json need not run it again


class SideCampaign:
    def __init__(self, cfg: Config, side: str, directory: Path, failure_facets: list | None):
        """Builds (and so checks) the scenario, back end, actions and algorithm now."""
        self.cfg, self.side, self.directory = cfg, side, Path(directory)
        self.spec = spec_of(cfg, failure_facets)
        self.simulator = build_simulator(self.spec)
        self.scenario, self.policy = self.simulator.scenario, self.simulator.policy
        self.algorithm = build_algorithm(cfg, self.simulator)
        close_simulator(self.simulator, cfg.farm.chunk_timeout)  # its back end simulates nothing: the executor's do
        self.ledger = Ledger(self.directory / "ledger", self.scenario.state_names)
        self.journal = Journal(self.directory)
        self.config_hash = config_hash(cfg)
        self.stamp = Stamp(self.directory, side, self.config_hash, cfg.farm.seed, self.scenario)
        self.campaign: Campaign | None = None
        self.startup_s = 0.0
        self.virtual = None  # the virtual farm's VirtualClock (farm/execution/virtual.py)
        self.holdout: dict | None = None  # fresh uniform runs against the set (coordinator/holdout.py)
        self._restored: checkpoint.Restored | None = None
        self.memory = MemoryGuard(cfg, self.scenario.n)
        # the directory `scenario-farm resume` takes: the total's, which holds the sides'
        self.campaign_root = self.directory if side == "total" else self.directory.parent.parent

    def restore(self, say=lambda text: None) -> None:
        """Load and check this campaign's checkpoint, if it has one (nothing is written).
        ``say``: a line before and after reading a large one (millions of boxes take a while;
        a small one is read at once, and an error it ends in stays the only line)."""
        if self.journal.exists():
            megabytes = self.journal.size_bytes() / 1e6
            loud = megabytes >= LARGE_CHECKPOINT_MB
            prefix = "" if self.side == "total" else f"{self.side} side: "
            if loud:
                say(f"{prefix}reading the checkpoint ({megabytes:,.0f} MB)")
            t0 = time.monotonic()
            self._restored = checkpoint.restore(self.journal, self.ledger, self.algorithm, self.policy, self.stamp)
            if loud:
                say(f"{prefix}checkpoint read in {time.monotonic() - t0:.1f} s: resuming at "
                    f"{self._restored.driver.counters.committed:,} committed runs")
        elif any((self.directory / "ledger").glob("segment-*.parquet")):
            raise CampaignError(f"{self.directory}: ledger segments exist but checkpoint.npz is missing; refusing "
                                f"to restart the campaign from scratch over them")

    def run(self, progress: Progress, status: StatusWriter) -> Campaign:
        """Run to the end (a finished campaign read back runs nothing), checkpointing every
        ``farm.checkpoint_every`` seconds; raises Stopped after a signal (checkpointed)."""
        restored = self._restored
        if restored is not None and restored.driver.counters.done:
            self.campaign = build_campaign(self.cfg, self.algorithm, self.simulator, None, restored=restored)
            if self.side == "total":
                # killed while finishing, before summary.json: the holdout saved with the last
                # checkpoint (or, killed before it was written, the same seeded runs again)
                self.holdout = self._holdout_again(progress)
            return self.campaign
        farm_cfg = self.cfg.farm
        self.directory.mkdir(parents=True, exist_ok=True)
        stop = stop_on_signals()
        # the handlers cover start-up too: a signal while Ray starts (seconds) is taken
        # once it has started, not in the middle of ray.init (which can crash on it)
        with stop:
            t0 = time.monotonic()
            executor = make_executor(farm_cfg, self.spec, check_step_bound=self.cfg.quantify.boundary,
                                     stop=stop.event, notify=progress.line)
            self.startup_s = time.monotonic() - t0
            for line in executor.started(farm_cfg.counting, farm_cfg.batch_size, farm_cfg.pipeline_depth):
                progress.line(line)
            observers = [self._observer(progress, status)]
            self.campaign = build_campaign(self.cfg, self.algorithm, self.simulator, executor, observers, restored)
            stop.campaign = self.campaign
            try:
                self.campaign.run()
                if self.campaign.counters.done and self.side == "total":
                    self.holdout = self._holdout(executor, progress)
            except Interrupted:
                pass  # a wait for a chunk woke for the stop: the campaign is as after its last commit
            finally:
                executor.close()
            self.virtual = executor.report()
        done = self.campaign.counters.done
        if done:
            self.algorithm.stop_committing()  # the last checkpoint is then gathered with less held
        self.save()
        if not done:
            status.update(self.side, self.campaign, state="stopped", force=True)
            if self.memory.held:
                raise self.memory.over(self.campaign.counters.committed, self.campaign_root)
            raise Stopped(f"stopped at {self.campaign.counters.committed} committed runs")
        self.algorithm.release()
        gc.collect()  # what reference cycles still hold of the released state, before the heap is trimmed
        release_freed_memory()
        return self.campaign

    def _holdout_again(self, progress: Progress) -> dict | None:
        """The holdout of a finished campaign read back: its checkpoint (``HOLDOUT_FILE``),
        else its runs again, on an executor of its own."""
        if self.cfg.quantify.holdout_runs <= 0:
            return None
        saved = self._saved_holdout()
        if saved is not None:
            progress.line(f"holdout: {saved['runs']:,} runs read back from {HOLDOUT_FILE}")
            return saved
        stop = stop_on_signals()
        with stop:
            executor = make_executor(self.cfg.farm, self.spec, check_step_bound=self.cfg.quantify.boundary,
                                     stop=stop.event, notify=progress.line)
            try:
                return self._holdout(executor, progress)
            except Interrupted:
                raise Stopped("stopped while finishing (the holdout's runs); resume finishes it") from None
            finally:
                executor.close()

    def _holdout(self, executor, progress: Progress) -> dict | None:
        """``quantify.holdout_runs`` fresh runs from uniform starts in Sigma, on the
        campaign's executor, against the set it found."""
        runs = self.cfg.quantify.holdout_runs
        if runs <= 0:
            return None
        progress.line(f"holdout: {runs:,} fresh runs from uniform starts against the set")
        indices, starts = holdout_starts(self.scenario, self.cfg.farm.seed, runs)
        outcomes = np.concatenate([executor.result(h).outcomes
                                   for h in executor.submit(0, starts, indices=indices.astype(np.int64))])
        inside = self.algorithm.result().contains(starts)
        report = holdout_report(inside, outcomes, self.simulator.deterministic)
        write_json(self.directory / HOLDOUT_FILE, {**self._holdout_stamp(), "report": report})
        return report

    def _holdout_stamp(self) -> dict:
        """What a saved holdout was run for: the same runs against the same set."""
        return {"config_hash": self.config_hash, "seed": self.cfg.farm.seed, "runs": self.cfg.quantify.holdout_runs}

    def _saved_holdout(self) -> dict | None:
        """The holdout saved for this campaign's config, seed and run count; None if there
        is none (killed before it was written) or it was run for other settings (a resume
        may change quantify.holdout_runs); a damaged file is a one-line CampaignError."""
        path = self.directory / HOLDOUT_FILE
        if not path.exists():
            return None
        saved = read_json(path, required=("config_hash", "seed", "runs", "report"))
        if {key: saved[key] for key in ("config_hash", "seed", "runs")} != self._holdout_stamp():
            return None
        if not isinstance(saved["report"], dict) or saved["report"].get("runs") != saved["runs"]:
            raise CampaignError(f"{path}: report does not hold the holdout's {saved['runs']} runs (damaged?)")
        return saved["report"]

    def save(self) -> None:
        """A checkpoint now (farm/directory/checkpoint.py)."""
        checkpoint.save(self.campaign, self.ledger, self.journal, self.stamp)

    def _observer(self, progress: Progress, status: StatusWriter):
        """After every committed chunk: progress, status, and a checkpoint when one is due."""
        last_checkpoint = [time.monotonic()]
        seen_updates = [0]
        every = self.cfg.farm.checkpoint_every
        side = "" if self.side == "total" else f"{self.side} side: "

        def observe(campaign: Campaign) -> None:
            if self.memory.exceeded(self.algorithm.held):
                campaign.stop()
            if campaign.adversary is not None and len(campaign.adversary.history) > seen_updates[0]:
                seen_updates[0] = len(campaign.adversary.history)
                progress.line(f"{side}search: next round samples {campaign.adversary.policy.description}")
            progress.update(self.side, campaign)
            status.update(self.side, campaign)
            if time.monotonic() - last_checkpoint[0] >= every:
                self.save()
                last_checkpoint[0] = time.monotonic()

        return observe
