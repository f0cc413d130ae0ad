"""The batches drawn ahead of the commit head, and their chunks as they come back.

Batch ``b``'s starts are drawn from the state as it is when the batch is drawn (the
parallel contract, shared/spec/algorithms.md point 2), up to ``pipeline_depth`` batches
ahead of the head (another one once the head's runs ahead fall to the lead,
coordinator/driver/lead.py); each goes to the executor as it is drawn and comes back as
chunks, fetched in index order. A batch is kept until every run of it is committed for
good: the head may go back into it (a held replacement that changes the state,
coordinator/driver/holds.py).
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from coordinator.driver.lead import Lead
from coordinator.executor import Chunk
from coordinator.stable_sampler import Draws

# A deterministic system's certification (every centre once) draws, batch by batch, the
# next centres not drawn yet at the state the batch is drawn at: the order follows the
# batches. Under sequential counting they are these (the default window), whatever
# farm.batch_size and pipeline_depth say, so that those change no result there either.
ENUMERATION_BATCH = 1024
ENUMERATION_DEPTH = 2


def batch_shape(settings, enumerating: bool, workers_batch, quiet_needed) -> tuple[int, int]:
    """(runs per batch, batches ahead): the settings' (deferred counting), fixed ones while
    a deterministic certification enumerates, and under sequential counting (where the
    batch size changes no sampled run) as many as keep the workers busy
    (``workers_batch()``), but no more than the round's quiet runs (``quiet_needed()``): runs in flight past a
    round's end are dropped, and each is a draw a change can move (docs/benchmarks.md,
    "2026-11-26, morning": many workers of short runs)."""
    if settings.lag:
        return settings.batch_size, settings.pipeline_depth
    if enumerating:
        return ENUMERATION_BATCH, ENUMERATION_DEPTH
    return min(workers_batch(), max(settings.batch_size, quiet_needed())), settings.pipeline_depth


@dataclass
class Pending:
    """A batch of draws from ``first_index`` on, and its chunks fetched so far."""

    first_index: int
    draws: Draws
    starts: np.ndarray
    handles: list = field(default_factory=list)
    next_handle: int = 0
    chunks: list = field(default_factory=list)  # fetched, in index order (contiguous)
    ends: list = field(default_factory=list)  # each fetched chunk's end index
    drawn_at: int = -1  # the head when it was drawn (-1: read back from a checkpoint)
    reached: bool = False  # has the head located a run in it

    def __len__(self) -> int:
        return len(self.draws)

    @property
    def end(self) -> int:
        return self.first_index + len(self.draws)

    def done(self, head: int) -> int:
        """Its runs before index ``head``."""
        return min(max(head - self.first_index, 0), len(self.draws))

    def chunk_at(self, index: int) -> Chunk | None:
        """The fetched chunk that holds run ``index``, if fetched."""
        at = bisect.bisect_right(self.ends, index)
        return self.chunks[at] if at < len(self.chunks) else None

    def fetched(self, chunk: Chunk) -> None:
        self.chunks.append(chunk)
        self.ends.append(chunk.first_index + len(chunk))


class Pipeline:
    """The batches in flight, oldest first: drawn, sent, fetched in order, released once
    committed for good, or dropped at a round end."""

    def __init__(self, launcher, pending=(), lead: Lead | None = None):
        self.launcher = launcher  # coordinator/driver/launcher.py: the executor's side
        self.batches: deque[Pending] = deque(pending)
        self.lead = lead or Lead(adaptive=False)  # how far ahead the next batch is drawn

    def __iter__(self):
        return iter(self.batches)

    def __bool__(self) -> bool:
        return bool(self.batches)

    def fill(self, head: int, batch: int, depth: int, budget: int, draw, run_s: float | None = None,
             fixed: bool = False) -> None:
        """Keep up to ``depth`` batches of ``batch`` runs drawn (``draw(indices) -> Draws``)
        and sent ahead of ``head`` (fewer when the budget ends), another one only while the
        head's runs ahead are at most the lead's for runs of ``run_s`` seconds (``fixed``:
        the full pipeline's, as a deterministic certification's order needs); batches the
        head has passed but may go back into do not count."""
        ahead = [p for p in self.batches if p.end > head]
        # the full pipeline's lead counts the batches as drawn (a round's first may be larger)
        lead = self.lead.runs(max([batch] + [len(p) for p in ahead]), depth, None if fixed else run_s)
        runs_ahead = sum(p.end - max(head, p.first_index) for p in ahead)
        while len(ahead) < depth and (not ahead or runs_ahead <= lead):
            first = self.batches[-1].end if self.batches else head
            size = min(batch, budget - first)
            if size <= 0:
                break
            draws = draw(np.arange(first, first + size))
            p = Pending(first, draws, self.launcher.starts(draws.ids), drawn_at=head)  # may be < size
            self.batches.append(p)
            ahead.append(p)
            runs_ahead += len(p)
        for p in self.batches:
            if not p.handles and not p.chunks:
                done = p.done(head)
                p.handles = self.launcher.submit(p.first_index + done, p.starts[done:])

    def holding(self, index: int) -> Pending | None:
        """The batch that holds run ``index``, if drawn."""
        return next((p for p in self.batches if p.first_index <= index < p.end), None)

    def locate(self, head: int) -> tuple[Pending, Chunk] | None:
        """The batch and fetched chunk that hold the head's run (fetching, in order, the
        chunks up to it); None when no batch is drawn there (the budget is spent)."""
        p = self.holding(head)
        if p is None:
            return None
        chunk = p.chunk_at(head)
        while chunk is None:
            if self.lead.active and not self.next_ready(p):
                self.lead.waited()  # for a worker
            chunk = self.fetch_next(p)
            if not chunk.first_index <= head < chunk.first_index + len(chunk):
                chunk = None
        if not p.reached:
            p.reached = True
            self.lead.reached(ahead=0 <= p.drawn_at < p.first_index)
        return p, chunk

    def fetch_next(self, p: Pending) -> Chunk:
        """Fetch batch ``p``'s next chunk (waiting for it), in index order."""
        chunk = self.launcher.fetch(p.handles[p.next_handle])
        p.next_handle += 1
        p.fetched(chunk)
        return chunk

    def next_ready(self, p: Pending) -> bool:
        """Is batch ``p``'s next chunk back (fetched without waiting for a worker)?"""
        return p.next_handle < len(p.handles) and self.launcher.ready(p.handles[p.next_handle])

    def release(self, final: int) -> None:
        """Drop the batches whose every run is committed for good (they end before ``final``)."""
        while self.batches and self.batches[0].end <= final:
            self.batches.popleft()

    def forget_drawn_past(self, head: int) -> None:
        """Cancel and forget the batches drawn while the head stood past index ``head``: it
        went back there (a held replacement changed the state), and under deferred
        counting which runs a batch's draws mispredict depends on the state they were
        drawn at. ``fill`` draws them again when the head is where it drew them first,
        so the result does not depend on the holds (that is, on the workers' timing)."""
        while self.batches and self.batches[-1].drawn_at > head:
            self._cancel(self.batches.pop())

    def drop(self) -> None:
        """Cancel and forget every batch (a round end: their indices are drawn again)."""
        for p in self.batches:
            self._cancel(p)
        self.batches.clear()

    def _cancel(self, p: Pending) -> None:
        """Cancel batch ``p``'s chunks not fetched yet."""
        for handle in p.handles[p.next_handle :]:
            self.launcher.cancel(handle)

    def open(self, head: int, drawn_by: bool = False) -> list[Pending]:
        """The batches with runs from ``head`` on (what a checkpoint keeps); ``drawn_by``:
        only those drawn with the head at ``head`` or before (deferred counting draws the
        others again, at the state a resumed head reaches)."""
        return [p for p in self.batches if p.end > head and not (drawn_by and p.drawn_at > head)]
