"""Experience replay (paper Sec. 4.4): the visited states of committed runs are kept and,
when delta shrinks, put through line 15 again (a stored state that is now neither
covered nor near a failure becomes a vertex).

The states stay where they were simulated: the buffer holds, per committed chunk, the
executor's handle on its visited states and which runs (and how many of their states)
count, plus the runs' keys and start states. At a round end the executor screens the
stored states on the workers and sends back only the new ones; a lost handle (a dead
worker, a resumed campaign) is replaced by re-simulating the runs from their keys,
which gives the very same states. So the coordinator's memory and its checkpoints grow
by ~50 bytes per stored run, not by its trajectory.

Capacity counts states offered, duplicates included (``replay_capacity``). For a
deterministic system a vertex's run is stored once: its repeats are the same states,
and replaying a state twice adds nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios.base import FAILURE, TRUNCATED


@dataclass
class Stored:
    """Runs of one chunk kept for replay."""

    source: object  # the executor's handle on their visited states; None: re-simulate from keys
    indices: np.ndarray  # (r,) global sample indices (the runs' keys)
    rows: np.ndarray  # (r,) their rows in the source's chunk
    takes: np.ndarray  # (r,) how many of each run's visited states count
    parents: np.ndarray  # (r,) the vertex each run started from
    starts: np.ndarray  # (r, n) start states (to re-simulate)


def visited_counts(lengths: np.ndarray, outcomes: np.ndarray) -> np.ndarray:
    """Visited states per run (see RunBatch.visited): after the start, inside Sigma."""
    # two comparisons, not np.isin: a replacement's one run is recorded alone, thousands of
    # times a campaign, and isin's set machinery costs tens of microseconds a call
    left = (outcomes == FAILURE) | (outcomes == TRUNCATED)
    return np.maximum(lengths.astype(np.int64) - 1 - left, 0)


def select(states: np.ndarray, offsets: np.ndarray, rows: np.ndarray, takes: np.ndarray):
    """The first ``takes[i]`` visited states of each run ``rows[i]``, in order; and the
    position i of each state's run."""
    run = np.repeat(np.arange(len(rows)), takes)
    within = np.arange(int(takes.sum())) - np.repeat(np.cumsum(takes) - takes, takes)
    return states[offsets[rows][run] + within], run


def new_states(coverage, states: np.ndarray) -> np.ndarray:
    """(S,) bool: line 15 now: neither within delta of an alive centre nor of a failure."""
    witness, near = coverage.classify_states(states)
    return (witness < 0) & ~near


def merged_by_source(pieces: list[Stored]) -> tuple[list[Stored], list[tuple[int, int, int]]]:
    """The pieces that share a source (the same chunk's visited states) as one piece each, in
    the order of their first: a chunk's runs are committed piece by piece (a round end has
    several pieces per chunk: docs/benchmarks.md), and each piece costs a replay call's
    serialization more than its runs do. -> (merged, parts), ``parts[i]`` = (its
    merged piece, its first run there, its runs) for piece ``i`` (``split_found``). A piece
    without a source (re-simulated from its keys) stays as it is."""
    groups: list[list[Stored]] = []
    runs: list[int] = []  # per merged piece, its runs so far
    where: dict[int, int] = {}  # id(source) -> its merged piece
    parts = []
    for piece in pieces:
        at = where.get(id(piece.source)) if piece.source is not None else None
        if at is None:
            at = len(groups)
            groups.append([])
            runs.append(0)
            if piece.source is not None:
                where[id(piece.source)] = at
        parts.append((at, runs[at], len(piece.indices)))
        groups[at].append(piece)
        runs[at] += len(piece.indices)
    fields = ("indices", "rows", "takes", "parents", "starts")
    merged = [group[0] if len(group) == 1 else
              Stored(group[0].source, *(np.concatenate([getattr(p, f) for p in group]) for f in fields))
              for group in groups]
    return merged, parts


def split_found(found: list, parts: list[tuple[int, int, int]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """What the executor found per merged piece, back per piece (``merged_by_source``): a
    piece's states are those of its runs, in order (``select`` keeps the runs' order, and
    what is new is a subset of it), with its runs' positions counted from its own first."""
    out = []
    for at, first, runs in parts:
        states, run = found[at]
        lo, hi = np.searchsorted(run, [first, first + runs])
        out.append((states[lo:hi], run[lo:hi] - first))
    return out


class ReplayBuffer:
    def __init__(self, capacity: int, deterministic: bool, n: int):
        self.capacity = capacity
        self.n = n
        self.deterministic = deterministic
        self.size = 0  # states offered so far (the capacity's unit)
        self.pieces: list[Stored] = []
        self._stored_vertices = np.zeros(0, dtype=bool)  # deterministic: vertices whose run is kept

    def add(self, chunk, rows: np.ndarray, start_ids: np.ndarray, starts: np.ndarray, vertex_count: int) -> None:
        """Committed runs ``rows`` of ``chunk`` (non-failing ones are kept, up to capacity)."""
        if self.size >= self.capacity:
            return
        ok = np.flatnonzero(chunk.outcomes[rows] != FAILURE)
        if len(ok) == 0:
            return
        counts = visited_counts(chunk.lengths[rows[ok]], chunk.outcomes[rows[ok]])
        room = self.capacity - self.size
        takes = np.minimum(counts, np.maximum(room - (np.cumsum(counts) - counts), 0))
        self.size += int(takes.sum())
        keep = takes > 0
        parents = start_ids[ok]
        if self.deterministic:
            if len(self._stored_vertices) < vertex_count:
                grown = np.zeros(vertex_count, dtype=bool)
                grown[: len(self._stored_vertices)] = self._stored_vertices
                self._stored_vertices = grown
            first = np.zeros(len(ok), dtype=bool)
            first[np.unique(parents, return_index=True)[1]] = True  # a vertex's first run in this chunk
            keep &= first & ~self._stored_vertices[parents]
            self._stored_vertices[parents[keep]] = True
        if keep.any():
            kept = rows[ok[keep]]
            self.pieces.append(Stored(chunk.keep_visited(kept, takes[keep]), chunk.indices[kept], kept,
                                      takes[keep], parents[keep], starts[ok[keep]]))

    @staticmethod
    def candidates(pieces: list, found: list) -> tuple[np.ndarray, np.ndarray]:
        """Every stored state that is new now, in the order stored, with its run's vertex
        (``found``: per piece, what the executor screened as new)."""
        if not pieces:
            return np.empty((0, 0)), np.empty(0, dtype=np.int64)
        states = [s for s, _ in found]
        parents = [piece.parents[run] for piece, (_, run) in zip(pieces, found)]
        return np.concatenate(states), np.concatenate(parents)

    def release(self) -> None:
        """Drop the handles on stored states (the keys stay, so checkpoints do not
        change): the last replay is over. With the local executor the handles are the
        trajectories themselves (lead-follow at delta_min 0.125: ~0.3 GB)."""
        for piece in self.pieces:
            piece.source = None

    # -- persistence: keys only (no states) ---------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        pieces, n = self.pieces, self.n
        return {
            "replay.index": np.concatenate([p.indices for p in pieces]) if pieces else np.empty(0, np.int64),
            "replay.take": np.concatenate([p.takes for p in pieces]) if pieces else np.empty(0, np.int64),
            "replay.parent": np.concatenate([p.parents for p in pieces]) if pieces else np.empty(0, np.int64),
            "replay.start": np.concatenate([p.starts for p in pieces]) if pieces else np.empty((0, n)),
            "replay.size": np.array(self.size),
            "replay.vertices": self._stored_vertices.copy(),
        }

    def load_state(self, state: dict) -> None:
        """Pieces without a source: their states are re-simulated at the next replay."""
        index = state["replay.index"].astype(np.int64)
        self.pieces = [Stored(None, index, np.arange(len(index)), state["replay.take"].astype(np.int64),
                              state["replay.parent"].astype(np.int64), state["replay.start"])] if len(index) else []
        self.size = int(state["replay.size"])
        self._stored_vertices = state["replay.vertices"].astype(bool)
