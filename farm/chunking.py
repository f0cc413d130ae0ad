"""How a batch is cut into chunks for workers (shared/spec/scaling.md, "Chunking").

A chunk is one call: the coordinator pays for sending and reading it, a worker for
taking it. The size follows the simulator's run time ``run_time`` and the call's cost
``call_cost``:

- enough chunks to keep every worker busy from the batches in flight: at most
  ``batch * pipeline_depth / workers`` runs a chunk;
- few enough calls for the coordinator: at least ``4 * workers * call_cost / run_time``
  runs a chunk (the coordinator then spends at most a quarter of its time on calls);
- a chunk takes at most about ``MAX_CHUNK_S`` of simulation, so that a round end or a stop
  does not wait long for it (the coordinator's floor wins over it).

Chunking never changes a result: runs are committed in index order and re-screened.
"""

from __future__ import annotations

import numpy as np

MAX_CHUNK_S = 1.5  # [s] of simulation a chunk takes at most (unless the coordinator's floor says more)
DRIVER_SHARE = 4  # the coordinator spends at most 1 / DRIVER_SHARE of its time on calls


def chunk_size(batch: int, workers: int, pipeline_depth: int, run_time: float, call_cost: float) -> int:
    """Runs per chunk for batches of ``batch`` runs (``run_time``: seconds a run takes)."""
    busy = -(-batch * pipeline_depth // max(workers, 1))
    if run_time <= 0:
        return max(1, busy)
    driver = int(np.ceil(DRIVER_SHARE * workers * call_cost / run_time))
    short = max(1, int(MAX_CHUNK_S / run_time))
    return int(max(1, driver, min(busy, short)))


def chunk_rows(n: int, workers: int, pipeline_depth: int, run_time: float, call_cost: float,
               urgent: bool = False) -> list[np.ndarray]:
    """The rows of a batch of ``n`` runs, cut into chunks of about equal size. ``urgent``
    (replacements: the head may be waiting for them): one wave over the workers, however
    small the chunks."""
    if n == 0:
        return []
    size = -(-n // max(workers, 1)) if urgent else chunk_size(n, workers, pipeline_depth, run_time, call_cost)
    return np.array_split(np.arange(n), -(-n // size))
