"""Which final centres a deterministic certification has checked, and why that still holds.

In a deterministic system a centre's run is always the same run, so one run that stays
in the set (no failure, every state within delta of an alive centre: a strict quiet
screening) certifies its centre for as long as the centres that covered its states (its
witnesses) are alive: more centres can only cover more, and a run's states do not
change. A run drawn before a change therefore still certifies its centre after the
change if its witnesses survived, and only centres whose witnesses were pruned (and new
centres) need a run again. That is VAL^delta (every centre once) on the final set,
without re-running what a change did not touch.

Cost: a campaign at delta_min = 0.125 certifies ~1.8 M centres with ~20 M witnesses and
prunes thousands of times, so nothing here is proportional to all entries per call:
entries append into growing buffers, and a prune finds the entries that named a killed
centre through a reverse index (witness -> entries) kept as a few sorted runs of
doubling size (the logarithmic method: a new run merges with the last while that is
no larger, so a witness is merged O(log W) times; a lookup is a binary search per run). It replaced one index rebuilt only when the entries appended since outnumbered
those it covered, with a linear scan of those for every prune: 120 s of a 190 s
campaign at delta_min 0.125.
"""

from __future__ import annotations

import numpy as np


class _Buffer:
    """A growable 1-D array (amortized doubling)."""

    def __init__(self, dtype, initial=()):
        data = np.asarray(initial, dtype=dtype)
        self.data = np.empty(max(16, 2 * len(data)), dtype=dtype)
        self.data[: len(data)] = data
        self.size = len(data)

    def extend(self, values: np.ndarray) -> None:
        need = self.size + len(values)
        if need > len(self.data):
            grown = np.empty(max(need, 2 * len(self.data)), dtype=self.data.dtype)
            grown[: self.size] = self.data[: self.size]
            self.data = grown
        self.data[self.size : need] = values
        self.size = need

    @property
    def view(self) -> np.ndarray:
        return self.data[: self.size]


class Certificates:
    def __init__(self):
        self._vertex = _Buffer(np.int64)  # (E,) the centre each entry certifies
        self._offsets = _Buffer(np.int64, [0])  # (E + 1,) its witnesses: witness[off[e]:off[e+1]]
        self._witness = _Buffer(np.int64)  # (W,)
        self._valid = _Buffer(bool)  # (E,) every witness alive since the entry was made
        self._count = np.zeros(0, dtype=np.int64)  # vertex -> valid entries certifying it
        self._reverse = _SortedRuns()  # witness -> entries naming it

    @property
    def vertex(self) -> np.ndarray:
        return self._vertex.view

    def certified(self, count: int) -> np.ndarray:
        """(count,) bool: vertex ids with a valid certificate."""
        out = np.zeros(count, dtype=bool)
        n = min(count, len(self._count))
        out[:n] = self._count[:n] > 0
        return out

    def add(self, vertices: np.ndarray, witness_offsets: np.ndarray, witnesses: np.ndarray) -> None:
        """Entries for ``vertices`` (their runs' witnesses in CSR form)."""
        if len(vertices) == 0:
            return
        self._vertex.extend(vertices)
        self._offsets.extend(self._offsets.view[-1] + witness_offsets[1:])
        self._witness.extend(witnesses)
        first_entry = self._valid.size
        self._valid.extend(np.ones(len(vertices), dtype=bool))
        entry = first_entry + np.repeat(np.arange(len(vertices)), np.diff(witness_offsets))
        self._reverse.add(np.asarray(witnesses, dtype=np.int64), entry)
        top = int(vertices.max()) + 1
        if len(self._count) < top:
            self._count = np.concatenate([self._count, np.zeros(max(top, 2 * len(self._count)) - len(self._count),
                                                                np.int64)])
        np.add.at(self._count, vertices, 1)

    def invalidate(self, killed: np.ndarray) -> None:
        """After a prune of vertex ids ``killed``: entries naming one of them as a
        witness no longer hold (an entry for a killed centre itself does not matter:
        only alive centres are asked about)."""
        killed = np.asarray(killed, dtype=np.int64)
        if len(killed) == 0 or self._witness.size == 0:
            return
        entries = np.unique(self._reverse.find(np.unique(killed)))
        entries = entries[self._valid.view[entries]]
        self._valid.view[entries] = False
        np.subtract.at(self._count, self._vertex.view[entries], 1)

    # -- persistence ----------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        return {"cert.vertex": self._vertex.view, "cert.offsets": self._offsets.view,
                "cert.witness": self._witness.view, "cert.valid": self._valid.view}

    @classmethod
    def from_state(cls, state: dict) -> "Certificates":
        out = cls()
        if "cert.vertex" in state and len(state["cert.vertex"]):
            out._vertex = _Buffer(np.int64, state["cert.vertex"])
            out._offsets = _Buffer(np.int64, state["cert.offsets"])
            out._witness = _Buffer(np.int64, state["cert.witness"])
            out._valid = _Buffer(bool, state["cert.valid"].astype(bool))
            entry = np.repeat(np.arange(out._vertex.size), np.diff(out._offsets.view))
            out._reverse.add(out._witness.view, entry)
            valid_vertices = out._vertex.view[out._valid.view]
            out._count = np.bincount(valid_vertices, minlength=int(out._vertex.view.max()) + 1).astype(np.int64)
        return out


class _SortedRuns:
    """A multimap key -> values as sorted runs of doubling size. Keys (vertex ids) and
    values (entry ids) are stored as int32: half the memory of ~20 M pairs."""

    def __init__(self):
        self.runs: list[tuple[np.ndarray, np.ndarray]] = []  # (sorted keys, their values)

    def add(self, keys: np.ndarray, values: np.ndarray) -> None:
        if len(keys) == 0:
            return
        if max(int(keys.max()), int(values.max())) >= 2**31:
            raise OverflowError("certificates: more than 2^31 centres or entries")
        keys, values = keys.astype(np.int32), values.astype(np.int32)
        order = np.argsort(keys, kind="stable")
        self.runs.append((keys[order], values[order]))
        while len(self.runs) > 1 and len(self.runs[-2][0]) <= len(self.runs[-1][0]):  # a binary counter
            (k1, v1), (k2, v2) = self.runs.pop(), self.runs.pop()
            self.runs.append(_merge(k2, v2, k1, v1))

    def find(self, keys: np.ndarray) -> np.ndarray:
        """Every value stored under one of ``keys`` (sorted, unique)."""
        found = []
        keys = keys[keys < 2**31].astype(np.int32)  # searching int32 runs by int64 would copy them
        for run_keys, run_values in self.runs:
            lo = np.searchsorted(run_keys, keys, side="left")
            hi = np.searchsorted(run_keys, keys, side="right")
            counts = hi - lo
            total = int(counts.sum())
            if total:
                starts = np.repeat(lo - np.cumsum(counts) + counts, counts)
                found.append(run_values[starts + np.arange(total)])
        return np.concatenate(found).astype(np.int64) if found else np.zeros(0, dtype=np.int64)


def _merge(k_old, v_old, k_new, v_new) -> tuple[np.ndarray, np.ndarray]:
    """Two sorted runs as one, older pairs first among equal keys. Placing the newer
    run by binary search needs ~14 bytes per pair at the peak; an argsort of the two
    concatenated needed ~24 (its int64 order alone 8), ~0.5 GB more at 20 M pairs."""
    n = len(k_old) + len(k_new)
    at_new = np.searchsorted(k_old, k_new, side="right") + np.arange(len(k_new))
    old = np.ones(n, dtype=bool)
    old[at_new] = False
    keys, values = np.empty(n, dtype=k_old.dtype), np.empty(n, dtype=v_old.dtype)
    keys[at_new], values[at_new] = k_new, v_new
    keys[old], values[old] = k_old, v_old
    return keys, values
