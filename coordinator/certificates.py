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
centre through a reverse index (witness -> entries) rebuilt when the entries appended
since its last build outnumber those it covers (amortized O(log) per witness).
"""

from __future__ import annotations

import numpy as np


REBUILD_MIN = 65536  # witnesses: below this a linear scan of the tail is as cheap


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
        self._rev_start = np.zeros(1, dtype=np.int64)  # reverse index over witnesses [0, _rev_w)
        self._rev_entry = np.zeros(0, dtype=np.int64)
        self._rev_w = 0

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
        self._valid.extend(np.ones(len(vertices), dtype=bool))
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
        self._refresh_reverse()
        hit = [self._entries_naming(killed)]
        recent = self._witness.view[self._rev_w :]
        if len(recent):
            mark = np.zeros(max(int(recent.max()), int(killed.max())) + 1, dtype=bool)
            mark[killed] = True
            pos = self._rev_w + np.flatnonzero(mark[recent])
            hit.append(np.searchsorted(self._offsets.view, pos, side="right") - 1)
        entries = np.unique(np.concatenate(hit))
        entries = entries[self._valid.view[entries]]
        self._valid.view[entries] = False
        np.subtract.at(self._count, self._vertex.view[entries], 1)

    def _entries_naming(self, killed: np.ndarray) -> np.ndarray:
        killed = killed[killed < len(self._rev_start) - 1]
        lo, hi = self._rev_start[killed], self._rev_start[killed + 1]
        counts = hi - lo
        if counts.sum() == 0:
            return np.zeros(0, dtype=np.int64)
        starts = np.repeat(lo - np.cumsum(counts) + counts, counts)
        return self._rev_entry[starts + np.arange(int(counts.sum()))]

    def _refresh_reverse(self) -> None:
        """Rebuild witness -> entries once the uncovered tail outgrows the covered part."""
        w = self._witness.size
        if w - self._rev_w <= max(self._rev_w, REBUILD_MIN):
            return
        witness = self._witness.view
        entry = np.repeat(np.arange(self._vertex.size), np.diff(self._offsets.view))
        order = np.argsort(witness, kind="stable")
        self._rev_entry = entry[order]
        self._rev_start = np.zeros(int(witness.max()) + 2, dtype=np.int64)
        np.cumsum(np.bincount(witness, minlength=len(self._rev_start) - 1), out=self._rev_start[1:])
        self._rev_w = w

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
            valid_vertices = out._vertex.view[out._valid.view]
            out._count = np.bincount(valid_vertices, minlength=int(out._vertex.view.max()) + 1).astype(np.int64)
        return out
