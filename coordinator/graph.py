"""The SPE exploration graph G = (Phi_sigma, E) (paper Alg. 8).

Every edge joins a run's start vertex sigma to a state sigma' first discovered by that
run, so G is a forest: each explored vertex has exactly one parent, covering-set
vertices are roots. ``reachable`` is the paper's "all vertices that directly or
indirectly connect to sigma" (the undirected tree of sigma); the ``ancestors`` variant
prunes only the vertices that can reach sigma (the path to its root), which is what
unsafety propagates along.
"""

from __future__ import annotations

import numpy as np


class ExplorationForest:
    def __init__(self):
        self._parent = np.empty(1024, dtype=np.int64)
        self._root = np.empty(1024, dtype=np.int64)
        self.size = 0
        self._members: dict[int, list[int]] = {}  # root -> vertices of its tree (if > 1)

    @property
    def parent(self) -> np.ndarray:
        return self._parent[: self.size]

    @property
    def root(self) -> np.ndarray:
        return self._root[: self.size]

    def __len__(self) -> int:
        return self.size

    def _grow(self, count: int) -> np.ndarray:
        need = self.size + count
        if need > len(self._parent):  # amortized doubling: appends stay O(1)
            cap = max(need, 2 * len(self._parent))
            self._parent = np.resize(self._parent, cap)
            self._root = np.resize(self._root, cap)
        ids = np.arange(self.size, need, dtype=np.int64)
        self.size = need
        return ids

    def add_roots(self, count: int) -> None:
        ids = self._grow(count)
        self._parent[ids] = -1
        self._root[ids] = ids

    def add_children(self, parent: int, count: int) -> None:
        r = int(self._root[parent])
        ids = self._grow(count)
        self._parent[ids] = parent
        self._root[ids] = r
        self._members.setdefault(r, [r]).extend(ids.tolist())

    def reachable(self, vertex: int, mode: str = "undirected") -> np.ndarray:
        if mode == "ancestors":
            out = [vertex]
            p = int(self.parent[vertex])
            while p >= 0:
                out.append(p)
                p = int(self.parent[p])
            return np.asarray(out, dtype=np.int64)
        r = int(self.root[vertex])
        return np.asarray(self._members.get(r, [r]), dtype=np.int64)

    def state(self) -> dict:
        return {"parent": self.parent.copy()}

    @classmethod
    def from_state(cls, state: dict) -> "ExplorationForest":
        forest = cls()
        parent = np.asarray(state["parent"], dtype=np.int64)
        ids = forest._grow(len(parent))
        forest._parent[ids] = parent
        root = np.arange(len(parent), dtype=np.int64)
        for v in np.nonzero(parent >= 0)[0]:  # parents always precede children
            root[v] = root[parent[v]]
        forest._root[ids] = root
        for v in np.nonzero(parent >= 0)[0]:
            forest._members.setdefault(int(root[v]), [int(root[v])]).append(int(v))
        return forest
