"""What the algorithms need from a batch of runs: the visited states, flattened."""

from __future__ import annotations

import numpy as np

from scenarios.base import FAILURE, TRUNCATED
from scenarios.run import RunBatch


def visited_states(batch: RunBatch, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """States after the start that lie inside Sigma, of the runs ``rows``, in run then
    time order: (S, n) states and (S,) position of their run within ``rows``.

    A run's terminal state is left out when the run failed or was truncated: it is
    outside Sigma (a failure is handled on its own; a truncation ends the run quietly).
    """
    lengths = batch.lengths[rows].astype(np.int64)
    ends = lengths - np.isin(batch.outcomes[rows], (FAILURE, TRUNCATED))
    counts = np.maximum(ends - 1, 0)
    total = int(counts.sum())
    if total == 0:
        return np.empty((0, batch.trajectories.shape[2])), np.empty(0, dtype=np.int64)
    run_pos = np.repeat(np.arange(len(rows)), counts)
    offsets = np.cumsum(counts) - counts
    t = np.arange(total) - np.repeat(offsets, counts) + 1
    return batch.trajectories[t, rows[run_pos]], run_pos


def first_true_per_run(flags: np.ndarray, run_pos: np.ndarray, runs: int) -> np.ndarray:
    """(runs,) bool: does run r have any flagged state?"""
    out = np.zeros(runs, dtype=bool)
    out[run_pos[flags]] = True
    return out
