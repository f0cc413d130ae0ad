"""Which final centres a deterministic certification has checked, and why that still holds.

In a deterministic system a centre's run is always the same run, so one run that stays
in the set (no failure, every state within delta of an alive centre: a strict quiet
screening) certifies its centre for as long as the centres that covered its states (its
witnesses) are alive: more centres can only cover more, and a run's states do not
change. A run drawn before a change therefore still certifies its centre after the
change if its witnesses survived, and only centres whose witnesses were pruned (and new
centres) need a run again. That is VAL^delta (every centre once) on the final set,
without re-running what a change did not touch.

Cost: a fine campaign certifies millions of centres with tens of millions of witnesses
and prunes thousands of times, so nothing here is proportional to all entries per call:
entries append into growing buffers, and a prune finds the entries that named a killed
centre through a reverse index (witness -> entries) kept as a few sorted runs merged in
tiers (the logarithmic method: a witness is merged O(log W) times; a lookup is a binary
search per run). docs/benchmarks.md has what the simpler indexes cost.
"""

from __future__ import annotations

import numpy as np

from coordinator.buffers import Appendable
from coordinator.unique import unique_ints


class CheckedCentres:
    def __init__(self):
        # vertex ids as int32 (``add`` refuses ids >= 2^31): ~83 M witnesses at delta_min
        # 0.125, 0.33 GB less than int64
        self._vertex = Appendable(np.int32)  # (E,) the centre each entry certifies
        self._offsets = Appendable(np.int64, [0])  # (E + 1,) its witnesses: witness[off[e]:off[e+1]]
        self._witness = Appendable(np.int32)  # (W,)
        self._valid = Appendable(bool)  # (E,) every witness alive since the entry was made
        self._count = np.zeros(0, dtype=np.int64)  # vertex -> valid entries certifying it
        self._reverse: _SortedRuns | None = _SortedRuns()  # witness -> entries naming it

    @property
    def vertex(self) -> np.ndarray:
        return self._vertex.view

    def certified(self, count: int) -> np.ndarray:
        """(count,) bool: vertex ids with a valid certificate."""
        return self.certified_range(0, count)

    def certified_range(self, lo: int, hi: int) -> np.ndarray:
        """(hi - lo,) bool: vertex ids lo..hi-1 with a valid certificate."""
        out = np.zeros(hi - lo, dtype=bool)
        n = max(0, min(hi, len(self._count)) - lo)
        out[:n] = self._count[lo : lo + n] > 0
        return out

    def certified_at(self, ids: np.ndarray) -> np.ndarray:
        """(len(ids),) bool: these vertex ids have a valid certificate."""
        ids = np.asarray(ids, dtype=np.int64)
        known = ids < len(self._count)
        out = np.zeros(len(ids), dtype=bool)
        out[known] = self._count[ids[known]] > 0
        return out

    def add(self, vertices: np.ndarray, witness_offsets: np.ndarray, witnesses: np.ndarray) -> None:
        """Entries for ``vertices`` (their runs' witnesses in CSR form)."""
        self._entries()
        if len(vertices) == 0:
            return
        if int(vertices.max()) >= 2**31 or (len(witnesses) and int(witnesses.max()) >= 2**31):
            raise OverflowError("checked centres: more than 2^31 centres")
        self._vertex.extend(vertices)
        self._offsets.extend(self._offsets.view[-1] + witness_offsets[1:])
        self._witness.extend(witnesses)
        first_entry = self._valid.size
        self._valid.extend(np.ones(len(vertices), dtype=bool))
        entry = first_entry + np.repeat(np.arange(len(vertices)), np.diff(witness_offsets))
        if self._reverse is not None:  # else built from every entry when first needed
            self._reverse.add(np.asarray(witnesses, dtype=np.int64), entry)
        top = int(vertices.max()) + 1
        if len(self._count) < top:
            self._count = np.concatenate([self._count, np.zeros(max(top, 2 * len(self._count)) - len(self._count),
                                                                np.int64)])
        np.add.at(self._count, vertices, 1)

    def invalidate(self, killed: np.ndarray) -> np.ndarray:
        """After a prune of vertex ids ``killed``: entries naming one of them as a
        witness no longer hold (an entry for a killed centre itself does not matter:
        only alive centres are asked about). Returns the vertices that lost their last
        certificate."""
        self._entries()
        killed = np.asarray(killed, dtype=np.int64)
        if len(killed) == 0 or self._witness.size == 0:
            return np.zeros(0, dtype=np.int64)
        entries = unique_ints(self._index().find(unique_ints(killed)))
        entries = entries[self._valid.view[entries]]
        self._valid.view[entries] = False
        vertices = self._vertex.view[entries]
        np.subtract.at(self._count, vertices, 1)
        vertices = unique_ints(vertices)
        return vertices[self._count[vertices] == 0]

    def _index(self) -> "_SortedRuns":
        if self._reverse is None:  # released, or loaded from a checkpoint: from the entries
            self._reverse = _SortedRuns()
            # a slice of witnesses at a time, each a compressed run of its own: all at once,
            # the entry of each witness and the pairs (8 bytes each, twice while sorted)
            # made a resumed delta_min 0.125 campaign peak ~0.5 GB above the run it resumed
            offsets, witness = self._offsets.view, self._witness.view
            for lo in range(0, len(witness), _SortedRuns.FINAL_SIZE):
                hi = min(lo + _SortedRuns.FINAL_SIZE, len(witness))
                entry = np.searchsorted(offsets, np.arange(lo, hi), side="right") - 1
                self._reverse.add(witness[lo:hi], entry)
        return self._reverse

    def release_index(self) -> None:
        """Drop the reverse index (a finished campaign prunes nothing more); a later
        ``invalidate`` builds it again."""
        self._reverse = None

    def release(self) -> None:
        """Keep only which centres are certified (the ``certified*`` queries): the
        campaign is done and checkpointed. The entries (~0.35 GB at delta_min 0.125) are
        dropped; ``add``, ``invalidate`` and ``state`` are refused after it."""
        self._reverse = None
        self._vertex = self._offsets = self._witness = self._valid = None

    def _entries(self) -> None:
        if self._witness is None:
            raise RuntimeError("checked centres: the entries were released (the campaign is done)")

    # -- persistence ----------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        self._entries()
        return {"cert.vertex": self._vertex.view, "cert.offsets": self._offsets.view,
                "cert.witness": self._witness.view, "cert.valid": self._valid.view}

    @classmethod
    def from_state(cls, state: dict) -> "CheckedCentres":
        out = cls()
        if "cert.vertex" in state and len(state["cert.vertex"]):
            out._vertex = Appendable(np.int32, state["cert.vertex"])
            out._offsets = Appendable(np.int64, state["cert.offsets"])
            out._witness = Appendable(np.int32, state["cert.witness"])
            out._valid = Appendable(bool, state["cert.valid"].astype(bool))
            out._reverse = None  # built at the first prune
            valid_vertices = out._vertex.view[out._valid.view]
            out._count = np.bincount(valid_vertices, minlength=int(out._vertex.view.max()) + 1).astype(np.int64)
        return out


class _SortedRuns:
    """A multimap key -> values as sorted runs, merged in tiers. Keys are vertex ids and
    values entry ids, both < 2^31.

    A run is int64 pairs key << 32 | value, sorted (by key, then value). A new run starts
    at tier 0; ``TIER`` runs of one tier merge into one of the next (a stable sort of
    their concatenation, which numpy does as a merge of the sorted runs it finds:
    timsort), so a pair is merged log_TIER(adds) times and a lookup searches at most
    (TIER - 1) runs per tier: fewer merges per pair than merging two runs at a time.

    A run of ``FINAL_SIZE`` pairs or more is merged no more and kept as compressed
    sparse rows: its distinct keys (int32), where each key's values start, and the
    values (int32). A key recurs ~20 times in such a run (witnesses of neighbouring
    centres, drawn close together), so it costs about half the bytes of its pairs. Merges
    stay below TIER x FINAL_SIZE pairs, and hold about 1.5x their pairs at once: a merge
    lets each input go once it is copied, and compression reads the pairs' halves in
    place (the last merges, holding inputs, concatenation and the sort's buffer at once,
    would otherwise make a fine campaign's peak memory). A lookup pays a binary search in
    each of a few more runs."""

    TIER = 4
    FINAL_SIZE = 1 << 22
    FINAL = -1  # the tier of a compressed run

    def __init__(self):
        self.runs: list = []  # sorted pairs, or (keys, starts, values) once final; oldest first
        self.tiers: list[int] = []

    def add(self, keys: np.ndarray, values: np.ndarray) -> None:
        if len(keys) == 0:
            return
        if max(int(keys.max()), int(values.max())) >= 2**31:
            raise OverflowError("checked centres: more than 2^31 centres or entries")
        pairs = (np.asarray(keys, dtype=np.int64) << 32) | np.asarray(values, dtype=np.int64)
        pairs.sort(kind="stable")
        self._append(pairs, 0)
        while (len(self.tiers) >= self.TIER and len(set(self.tiers[-self.TIER :])) == 1
               and self.tiers[-1] != self.FINAL):
            tier = self.tiers[-1] + 1
            parts = self.runs[-self.TIER :]
            del self.runs[-self.TIER :], self.tiers[-self.TIER :]
            self._append(_merge(parts), tier)

    def _append(self, pairs: np.ndarray, tier: int) -> None:
        if len(pairs) >= self.FINAL_SIZE:
            pairs, tier = _compress(pairs), self.FINAL
        self.runs.append(pairs)
        self.tiers.append(tier)

    def find(self, keys: np.ndarray) -> np.ndarray:
        """Every value stored under one of ``keys`` (sorted, unique)."""
        found = []
        keys = np.asarray(keys, dtype=np.int64)
        keys = keys[(keys >= 0) & (keys < 2**31)]
        lo_pairs, hi_pairs, keys32 = keys << 32, (keys + 1) << 32, keys.astype(np.int32)
        for run in self.runs:
            compressed = isinstance(run, tuple)
            if compressed:
                run_keys, starts, values = run
                at = np.searchsorted(run_keys, keys32)  # int32 both: no cast of the run
                hit = at < len(run_keys)
                hit[hit] = run_keys[at[hit]] == keys32[hit]
                lo, hi = starts[at[hit]], starts[at[hit] + 1]
            else:
                lo = np.searchsorted(run, lo_pairs, side="left")
                hi = np.searchsorted(run, hi_pairs, side="left")
            counts = hi - lo
            total = int(counts.sum())
            if total:
                rows = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(total)
                found.append(values[rows].astype(np.int64) if compressed else run[rows] & 0xFFFFFFFF)
        return np.concatenate(found) if found else np.zeros(0, dtype=np.int64)


def _merge(parts: list[np.ndarray]) -> np.ndarray:
    """One sorted run of the sorted ``parts`` (emptied): each part is let go once it is
    copied, so that the merge holds about one copy of the pairs, not two (the inputs and
    their concatenation)."""
    merged = np.empty(sum(len(p) for p in parts), dtype=np.int64)
    at = 0
    while parts:
        part = parts.pop(0)
        merged[at : at + len(part)] = part
        at += len(part)
        del part
    merged.sort(kind="stable")  # a merge of the sorted runs it finds (timsort)
    return merged


def _compress(pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sorted pairs key << 32 | value -> (distinct keys, starts of their values, values).

    The halves are read through an int32 view of the pairs (both < 2^31, so the same
    numbers): shifting and masking made two int64 temporaries the size of the run, at
    the moment the campaign's memory peaks (after its largest merge)."""
    halves = pairs.view(np.int32).reshape(-1, 2)
    high = 1 if np.little_endian else 0
    keys = np.ascontiguousarray(halves[:, high])
    change = np.empty(len(keys), dtype=bool)
    change[0] = True
    np.not_equal(keys[1:], keys[:-1], out=change[1:])
    first = np.flatnonzero(change).astype(np.int32)
    del change
    distinct = keys[first]
    del keys
    return distinct, np.append(first, np.int32(len(pairs))), np.ascontiguousarray(halves[:, 1 - high])
