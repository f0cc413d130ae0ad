"""The driver's persisted state: where a campaign stands (``Counters``), and the draws and
replacements a resumed campaign simulates again, to and from a checkpoint's arrays."""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass, field

import numpy as np

from coordinator.driver.pipeline import Pending
from coordinator.driver.replacements import Replacement
from coordinator.executor import Chunk
from coordinator.stable_sampler import Draws
from scenarios.base import TRUNCATED


@dataclass
class Counters:
    """Where a campaign stands. Runs simulated and read back are committed (the head's
    runs, a discarded one included), replaced, or dropped (``runs_dropped``)."""

    committed: int = 0  # the head: the next sample index to commit (indices are contiguous)
    quiet: int = 0  # the N_eps counter: indices of the streak resolved and quiet
    streak_start: int = 0  # the first index after the last change
    escaped_in_streak: int = 0  # counted quiet runs that left Phi_delta near PhiBar
    changes: int = 0
    runs_simulated: int = 0
    steps_simulated: int = 0
    runs_discarded: int = 0  # mispredicted runs, discarded unseen (replacements that moved again too)
    runs_replaced: int = 0  # replacements applied
    rounds_completed: int = 0
    done: bool = False
    converged: bool = False  # the last round ended by the N_eps rule
    round_ends: list = field(default_factory=list)  # committed count at each round end
    elapsed_s: float = 0.0
    recorded: int = 0  # runs handed to the recorder so far
    attempts: int = 0  # sampled certification: checks begun; deterministic: 1 + changes while certifying
    certification_from: int = -1  # the committed count when certification began (-1: it did not)
    closing_ends: list = field(default_factory=list)  # committed count at each closing round's end
    check_violations: int = 0  # violations the current check saw within quantify.certify_tolerance
    truncations: list = field(default_factory=list)  # committed truncated runs per facet (Scenario.facets() order)

    def count_truncations(self, chunk: Chunk, rows: np.ndarray) -> None:
        """Add the truncated runs among the chunk's (used) ``rows``, by the facet they left
        Sigma through."""
        if chunk.exits is None:
            return
        left = chunk.exits[rows][chunk.outcomes[rows] == TRUNCATED]
        if len(left):
            counts = np.bincount(left, minlength=len(self.truncations))
            counts[: len(self.truncations)] += np.asarray(self.truncations, dtype=np.int64)
            self.truncations = counts.tolist()

    def start_streak(self) -> None:
        """A change or a round end: the N_eps count starts again at the head (runs before
        it were decided at the old state)."""
        self.quiet = 0
        self.escaped_in_streak = 0
        self.streak_start = self.committed

    def violations_tolerated(self, tolerance: int) -> int:
        """Violations the sampled checks counted without applying them: every failed check
        tolerated ``tolerance`` and applied the next; the current one has tolerated
        ``check_violations``."""
        return tolerance * max(self.attempts - 1, 0) + self.check_violations

    @property
    def runs_certification(self) -> int:
        """Committed runs since certification began (closing rounds and checks; for a
        deterministic system, its last round, which is its certification)."""
        return self.committed - self.certification_from if self.certification_from >= 0 else 0

    @property
    def runs_dropped(self) -> int:
        """Runs simulated whose results were not used: in flight at a round end."""
        return self.runs_simulated - self.committed - self.runs_replaced


@dataclass
class DriverState:
    """A campaign driver's state: the counters, the batches with runs not committed for
    good and the replacements not yet applied, so that a resumed campaign simulates
    exactly them again. Draws read back are checked again before they are used (their
    examined slots are not kept)."""

    counters: Counters
    pending: list[Pending]
    replacements: list[Replacement]
    final_distribution: str = ""

    @classmethod
    def of(cls, counters: Counters, pipeline, replacements, speculations, final_distribution: str,
           deferred: bool = False) -> "DriverState":
        """A running driver's state as committed for good: with holds, as the head passed
        the first of them (what follows it may be undone; coordinator/driver/holds.py).
        ``deferred``: deferred counting, whose batches drawn past that point are left out
        (``Pipeline.forget_drawn_past``)."""
        counts, queued = replacements.committed_for_good()
        if counts:
            counters = dataclasses.replace(counters, **counts, **speculations.committed_counts())
        return cls(counters, pipeline.open(counters.committed, drawn_by=deferred), queued, final_distribution)

    def write(self, n: int) -> tuple[dict[str, np.ndarray], dict]:
        """-> arrays (``n``: the state's dimension) and JSON-able metadata."""
        head = self.counters.committed
        arrays = {"pending.count": np.array(len(self.pending))}
        for i, p in enumerate(self.pending):
            done = p.done(head)
            arrays[f"pending.{i}.first_index"] = np.array(p.first_index + done)
            arrays[f"pending.{i}.starts"] = p.starts[done:]
            arrays[f"pending.{i}.start_ids"] = p.draws.ids[done:]
            arrays[f"pending.{i}.fixed"] = np.array(p.draws.fixed)
        replacements = self.replacements
        arrays["replacements.index"] = np.array([r.index for r in replacements], dtype=np.int64)
        arrays["replacements.start_id"] = np.array([r.draws.ids[0] for r in replacements], dtype=np.int64)
        arrays["replacements.start"] = np.stack([r.start for r in replacements]) if replacements else np.empty((0, n))
        arrays["replacements.due"] = np.array([r.due for r in replacements], dtype=np.int64)
        meta = {"counters": asdict(self.counters), "final_distribution": self.final_distribution}
        return arrays, meta

    @classmethod
    def read(cls, arrays: dict[str, np.ndarray], meta: dict) -> "DriverState":
        """Raises KeyError, TypeError or ValueError when the checkpoint is damaged."""
        pending = []
        for i in range(int(arrays["pending.count"])):
            ids = arrays[f"pending.{i}.start_ids"].astype(np.int64)
            fixed = bool(arrays[f"pending.{i}.fixed"]) if f"pending.{i}.fixed" in arrays else False
            pending.append(Pending(int(arrays[f"pending.{i}.first_index"]), Draws.unknown(ids, fixed),
                                   arrays[f"pending.{i}.starts"]))
        replacements = [Replacement(int(index), Draws.unknown(np.array([start_id], dtype=np.int64)), start, int(due))
                        for index, start_id, start, due in zip(arrays["replacements.index"],
                                                               arrays["replacements.start_id"],
                                                               arrays["replacements.start"], arrays["replacements.due"])]
        counters = dict(meta["counters"])
        counters.pop("violations_tolerated", None)  # kept by checkpoints of 2026-11-28: now derived
        return cls(Counters(**counters), pending, replacements, meta.get("final_distribution", ""))
