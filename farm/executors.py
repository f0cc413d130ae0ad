"""The in-process executor (coordinator/executor.py has the contract).

``LocalExecutor`` simulates in the coordinator's process when a result is asked for, so
a dropped batch costs nothing, and screens against the live coverage (always current).
Each batch is one chunk.
"""

from __future__ import annotations

import numpy as np

from coordinator.executor import Chunk, chunk_of, summarize
from farm.memory import keep_freed_memory
from scenarios.simulator import SimSpec, Simulator


def build_simulator(spec: SimSpec, check_step_bound: bool = False) -> Simulator:
    keep_freed_memory()  # this process simulates batches from now on
    return Simulator(spec, check_step_bound)


class LocalExecutor:
    """In-process, lazy: a batch is simulated when its result is first asked for."""

    name = "local"
    workers = 1

    def __init__(self, spec: SimSpec, check_step_bound: bool = False):
        self.spec = spec
        self.simulator = build_simulator(spec, check_step_bound)
        self._jobs: dict[int, tuple[int, np.ndarray, object]] = {}
        self._next = 0

    def submit(self, first_index: int, starts: np.ndarray, screen=None) -> list[int]:
        handle = self._next
        self._next += 1
        self._jobs[handle] = (first_index, starts, screen)
        return [handle]

    def result(self, handle: int) -> Chunk:
        first_index, starts, screen = self._jobs.pop(handle)
        batch = self.simulator.simulate(first_index, starts)
        summary, visited = summarize(batch, screen)
        return chunk_of(summary, lambda: visited)

    def cancel(self, handle: int) -> None:
        self._jobs.pop(handle, None)

    def close(self) -> None:
        self._jobs.clear()
