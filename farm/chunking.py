"""How big a chunk is and how long it may take: from the run time and the Ray call cost
the executor measures (shared/spec/scaling.md, "Chunking and the virtual farm").

A chunk is the runs one worker simulates in one call. Its size follows the simulator:

- every worker gets a share of every batch (``ceil(runs / workers)`` runs at most), so
  the ``pipeline_depth`` batches in flight keep each worker ``pipeline_depth`` chunks deep
  and none idles when the oldest batch is committed;
- a chunk holds at most ``CHUNK_S`` seconds of simulation, so that a round end (whose
  dropped chunks still run to their end on their workers) or a stop waits about that long;
- but at least ``workers * t_call / (DRIVER_SHARE * t_run)`` runs (scaling.md's
  ``c ~ 4 W t_call / t_run``): with every worker busy, the driver spends at most about a
  quarter of its time on Ray calls; past that, chunks grow (and fewer workers are busy)
  rather than the driver falling behind all of them.

``t_run`` is a worker's busy time per run, ``t_call`` the driver's time per chunk (its
call and the read of its result), both smoothed over the latest chunks. How a batch is
cut never changes a result: runs are committed in index order and re-screened.

The time limit of a chunk is ``LIMIT_FACTOR`` times its expected time plus
``LIMIT_FLOOR_S`` (``farm.chunk_timeout`` replaces it), counted from when its worker
starts it; before any chunk has come back nothing is measured, and the limit is
``UNMEASURED_LIMIT_S``.
"""

from __future__ import annotations

import math

CHUNK_S = 1.0  # [s] of simulation a chunk holds at most (unless the driver cannot afford smaller)
DRIVER_SHARE = 0.25  # of the driver's time on Ray calls, every worker busy
CALL_S = 1e-3  # [s] the driver's time per chunk until it is measured
DECAY = 0.8  # weight of the older chunks in the smoothed run and call times, per chunk
LIMIT_FACTOR = 10.0  # a chunk may take this many times its expected time ...
LIMIT_FLOOR_S = 5.0  # [s] ... plus this (a loaded machine, a garbage collection)
UNMEASURED_LIMIT_S = 600.0  # [s] a chunk's limit before any chunk has come back


class ChunkSizer:
    """The measured run and call times of one executor, and what follows from them."""

    def __init__(self, workers: int, chunk_timeout: float = 0.0):
        """``chunk_timeout``: a fixed limit per chunk in seconds (farm.chunk_timeout); 0: derived."""
        self.workers = max(1, int(workers))
        self.chunk_timeout = float(chunk_timeout)
        self._busy = self._runs = 0.0  # decayed sums: t_run = busy / runs
        self._call = self._calls = 0.0  # decayed sums: t_call = call / calls

    # -- measurements ----------------------------------------------------------------------
    def ran(self, runs: int, busy_s: float) -> None:
        """A worker spent ``busy_s`` seconds on a chunk of ``runs`` runs."""
        if runs > 0 and busy_s >= 0:
            self._busy = DECAY * self._busy + busy_s
            self._runs = DECAY * self._runs + runs

    def called(self, seconds: float) -> None:
        """The driver spent ``seconds`` on one chunk's call and result."""
        if seconds >= 0:
            self._call = DECAY * self._call + seconds
            self._calls = DECAY * self._calls + 1

    @property
    def run_s(self) -> float | None:
        """A worker's seconds per run (None until a chunk has come back)."""
        return self._busy / self._runs if self._runs else None

    @property
    def call_s(self) -> float:
        """The driver's seconds per chunk."""
        return self._call / self._calls if self._calls else CALL_S

    # -- what follows ----------------------------------------------------------------------
    def size(self, runs: int) -> int:
        """Runs per chunk for a batch of ``runs`` runs (1 up to ``runs``)."""
        if runs <= 1:
            return 1
        run_s = self.run_s
        share = math.ceil(runs / self.workers)
        if run_s is None:
            return share
        run_s = max(run_s, 1e-9)
        by_time = max(1, math.floor(CHUNK_S / run_s))
        afford = math.ceil(self.workers * self.call_s / (DRIVER_SHARE * run_s))
        return min(runs, max(1, min(share, by_time), afford))

    def chunks(self, runs: int) -> int:
        """The chunks a batch of ``runs`` runs is cut into."""
        return max(1, math.ceil(runs / self.size(runs)))

    def busy_at_most(self, batch_size: int, pipeline_depth: int) -> int:
        """Workers that ``pipeline_depth`` batches of ``batch_size`` runs can keep busy."""
        return min(self.workers, pipeline_depth * self.chunks(batch_size))

    def limit(self, runs: int) -> float:
        """[s] the time a chunk of ``runs`` runs may take once its worker has started it."""
        if self.chunk_timeout > 0:
            return self.chunk_timeout
        if self.run_s is None:
            return UNMEASURED_LIMIT_S
        return LIMIT_FLOOR_S + LIMIT_FACTOR * runs * self.run_s
