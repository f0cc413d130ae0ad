"""Which final centres a deterministic certification has checked, and why that still holds.

In a deterministic system a centre's run is always the same run, so one run that stays
in the set (no failure, every state within delta of an alive centre: a strict quiet
screening) certifies its centre for as long as the centres that covered its states (its
witnesses) are alive: more centres can only cover more, and a run's states do not
change. A run drawn before a change therefore still certifies its centre after the
change if its witnesses survived, and only centres whose witnesses were pruned (and new
centres) need a run again. That is VAL^delta (every centre once) on the final set,
without re-running what a change did not touch.
"""

from __future__ import annotations

import numpy as np


class Certificates:
    def __init__(self):
        self.vertex = np.empty(0, dtype=np.int64)  # (E,) the centre each entry certifies
        self.offsets = np.zeros(1, dtype=np.int64)  # (E + 1,) its witnesses: witness[off[e]:off[e+1]]
        self.witness = np.empty(0, dtype=np.int64)
        self.valid = np.empty(0, dtype=bool)  # (E,) its witnesses are all alive
        self._by_vertex = np.empty(0, dtype=bool)  # vertex -> has a valid entry

    def certified(self, count: int) -> np.ndarray:
        """(count,) bool: vertex ids with a valid certificate."""
        out = np.zeros(count, dtype=bool)
        n = min(count, len(self._by_vertex))
        out[:n] = self._by_vertex[:n]
        return out

    def add(self, vertices: np.ndarray, witness_offsets: np.ndarray, witnesses: np.ndarray) -> None:
        """Entries for ``vertices`` (their runs' witnesses in CSR form)."""
        if len(vertices) == 0:
            return
        self.vertex = np.concatenate([self.vertex, vertices])
        self.offsets = np.concatenate([self.offsets, self.offsets[-1] + witness_offsets[1:]])
        self.witness = np.concatenate([self.witness, witnesses])
        self.valid = np.concatenate([self.valid, np.ones(len(vertices), dtype=bool)])
        top = int(vertices.max()) + 1
        if len(self._by_vertex) < top:
            grown = np.zeros(top, dtype=bool)
            grown[: len(self._by_vertex)] = self._by_vertex
            self._by_vertex = grown
        self._by_vertex[vertices] = True

    def invalidate(self, alive: np.ndarray) -> None:
        """After a prune: entries with a dead witness (or a dead centre) no longer hold."""
        if not self.valid.any():
            return
        dead = ~alive[self.witness]
        dead_before = np.zeros(len(dead) + 1, dtype=np.int64)
        np.cumsum(dead, out=dead_before[1:])
        broken = (dead_before[self.offsets[1:]] > dead_before[self.offsets[:-1]]) | ~alive[self.vertex]
        self.valid &= ~broken
        self._by_vertex[:] = False
        self._by_vertex[self.vertex[self.valid]] = True

    # -- persistence ----------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        return {"cert.vertex": self.vertex, "cert.offsets": self.offsets, "cert.witness": self.witness,
                "cert.valid": self.valid}

    @classmethod
    def from_state(cls, state: dict) -> "Certificates":
        out = cls()
        if "cert.vertex" in state and len(state["cert.vertex"]):
            out.vertex, out.offsets = state["cert.vertex"].astype(np.int64), state["cert.offsets"].astype(np.int64)
            out.witness, out.valid = state["cert.witness"].astype(np.int64), state["cert.valid"].astype(bool)
            out._by_vertex = np.zeros(int(out.vertex.max()) + 1, dtype=bool)
            out._by_vertex[out.vertex[out.valid]] = True
        return out
