"""The executor contract: where batches of runs are simulated and screened.

    submit(first_index, starts, screen) -> handles   simulate runs first_index.. from
                                                     ``starts``; one handle per chunk, in
                                                     index order (how a batch is cut
                                                     into chunks is the executor's
                                                     business: results never depend on it)
    result(handle) -> Chunk                          wait for one chunk
    cancel(handle)                                   drop a chunk (it is not committed)
    close()

``screen`` is what the runs are screened against on the worker: a
``coordinator.coverage.Coverage`` (quantification: the executor keeps a mirror of it on
each worker, in sync through its change log) or a fixed screen such as validation's
domain check; None for no screening. A ``Chunk`` carries only what the coordinator
needs per run; the visited states come on demand (``visited()``): a remote executor
leaves them where they were simulated until then.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

import numpy as np

from scenarios.base import FAILURE, TRUNCATED
from scenarios.rollout import RunBatch


@dataclass
class Chunk:
    first_index: int
    lengths: np.ndarray  # (k,) states per run, start included
    outcomes: np.ndarray  # (k,) FAILURE / TRUNCATED / HORIZON
    last: np.ndarray  # (k, n) terminal states
    screening: Any  # what the screen returned for these runs (None: not screened)
    fetch_visited: Callable[[], tuple[np.ndarray, np.ndarray]] = field(repr=False)
    _visited: tuple | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.lengths)

    @property
    def steps(self) -> int:
        return int(self.lengths.sum() - len(self.lengths))

    def visited(self) -> tuple[np.ndarray, np.ndarray]:
        """(S, n) visited states and (k + 1,) offsets (see RunBatch.visited)."""
        if self._visited is None:
            self._visited = self.fetch_visited()
        return self._visited

    def trajectory(self, row: int, start: np.ndarray) -> np.ndarray:
        """(length, n) every state of run ``row``: its start, its visited states and
        its terminal state if that left Sigma."""
        states, offsets = self.visited()
        parts = [start[None, :], states[offsets[row] : offsets[row + 1]]]
        if self.outcomes[row] in (FAILURE, TRUNCATED):
            parts.append(self.last[row][None, :])
        return np.concatenate(parts)


class Executor(Protocol):
    workers: int

    def submit(self, first_index: int, starts: np.ndarray, screen=None) -> list: ...

    def result(self, handle) -> Chunk: ...

    def cancel(self, handle) -> None: ...

    def close(self) -> None: ...


def summarize(batch: RunBatch, screen) -> tuple[dict, tuple[np.ndarray, np.ndarray]]:
    """What a worker sends back for a simulated batch: a small per-run summary (with the
    screen's verdicts) and, separately, the visited states."""
    states, offsets = batch.visited()
    screening = None if screen is None else screen.screen(states, offsets, batch.outcomes)
    summary = {"first_index": int(batch.indices[0]) if len(batch) else 0, "lengths": batch.lengths,
               "outcomes": batch.outcomes, "last": batch.last_states(), "screening": screening}
    return summary, (states, offsets)


def chunk_of(summary: dict, fetch_visited: Callable) -> Chunk:
    return Chunk(summary["first_index"], summary["lengths"], summary["outcomes"], summary["last"],
                 summary["screening"], fetch_visited)
