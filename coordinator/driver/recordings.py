"""The trajectories of committed state-changing failures, kept for the campaign's MCAP
recording (the runs worth looking at), up to a limit per campaign."""

from __future__ import annotations

import numpy as np

from coordinator.executor import Chunk
from scenarios.base import FAILURE, OUTCOME_NAMES


class Recordings:
    def __init__(self, limit: int, counters):
        self.limit = limit
        self.counters = counters  # ``recorded``: runs kept so far (a checkpoint keeps it)
        self.runs: list[dict] = []  # since the last take

    def offer(self, chunk: Chunk, row: int, index: int, start: np.ndarray) -> None:
        """Run ``row`` of ``chunk`` (sample index ``index``) changed the state: kept if it failed."""
        c = self.counters
        if c.recorded >= self.limit or chunk.outcomes[row] != FAILURE:
            return
        self.runs.append({"sample_index": index, "trajectory": chunk.trajectory(row, start),
                          "outcome": OUTCOME_NAMES[int(chunk.outcomes[row])]})
        c.recorded += 1

    def forget_from(self, index: int) -> None:
        """Commits from sample index ``index`` on were undone."""
        self.runs = [r for r in self.runs if r["sample_index"] < index]

    def take(self, until: int | None = None) -> list[dict]:
        """The runs kept since the last take, before sample index ``until`` (None: all)."""
        if until is None:
            taken, self.runs = self.runs, []
            return taken
        taken = [r for r in self.runs if r["sample_index"] < until]
        self.runs = [r for r in self.runs if r["sample_index"] >= until]
        return taken
