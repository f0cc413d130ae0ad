"""The in-process executor (coordinator/executor.py has the contract).

``LocalExecutor`` simulates in the coordinator's process when a result is asked for, so
a dropped batch costs nothing, and screens against the live coverage (always current).
Each batch is one chunk. The simulator runs in a thread of its own (farm/execution/waiting.py):
the coordinator's wait for it wakes for a stop within a fraction of a second, and gives
up on a chunk that overruns its time limit (derived from the measured run time as on
Ray, or farm.chunk_timeout) with the same one-line error as the Ray executor, naming the
user call it hangs in (a per-run simulator's reset, step or close). As on Ray, the first
run is simulated alone (the probe), timed under the first-run limit
(farm/execution/chunking.py); its result is joined to the rest of its batch's, the same
as if they had been simulated together (a run depends on its key only). A thread cannot
be cancelled, so there is no retry: the stuck thread stays until the process ends.
"""

from __future__ import annotations

import dataclasses
import threading
import time

import numpy as np

from coordinator.executor import Chunk, ChunkSummary, Executor, screen_piece
from coordinator.experience_replay import select
from farm.execution.chunking import ChunkSizer
from farm.execution.process import build_simulator, close_simulator
from farm.execution.waiting import InThread, culprit, name_runs
from scenarios.rollout import RunBatch
from scenarios.simulator import SimSpec


class LocalExecutor(Executor):
    """In-process, lazy: a batch is simulated when its result is first asked for."""

    name = "local"
    workers = 1

    def __init__(self, spec: SimSpec, check_step_bound: bool = False, chunk_timeout: float = 0.0,
                 stop: threading.Event | None = None):
        """``chunk_timeout``: seconds a batch may take (farm.chunk_timeout; 0: derived from
        the measured run time); ``stop``: set on SIGINT / SIGTERM, it ends the wait for a
        batch (``farm.execution.waiting.Interrupted``)."""
        self.spec = spec
        self.simulator = build_simulator(spec, check_step_bound)
        self.sizer = ChunkSizer(1, chunk_timeout)
        self._thread = InThread(stop)
        self._culprit = culprit(spec.scenario)
        self._jobs: dict[int, tuple] = {}
        self._next = 0

    @property
    def stop(self) -> threading.Event | None:
        return self._thread.stop

    @stop.setter
    def stop(self, event: threading.Event | None) -> None:
        self._thread.stop = event

    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None,
               indices: np.ndarray | None = None) -> list[int]:
        handle = self._next
        self._next += 1
        self._jobs[handle] = (first_index, starts, screen, actions, indices)
        return [handle]

    def result(self, handle: int) -> Chunk:
        first_index, starts, screen, actions, indices = self._jobs.pop(handle)
        probed = None
        if self.sizer.run_s is None and len(starts) > 1:
            probed = self._probe(first_index, starts, actions, indices)
        rest = slice(0 if probed is None else 1, None)  # the probe's run is not simulated again
        rest_indices = None if indices is None else indices[rest]

        def work():
            t0 = time.perf_counter()
            batch = self.simulator.simulate(first_index + rest.start, starts[rest], indices=rest_indices,
                                            actions=actions)
            done = ChunkSummary.of(batch if probed is None else RunBatch.joined([probed, batch]), screen)
            self.sizer.ran(len(starts) - rest.start, time.perf_counter() - t0)
            return done

        what = self._what(name_runs(self._culprit, first_index + rest.start, starts[rest], rest_indices))
        summary, visited = self._thread.run(work, self.sizer.limit(len(starts) - rest.start), what)
        return summary.chunk(lambda: visited, lambda rows, takes: _compact(visited, rows, takes))

    def _probe(self, first_index, starts, actions, indices) -> RunBatch:
        """The batch's first run alone, timed under the first-run limit: a simulator that
        hangs at once is named within it, and the rest of the batch gets a measured limit.
        The step bound is checked on the whole batch still."""
        index = None if indices is None else indices[:1]

        def work():
            t0 = time.perf_counter()
            batch = self.simulator.simulate(first_index, starts[:1], indices=index, actions=actions, rest_follows=True)
            self.sizer.ran(1, time.perf_counter() - t0)
            return batch

        return self._thread.run(work, self.sizer.limit(1), self._what(name_runs(self._culprit, first_index, starts[:1],
                                                                               indices)))

    def _what(self, runs: str):
        """What a wait that overran names: the user call the simulator hangs in, if it
        tells (a per-run simulator: ``PerRunBackend.where``), else the runs."""
        where = getattr(self.simulator.backend, "where", None)
        return lambda: (where() if where is not None else None) or runs

    def screen_stored(self, pieces, screen):
        runs = sum(len(p.indices) for p in pieces)

        def work():
            t0 = time.perf_counter()
            out = []
            for piece in pieces:
                if piece.source is None:
                    out.append(screen_piece(self.simulator, None, piece, screen))
                else:  # compacted when stored: its rows are 0..r-1
                    rows = np.arange(len(piece.rows))
                    out.append(screen_piece(self.simulator, piece.source, dataclasses.replace(piece, rows=rows),
                                            screen))
            self.sizer.replayed(runs, time.perf_counter() - t0)  # the next replay's limit follows it
            return out

        # a round end's replay finishes before a stop is taken (interruptible=False)
        return self._thread.run(work, self.sizer.replay_limit(runs),
                                self._what(f"{self._culprit}: experience replay of {runs} runs"), interruptible=False)

    def cancel(self, handle: int) -> None:
        self._jobs.pop(handle, None)

    def close(self) -> None:
        self._jobs.clear()
        close_simulator(self.simulator, self.sizer.chunk_timeout, self._thread)


def _compact(visited, rows, takes) -> tuple[np.ndarray, np.ndarray]:
    """Only the kept states of the kept runs (in-process, the chunk's arrays go away)."""
    states, _ = select(*visited, rows, takes)
    offsets = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(takes, out=offsets[1:])
    return states, offsets
