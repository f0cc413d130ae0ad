"""The estimate's runs: stages of stratified runs on executors, committed in index order.

Stage t's runs take the sample indices after stage t - 1's, grouped by stratum (its
allocation, coordinator/estimation/allocation.py, decided from the earlier stages'
outcomes only). Run i's start is drawn from D restricted to its stratum with the
stream (seed, i); its actions and disturbance come from the same key on the worker. So
every run, and every allocation, is a function of (seed, committed outcomes): the
estimate is the same on any number of workers and after a resume, and a second
controller given the same seed meets the very same starts and streams (common random
numbers). Batches of a stage are pipelined; a stage's end is a barrier (the next
allocation needs all its outcomes). The stopping rule is checked at stage ends.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np

from coordinator.estimation.allocation import allocate, smallest_stage, stage_size
from coordinator.estimation.strata import Strata
from coordinator.estimation.tally import Tally
from scenarios.base import FAILURE
from scenarios.streams import PURPOSE_START, RunStreams

MIN_STAGES_FOR_PRECISION = 2  # the relative-error rule trusts no interval from the pilot alone


@dataclass(frozen=True)
class EstimateSettings:
    """``runs``: the budget; ``relative_error``: stop at the first stage end (after the
    pilot's successor) where half-width <= relative_error x estimate (None: run the
    budget); ``confidence`` of the interval; ``pilot``: the first stage's runs;
    ``batch_size`` and ``pipeline_depth``: runs per submitted batch, batches in flight
    (they change no result)."""

    runs: int
    relative_error: float | None
    confidence: float
    pilot: int
    batch_size: int = 1024
    pipeline_depth: int = 2


@dataclass(frozen=True)
class CommittedBatch:
    """Runs ``first_index ..`` of stage ``stage`` as committed: their strata (k,),
    starts (k, n), and per controller their outcomes and steps (k,)."""

    first_index: int
    stage: int
    strata: np.ndarray
    starts: np.ndarray
    outcomes: tuple[np.ndarray, ...]
    steps: tuple[np.ndarray, ...]

    @property
    def indices(self) -> np.ndarray:
        return np.arange(self.first_index, self.first_index + len(self.strata), dtype=np.int64)


def draw_starts(strata: Strata, seed: int, first_index: int, run_strata: np.ndarray) -> np.ndarray:
    """(k, n) starts of runs ``first_index ..`` in ``run_strata``, each from its own stream."""
    streams = RunStreams.of(seed, np.arange(first_index, first_index + len(run_strata), dtype=np.uint64))
    return strata.draw(run_strata, streams.uniform(0, PURPOSE_START, len(strata.edges) + 1))


class StageRun:
    """An estimate's runs on ``executors`` (one per controller: the one under test, then
    the second of a paired comparison), resumed from ``tally`` if given. ``actions``:
    the action policy's state every chunk is simulated with (the search mixture's final
    weights), or None. Observers see every committed batch: ``observer(run, batch)``."""

    def __init__(self, strata: Strata, settings: EstimateSettings, seed: int, executors: list,
                 tally: Tally | None = None, actions: dict | None = None,
                 observers: Iterable[Callable] = ()):
        self.strata, self.settings, self.seed = strata, settings, seed
        self.executors = list(executors)
        self.tally = tally or Tally(len(strata), paired=len(self.executors) == 2)
        self.actions = actions
        self.observers = list(observers)
        self.stopped_by: str | None = None
        self._stop = False

    # -- progress --------------------------------------------------------------------------
    @property
    def committed(self) -> int:
        return self.tally.committed

    def rate(self, versus: bool = False):
        return self.tally.rate(self.strata.masses, self.settings.confidence, versus)

    def stop(self) -> None:
        """Stop after the batch being committed (a signal): the tally is as committed."""
        self._stop = True

    # -- the stages --------------------------------------------------------------------------
    def finished(self) -> str | None:
        """Why the estimate is over at a stage end ("relative error", "runs"), or None."""
        s, tally = self.settings, self.tally
        if s.relative_error is not None and tally.stages >= MIN_STAGES_FOR_PRECISION:
            rate = self.rate()
            if tally.failures.sum() > 0 and rate.half_width <= s.relative_error * rate.estimate:
                return "relative error"
        if s.runs - tally.committed < smallest_stage(len(self.strata)):
            return "runs"
        return None

    def _begin_stage(self) -> None:
        t = self.tally.stages
        size = min(stage_size(t, max(self.settings.pilot, smallest_stage(len(self.strata)))),
                   self.settings.runs - self.tally.committed)
        self.tally.begin(allocate(size, self.strata.masses, None if t == 0 else self.tally.sigmas()))

    def _stage_strata(self, first: int, count: int) -> np.ndarray:
        """The strata of runs ``first .. first + count`` of the current stage."""
        tally = self.tally
        base = tally.planned_total - int(tally.planned[-1].sum())
        bounds = np.cumsum(tally.planned[-1])
        return np.searchsorted(bounds, np.arange(first, first + count) - base, side="right").astype(np.int64)

    def run(self) -> Tally:
        """Run stages until the stopping rule, the budget or ``stop()``; -> the tally."""
        pending: deque = deque()
        try:
            while not self._stop:
                if self.tally.stages == 0 or self.tally.stage_complete():
                    self.stopped_by = self.finished() if self.tally.stages else None
                    if self.stopped_by:
                        break
                    self._begin_stage()
                self._fill(pending)
                self._commit(pending.popleft())
        finally:
            for _, _, _, handles in pending:
                for executor, chunk_handles in zip(self.executors, handles):
                    for handle in chunk_handles:
                        executor.cancel(handle)
        return self.tally

    def _fill(self, pending: deque) -> None:
        """Submit batches of the current stage up to the pipeline depth."""
        end = self.tally.planned_total
        batch = max(1, self.executors[0].batch_size(self.settings.batch_size))
        nxt = pending[-1][0] + len(pending[-1][1]) if pending else self.tally.committed
        while len(pending) < self.settings.pipeline_depth and nxt < end:
            count = min(batch, end - nxt)
            run_strata = self._stage_strata(nxt, count)
            starts = draw_starts(self.strata, self.seed, nxt, run_strata)
            handles = [deque(ex.submit(nxt, starts, None, self.actions)) for ex in self.executors]
            pending.append((nxt, run_strata, starts, handles))
            nxt += count

    def _commit(self, item) -> None:
        first, run_strata, starts, handles = item
        outcomes, steps = [], []
        for executor, chunk_handles in zip(self.executors, handles):
            chunks = []
            while chunk_handles:
                chunks.append(executor.result(chunk_handles[0]))
                chunk_handles.popleft()
            outcomes.append(np.concatenate([c.outcomes for c in chunks]))
            steps.append(np.concatenate([c.lengths for c in chunks]) - 1)
        failed = [o == FAILURE for o in outcomes]
        self.tally.add(run_strata, failed[0], failed[1] if len(failed) > 1 else None)
        batch = CommittedBatch(first, self.tally.stages - 1, run_strata, starts, tuple(outcomes), tuple(steps))
        for observer in self.observers:
            observer(self, batch)


_ESTIMATE_TAG = 0x6573_7469_6D61_7465  # "estimate": the estimate's streams are not the campaign's


def estimate_seed(campaign_seed: int) -> int:
    """The default seed of a campaign's estimates: derived from its seed, so that the runs
    the set was built from and the runs that estimate a rate beside it share no stream."""
    from scenarios.streams import mix64

    with np.errstate(over="ignore"):
        mixed = mix64(np.array([campaign_seed], dtype=np.uint64) ^ np.uint64(_ESTIMATE_TAG))
    return int(mixed[0] >> np.uint64(1))
