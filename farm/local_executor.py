"""The in-process executor (coordinator/executor.py has the contract).

``LocalExecutor`` simulates in the coordinator's process when a result is asked for, so
a dropped batch costs nothing, and screens against the live coverage (always current).
Each batch is one chunk.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from coordinator.executor import Chunk, Executor, chunk_of, screen_piece, summarize
from coordinator.experience_replay import select
from farm.simulators import build_simulator
from scenarios.simulator import SimSpec


class LocalExecutor(Executor):
    """In-process, lazy: a batch is simulated when its result is first asked for."""

    name = "local"
    workers = 1

    def __init__(self, spec: SimSpec, check_step_bound: bool = False):
        self.spec = spec
        self.simulator = build_simulator(spec, check_step_bound)
        self._jobs: dict[int, tuple[int, np.ndarray, object]] = {}
        self._next = 0

    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None) -> list[int]:
        handle = self._next
        self._next += 1
        self._jobs[handle] = (first_index, starts, screen, actions)
        return [handle]

    def result(self, handle: int) -> Chunk:
        first_index, starts, screen, actions = self._jobs.pop(handle)
        batch = self.simulator.simulate(first_index, starts, actions=actions)
        summary, visited = summarize(batch, screen)
        return chunk_of(summary, lambda: visited, lambda rows, takes: _compact(visited, rows, takes))

    def screen_stored(self, pieces, screen):
        out = []
        for piece in pieces:
            if piece.source is None:
                out.append(screen_piece(self.simulator, None, piece, screen))
            else:  # compacted when stored: its rows are 0..r-1
                rows = np.arange(len(piece.rows))
                out.append(screen_piece(self.simulator, piece.source, dataclasses.replace(piece, rows=rows), screen))
        return out

    def cancel(self, handle: int) -> None:
        self._jobs.pop(handle, None)

    def close(self) -> None:
        self._jobs.clear()


def _compact(visited, rows, takes) -> tuple[np.ndarray, np.ndarray]:
    """Only the kept states of the kept runs (in-process, the chunk's arrays go away)."""
    states, _ = select(*visited, rows, takes)
    offsets = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(takes, out=offsets[1:])
    return states, offsets
