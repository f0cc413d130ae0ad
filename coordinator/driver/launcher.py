"""The driver's side of the executor: runs sent from the algorithm's current state and
fetched back, counted as simulated (the executor contract is coordinator/executor.py)."""

from __future__ import annotations

import numpy as np

from coordinator.algorithm import Algorithm
from coordinator.executor import Chunk, Executor
from coordinator.stable_sampler import Draws
from scenarios.streams import RunStreams


class Launcher:
    """Draws starts from each run's own stream at the algorithm's state as it is now,
    sends runs to the executor (screened against the coverage, with the action policy's
    adaptive state) and fetches their chunks (``counters`` gain the runs and steps)."""

    def __init__(self, algorithm: Algorithm, executor: Executor | None, seed: int, counters, adversary=None):
        self.algorithm = algorithm
        self.executor = executor
        self.seed = seed
        self.counters = counters
        self.adversary = adversary

    # -- draws ------------------------------------------------------------------------------
    def streams(self, indices) -> RunStreams:
        return RunStreams.of(self.seed, np.asarray(indices, dtype=np.uint64))

    def draw(self, indices) -> Draws:
        """What runs ``indices``' streams draw now."""
        return self.algorithm.draw(self.streams(indices))

    def starts(self, ids: np.ndarray) -> np.ndarray:
        """The start states of vertex ids ``ids`` now."""
        return self.algorithm.vertices.points[ids]

    # -- the executor -------------------------------------------------------------------------
    def actions(self) -> dict | None:
        return self.adversary.policy.state() if self.adversary is not None else None

    def submit(self, first_index: int, starts: np.ndarray, indices: np.ndarray | None = None) -> list:
        return self.executor.submit(first_index, starts, self.algorithm.coverage, actions=self.actions(),
                                    indices=indices)

    def fetch(self, handle) -> Chunk:
        """Wait for one chunk; it counts as simulated."""
        chunk = self.executor.result(handle)
        self.counters.runs_simulated += len(chunk)
        self.counters.steps_simulated += chunk.steps
        return chunk

    def ready(self, handle) -> bool:
        return self.executor.ready(handle)

    @property
    def concurrent(self) -> bool:
        return self.executor.concurrent

    def cancel(self, handle) -> None:
        self.executor.cancel(handle)

    @property
    def workers(self) -> int:
        return self.executor.workers

    def run_seconds(self) -> float | None:
        return self.executor.run_seconds()
