"""The committed-run record since the last flush: the rows of the run ledger
(farm/directory/storage.py writes them as Parquet segments at every checkpoint)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coordinator.algorithm import Event
from coordinator.executor import Chunk
from coordinator.rescreen import Rescreen


class CommitLog:
    """Columns of the committed-run record since the last flush (the run ledger).

    Per chunk, what every row shares (first sample index, round, delta) is kept once and
    expanded at ``take``: a campaign shorter than ``farm.checkpoint_every`` holds the log
    of all its runs, so each row holds only what is its own."""

    COLUMNS = ("sample_index", "round", "delta", "start", "outcome", "steps", "margin", "changed", "counted", "kind")
    EXACT, DISCARDED, REPLACEMENT = 0, 1, 2  # ``kind``: used as drawn, mispredicted (unseen), a replacement

    def __init__(self):
        self.shared: list[tuple[int, int, int, float]] = []  # (first sample index, rows, round, delta)
        self.start: list[np.ndarray] = []
        self.outcome: list[np.ndarray] = []
        self.steps: list[np.ndarray] = []
        self.margin: list[np.ndarray] = []
        self.changed: list[np.ndarray] = []
        self.counted: list[np.ndarray] = []
        self.kind: list[np.ndarray] = []

    def add(self, first_index: int, starts: np.ndarray, chunk: Chunk, rows: np.ndarray, rnd: int, delta: float,
            changed: np.ndarray, counted: np.ndarray, kind: np.ndarray | None = None) -> None:
        """Rows ``rows`` of ``chunk`` (``starts``: theirs) hold sample indices
        ``first_index, first_index + 1, ...`` (a chunk is committed in order; a replacement
        is a row of its own)."""
        if len(rows) == 0:
            return
        self.shared.append((first_index, len(rows), rnd, delta))
        self.start.append(starts)
        self.outcome.append(chunk.outcomes[rows].astype(np.int8))
        self.steps.append((chunk.lengths[rows] - 1).astype(np.int32))
        self.margin.append(np.full(len(rows), np.nan) if chunk.margins is None else chunk.margins[rows].astype(float))
        self.changed.append(changed)
        self.counted.append(counted)
        self.kind.append(np.zeros(len(rows), dtype=np.int8) if kind is None else kind.astype(np.int8))

    def take(self) -> dict[str, np.ndarray] | None:
        if not self.shared:
            return None
        first, rows, rounds, deltas = (np.array(c) for c in zip(*self.shared))
        within = np.arange(int(rows.sum())) - np.repeat(np.cumsum(rows) - rows, rows)
        out = {"sample_index": np.repeat(first.astype(np.int64), rows) + within,
               "round": np.repeat(rounds.astype(np.int32), rows), "delta": np.repeat(deltas.astype(float), rows)}
        self.shared.clear()
        for name in self.COLUMNS[3:]:  # a column's pieces go as it is joined: ~1x the log held, not 2x
            pieces = getattr(self, name)
            out[name] = np.concatenate(pieces)
            pieces.clear()
        return {name: out[name] for name in self.COLUMNS}


@dataclass
class ChunkRows:
    """What the head decided for the runs of one chunk, logged in the order committed."""

    chunk: Chunk
    starts: np.ndarray  # (k, n)
    ids: np.ndarray  # (k,) their start vertices
    rescreen: Rescreen
    at: int  # the chunk's first row in its batch
    logged: int  # rows before this one are logged
    kind: np.ndarray  # (k,) int8 CommitLog.EXACT / DISCARDED
    changed: np.ndarray  # (k,) bool
    counted: np.ndarray  # (k,) bool: toward the round's quiet runs

    @classmethod
    def of(cls, p, chunk: Chunk, rescreen: Rescreen, head: int) -> "ChunkRows":
        """The runs of ``chunk`` of batch ``p`` (coordinator/driver/pipeline.py), from the head on."""
        at, k = chunk.first_index - p.first_index, len(chunk)
        return cls(chunk, p.starts[at : at + k], p.draws.ids[at : at + k], rescreen, at, head - chunk.first_index,
                   np.zeros(k, dtype=np.int8), np.zeros(k, dtype=bool), np.zeros(k, dtype=bool))

    def event(self, row: int) -> Event:
        return Event.of_run(self.chunk.first_index + row, self.chunk, row, self.starts[row], self.ids[row],
                            self.rescreen)
