"""One campaign over one set of failure facets, in its directory: the configured facets
("total", in the campaign directory) or one side's (fleet3's "lead" and "rear", in
``DIR/sides/<label>``). It owns its algorithm, its ledger and its checkpoint; its
executor lives while it runs.
"""

from __future__ import annotations

import gc
import time
from pathlib import Path

from coordinator.campaign import Campaign
from farm.directory import checkpoint
from farm.jobs.campaign_setup import build_algorithm, build_campaign, spec_of
from farm.config import Config, config_hash
from farm.execution.factory import make_executor
from farm.directory.journal import Journal
from farm.execution.memory import release_freed_memory
from farm.reports.progress import Progress
from farm.jobs.signals import stop_on_signals
from farm.execution.process import build_simulator
from farm.reports.status import StatusWriter
from farm.directory.storage import CampaignError, Ledger
from farm.execution.waiting import Interrupted


class Stopped(Exception):
    """The campaign was stopped by a signal; it is checkpointed and can be resumed."""


class FacetCampaign:
    def __init__(self, cfg: Config, label: str, directory: Path, failure_facets: list | None):
        """Builds (and so checks) the scenario, back end, actions and algorithm now."""
        self.cfg, self.label, self.directory = cfg, label, Path(directory)
        self.spec = spec_of(cfg, failure_facets)
        self.simulator = build_simulator(self.spec)
        self.scenario, self.policy = self.simulator.scenario, self.simulator.policy
        self.algorithm = build_algorithm(cfg, self.simulator)
        self.ledger = Ledger(self.directory / "ledger", self.scenario.state_names)
        self.journal = Journal(self.directory)
        self.config_hash = config_hash(cfg)
        self.campaign: Campaign | None = None
        self.startup_s = 0.0
        self.virtual = None  # the virtual farm's VirtualClock (farm/execution/virtual.py)
        self._restored: checkpoint.Restored | None = None

    def restore(self) -> None:
        """Load and check this campaign's checkpoint, if it has one (nothing is written)."""
        if self.journal.exists():
            self._restored = checkpoint.restore(self)
        elif any((self.directory / "ledger").glob("segment-*.parquet")):
            raise CampaignError(f"{self.directory}: ledger segments exist but checkpoint.npz is missing; refusing "
                                f"to restart the campaign from scratch over them")

    def run(self, progress: Progress, status: StatusWriter) -> Campaign:
        """Run to the end (a finished campaign read back runs nothing), checkpointing every
        ``farm.checkpoint_every`` seconds; raises Stopped after a signal (checkpointed)."""
        restored = self._restored
        if restored is not None and restored.driver.counters.done:
            self.campaign = build_campaign(self.cfg, self.algorithm, self.simulator, None, restored=restored)
            return self.campaign
        farm_cfg = self.cfg.farm
        self.directory.mkdir(parents=True, exist_ok=True)
        stop = stop_on_signals()
        # the handlers cover start-up too: a signal while Ray starts (seconds) is taken
        # once it has started, not in the middle of ray.init (which can crash on it)
        with stop:
            t0 = time.monotonic()
            executor = make_executor(farm_cfg, self.spec, check_step_bound=self.cfg.quantify.boundary,
                                     stop=stop.event)
            self.startup_s = time.monotonic() - t0
            if farm_cfg.executor == "ray":
                executor.notify = progress.line
                self._say_ray_is_up(executor, progress)
            observers = [self._observer(progress, status)]
            self.campaign = build_campaign(self.cfg, self.algorithm, self.simulator, executor, observers, restored)
            stop.campaign = self.campaign
            try:
                self.campaign.run()
            except Interrupted:
                pass  # a wait for a chunk woke for the stop: the campaign is as after its last commit
            finally:
                executor.close()
            if farm_cfg.executor == "virtual":
                self.virtual = executor.report()
        done = self.campaign.counters.done
        if done:
            self.algorithm.stop_committing()  # the last checkpoint is then gathered with less held
        checkpoint.save(self)
        if not done:
            status.update(self.label, self.campaign, state="stopped", force=True)
            raise Stopped(f"stopped at {self.campaign.counters.committed} committed runs")
        self.algorithm.release()
        gc.collect()  # what reference cycles still hold of the released state, before the heap is trimmed
        release_freed_memory()
        return self.campaign

    def _say_ray_is_up(self, executor, progress: Progress) -> None:
        farm_cfg = self.cfg.farm
        progress.line(f"Ray ({farm_cfg.address}) up with {farm_cfg.workers} workers in {self.startup_s:.1f} s")
        if farm_cfg.counting == "sequential":
            return  # the batch follows the workers (a result-neutral setting then)
        busy = executor.busy_at_most(farm_cfg.batch_size)
        if busy < farm_cfg.workers:  # deferred counting: the window is result-relevant, so said, not changed
            progress.line(f"note: {farm_cfg.batch_size} x {farm_cfg.pipeline_depth} runs in flight "
                          f"(farm.batch_size x farm.pipeline_depth) keep at most {busy} of the "
                          f"{farm_cfg.workers} workers busy; raise them for more (it costs runs: README, "
                          f"'Many workers', and docs/window.md)")

    def _observer(self, progress: Progress, status: StatusWriter):
        """After every committed chunk: progress, status, and a checkpoint when one is due."""
        last_checkpoint = [time.monotonic()]
        seen_updates = [0]
        every = self.cfg.farm.checkpoint_every
        side = "" if self.label == "total" else f"{self.label} side: "

        def observe(campaign: Campaign) -> None:
            if campaign.adversary is not None and len(campaign.adversary.history) > seen_updates[0]:
                seen_updates[0] = len(campaign.adversary.history)
                progress.line(f"{side}search: next round samples {campaign.adversary.policy.description}")
            progress.update(self.label, campaign)
            status.update(self.label, campaign)
            if time.monotonic() - last_checkpoint[0] >= every:
                checkpoint.save(self)
                last_checkpoint[0] = time.monotonic()

        return observe
