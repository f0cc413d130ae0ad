"""The driver of a margin-refinement campaign: waves of runs from box centres, then the
certification of the set (coordinator/margin/refinement.py says what the waves are).

A deterministic system needs none of coupled counting: every run is decided by its
start, so a wave's runs are drawn all at once (their centres, sample indices in wave
order), sent to the executor in batches, and told to the algorithm in index order as
their chunks come back. The next wave is a function of every result before it, so the
campaign is the same on any number of workers, and a resumed one simulates again
exactly the runs of the wave it stopped in. The driver has the farm's interface of
``coordinator.driver.Campaign`` (counters, checkpoint state, ledger rows, recordings).
"""

from __future__ import annotations

import time
from typing import Iterable

import numpy as np

from coordinator.driver.commit_log import CommitLog
from coordinator.driver.recordings import Recordings
from coordinator.driver.settings import CampaignSettings
from coordinator.driver.state import Counters, DriverState
from coordinator.executor import Chunk, Executor
from coordinator.margin.refinement import MarginRefinement


class RefinementCampaign:
    adversary = None  # one adversarial action: no search

    def __init__(self, algorithm: MarginRefinement, executor: Executor | None, settings: CampaignSettings,
                 observers: Iterable = (), restored: DriverState | None = None):
        self.algorithm = algorithm
        self.executor = executor
        self.settings = settings
        self.observers = list(observers)
        self.counters = restored.counters if restored is not None else Counters()
        self.final_distribution = restored.final_distribution if restored is not None else ""
        self.log = CommitLog()
        self.recordings = Recordings(settings.record_limit, self.counters)
        self.certify = settings.certify
        self._stop = False

    @property
    def n_eps(self) -> int:
        return self.settings.n_eps

    def quiet_needed(self) -> int:
        """The runs of the current wave (what progress counts toward)."""
        return max(len(self.algorithm.wave), 1)

    def stop(self) -> None:
        self._stop = True

    @property
    def stopping(self) -> bool:
        return self._stop

    # -- the loop -----------------------------------------------------------------------------
    def run(self) -> Counters:
        c, algo = self.counters, self.algorithm
        started = time.monotonic() - c.elapsed_s
        while not c.done and not self._stop:
            if algo.wave_done < len(algo.wave):
                self._run_wave()
            elif not algo.finished:
                rounds = algo.round
                algo.next_wave()
                algo.wave_first, algo.wave_done = c.committed, 0
                c.quiet = 0
                if algo.round > rounds or algo.finished:
                    c.round_ends.append(c.committed)
                    c.rounds_completed = algo.round + int(algo.finished)
            else:
                self._certify()
                c.converged = c.done = True
                self.final_distribution = algo.sampling_description()
            c.elapsed_s = time.monotonic() - started
            self._observe()
        c.elapsed_s = time.monotonic() - started
        return c

    def _run_wave(self) -> None:
        """Send the rest of the wave, commit its chunks in index order (a stop lands
        between chunks: what is committed is in the algorithm, the rest is sent again)."""
        algo, s = self.algorithm, self.settings
        boxes = algo.wave[algo.wave_done :]
        first = algo.wave_first + algo.wave_done
        starts = algo.starts(boxes)
        batch = self.executor.batch_size(s.batch_size)
        handles = []
        for lo in range(0, len(boxes), batch):
            handles += self.executor.submit(first + lo, starts[lo : lo + batch])
        taken = 0
        try:
            for handle in handles:
                chunk = self.executor.result(handle)
                taken += 1
                self._commit(boxes, starts, first, chunk)
                if self._stop:
                    break
        finally:
            for handle in handles[taken:]:
                self.executor.cancel(handle)

    def _commit(self, boxes: np.ndarray, starts: np.ndarray, first: int, chunk: Chunk) -> None:
        algo, c = self.algorithm, self.counters
        at = chunk.first_index - first
        rows = np.arange(len(chunk))
        these = boxes[at : at + len(chunk)]
        algo.tell(these, chunk.indices, chunk, rows)
        algo.wave_done += len(chunk)
        c.committed += len(chunk)
        c.quiet = algo.wave_done
        c.runs_simulated += len(chunk)
        c.steps_simulated += chunk.steps
        failed = np.flatnonzero(algo.failed[these])
        for row in failed[: max(self.settings.record_limit - c.recorded, 0)]:
            self.recordings.offer(chunk, int(row), int(chunk.indices[row]), starts[at + row])
        zeros = np.zeros(len(chunk), dtype=bool)
        self.log.add(chunk.first_index, starts[at : at + len(chunk)], chunk, rows, algo.round, algo.delta, zeros,
                     zeros)
        self._observe()

    def _certify(self) -> None:
        """Runs of safe boxes whose states are not held (a resumed campaign) run again,
        then the set is certified (coordinator/margin/invariance.py)."""
        algo = self.algorithm
        missing = algo.missing_visits()
        if len(missing):
            starts = algo.starts(missing)
            handles = self.executor.submit(0, starts, indices=algo.index[missing])
            at = 0
            for handle in handles:
                chunk = self.executor.result(handle)
                part = missing[at : at + len(chunk)]
                algo.remember(part, chunk)
                at += len(chunk)
        algo.certify()

    def _observe(self) -> None:
        for observe in self.observers:
            observe(self)

    # -- persistence --------------------------------------------------------------------------
    def committed_algorithm(self) -> MarginRefinement:
        return self.algorithm

    def take_recordings(self) -> list[dict]:
        return self.recordings.take()

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        state = DriverState(self.counters, [], [], self.final_distribution)
        return state.write(self.algorithm.scenario.n)
