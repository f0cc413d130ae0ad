"""The executor contract: where batches of runs are simulated and screened.

    submit(first_index, starts, screen, actions, indices) -> handles   simulate runs
                                                     first_index.. (or the given sample
                                                     ``indices``: replacements) from
                                                     ``starts``; one handle per chunk, in
                                                     index order (how a batch is cut
                                                     into chunks is the executor's
                                                     business: results never depend on it);
                                                     ``actions``: the action policy's adaptive
                                                     state (``ActionPolicy.state()``) for these
                                                     runs, or None; ``indices``: (k,) int64
                                                     sample indices of the runs instead of
                                                     first_index, first_index + 1, ...
                                                     (replacement runs), or None
    result(handle) -> Chunk                          wait for one chunk
    ready(handle) -> bool                            would result() return without waiting
    cancel(handle)                                   drop a chunk (it is not committed)
    screen_stored(pieces, coverage) -> [(states, run)]   experience replay: for each stored
                                                     piece (coordinator/experience_replay.py), its states
                                                     that are new under ``coverage`` (a piece
                                                     re-simulated from its keys uses the
                                                     newest ``actions`` submitted)
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
import dataclasses
from abc import ABC, abstractmethod
from typing import Any, Callable

import numpy as np

from scenarios.base import FAILURE, TRUNCATED
from scenarios.rollout import RunBatch


@dataclass(eq=False)  # one chunk is one object: the driver keys its re-screenings on it
class Chunk:
    first_index: int  # the sample index of its first run
    lengths: np.ndarray  # (k,) states per run, start included
    outcomes: np.ndarray  # (k,) FAILURE / TRUNCATED / HORIZON
    last: np.ndarray  # (k, n) terminal states
    screening: Any  # what the screen returned for these runs (None: not screened)
    fetch_visited: Callable[[], tuple[np.ndarray, np.ndarray]] = field(repr=False)
    keep: Callable = field(repr=False, default=None)  # (rows, takes) -> a handle for screen_stored
    _visited: tuple | None = field(default=None, repr=False)
    exits: np.ndarray | None = field(default=None, repr=False)  # (k,) int8 facet left through (RunBatch.exits)
    indices: np.ndarray | None = None  # (k,) sample indices, when not first_index + row
    margins: np.ndarray | None = field(default=None, repr=False)  # (k,) float64 (RunBatch.margins)

    def __post_init__(self):
        if self.indices is None:
            self.indices = np.arange(self.first_index, self.first_index + len(self.lengths), dtype=np.int64)

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

    def keep_visited(self, rows: np.ndarray, takes: np.ndarray):
        """A handle on the first ``takes[i]`` visited states of runs ``rows`` that the
        executor can screen later (``screen_stored``) without the coordinator holding them."""
        return self.keep(rows, takes)

    def part(self, lo: int, hi: int) -> "Chunk":
        """Runs ``lo:hi`` of this chunk, as a chunk of their own."""
        sc = self.screening
        if sc is not None:
            w0, w1, e0, e1 = sc.witness_offsets[lo], sc.witness_offsets[hi], sc.explore_offsets[lo], sc.explore_offsets[hi]
            sc = dataclasses.replace(sc, event=sc.event[lo:hi], escaped=sc.escaped[lo:hi],
                                     witness_offsets=sc.witness_offsets[lo : hi + 1] - w0, witnesses=sc.witnesses[w0:w1],
                                     explore_offsets=sc.explore_offsets[lo : hi + 1] - e0,
                                     explore_states=sc.explore_states[e0:e1])

        def visited():
            states, offsets = self.visited()
            return states[offsets[lo] : offsets[hi]], offsets[lo : hi + 1] - offsets[lo]

        keep = None if self.keep is None else (lambda rows, takes: self.keep(rows + lo, takes))
        return Chunk(int(self.indices[lo]), self.lengths[lo:hi], self.outcomes[lo:hi], self.last[lo:hi], sc, visited,
                     keep, indices=self.indices[lo:hi], exits=None if self.exits is None else self.exits[lo:hi],
                     margins=None if self.margins is None else self.margins[lo:hi])

    def trajectory(self, row: int, start: np.ndarray) -> np.ndarray:
        """(length, n) every state of run ``row``: its start, its visited states and
        its terminal state if that left Sigma."""
        states, offsets = self.visited()
        parts = [start[None, :], states[offsets[row] : offsets[row + 1]]]
        if self.outcomes[row] in (FAILURE, TRUNCATED):
            parts.append(self.last[row][None, :])
        return np.concatenate(parts)


class Executor(ABC):
    """Where runs are simulated (the contract above). Every executor passes the shared
    conformance suite (farm/execution/testing.py: the same committed sequence as in-process, cancel,
    close, a worker failure)."""

    name: str = ""
    workers: int = 1
    # runs go to workers when submitted and come back later (True), or are simulated when
    # their result is asked for (False: every handle is ready). The driver then sends a
    # pass's replacements together rather than one call per misprediction; results never
    # depend on it
    concurrent: bool = False
    notify = None  # takes a line for the user (e.g. a worker replaced), or None

    @abstractmethod
    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None,
               indices: np.ndarray | None = None) -> list:
        """Simulate runs ``first_index, first_index + 1, ...`` (or the sample ``indices``)
        from ``starts``; one handle per chunk, in index order."""

    @abstractmethod
    def result(self, handle) -> Chunk:
        """Wait for one chunk."""

    def ready(self, handle) -> bool:
        """Would ``result(handle)`` return without waiting for a worker? (The driver commits
        on past a replacement that is not back.) An executor that simulates when a result
        is asked for, in-process, says yes."""
        return True

    @abstractmethod
    def cancel(self, handle) -> None:
        """Drop a chunk: it is not committed."""

    @abstractmethod
    def screen_stored(self, pieces: list, screen) -> list[tuple[np.ndarray, np.ndarray]]:
        """Experience replay: each stored piece's states that are new under ``screen``."""

    @abstractmethod
    def close(self) -> None:
        """End the workers; the executor takes no more work."""

    def batch_size(self, requested: int) -> int:
        """Runs per batch that give every worker a chunk of each batch, so that the
        ``pipeline_depth`` batches in flight keep every worker busy (at least ``requested``). The driver asks only where the batch size cannot
        change a result (sequential counting)."""
        return requested

    def started(self, counting: str, batch_size: int, pipeline_depth: int) -> list[str]:
        """Lines for the user once the executor is up (e.g. where Ray runs), given the
        campaign's farm.counting, batch_size and pipeline_depth."""
        return []

    def report(self):
        """What a simulated clock measured (the virtual farm's ``VirtualClock``); None for
        an executor that runs in real time."""
        return None

    def run_seconds(self) -> float | None:
        """A worker's seconds per run as measured so far (None: nothing measured, or runs
        simulated when their results are asked for). How far ahead the campaign works for
        a change that waits follows it (coordinator/driver/campaign.py ``LookAhead.past_holds``);
        it never changes a result."""
        return None


@dataclass(eq=False)
class ChunkSummary:
    """What a worker sends back for a simulated chunk: per run, what the coordinator needs
    (the visited states travel apart, on demand: ``visited`` of ``of``)."""

    first_index: int  # the sample index of its first run
    lengths: np.ndarray  # (k,) states per run, start included
    outcomes: np.ndarray  # (k,) FAILURE / TRUNCATED / HORIZON
    last: np.ndarray  # (k, n) terminal states
    screening: Any  # what the screen returned for these runs (None: not screened)
    indices: np.ndarray  # (k,) int64 sample indices
    exits: np.ndarray | None  # (k,) int8 facet left through (RunBatch.exits)
    margins: np.ndarray | None = None  # (k,) float64 (RunBatch.margins)
    busy_s: float = 0.0  # [s] the worker's time on it (the chunk sizes follow it: farm/execution/chunking.py)

    @classmethod
    def of(cls, batch: RunBatch, screen) -> tuple["ChunkSummary", tuple[np.ndarray, np.ndarray]]:
        """A simulated batch screened against ``screen``: its summary and its visited states."""
        states, offsets = batch.visited()
        screening = None if screen is None else screen.screen(states, offsets, batch.outcomes)
        summary = cls(int(batch.indices[0]) if len(batch) else 0, batch.lengths, batch.outcomes, batch.last_states(),
                      screening, batch.indices.astype(np.int64), batch.exits, batch.margins)
        return summary, (states, offsets)

    def chunk(self, fetch_visited: Callable, keep: Callable) -> Chunk:
        """The chunk for the driver: its visited states fetched by ``fetch_visited()``,
        kept for experience replay by ``keep(rows, takes)``."""
        return Chunk(self.first_index, self.lengths, self.outcomes, self.last, self.screening, fetch_visited, keep,
                     indices=self.indices, exits=self.exits, margins=self.margins)


def screen_piece(simulator, source, piece, coverage) -> tuple[np.ndarray, np.ndarray]:
    """A stored piece's states that are new under ``coverage`` and their runs' positions,
    from the chunk's visited states ``source`` = (states, offsets), or re-simulated from
    the runs' keys when the source is gone."""
    from coordinator.experience_replay import new_states, select

    if source is None:
        batch = simulator.simulate(0, piece.starts, indices=piece.indices)  # the newest actions state
        states, offsets = batch.visited()
        rows = np.arange(len(piece.indices))
    else:
        states, offsets = source
        rows = piece.rows
    kept, run = select(states, offsets, rows, piece.takes)
    new = new_states(coverage, kept)
    return kept[new], run[new]
