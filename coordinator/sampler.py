"""Prioritized sampling of start centres (paper Sec. 4.4, rho_i ~ alpha(d* - d_i)),
kept up to date where the state changed instead of rebuilt over every centre.

Vertex ids are cut into blocks of ``BLOCK`` ids. Each block keeps the running sums of
its centres' weights (zero for a dead or excluded centre). A draw takes one uniform
number u: u * total picks a block against the blocks' totals, the rest of it picks the
centre inside the block against that block's running sums. Between two draws only the
blocks whose centres changed (killed, added, moved nearer a failure) are summed again,
and every block when d* (the largest distance among the candidates) changes, which is
rare against the changes of state; rebuilding one cumulative sum over all centres at
every change would dominate a fine campaign (docs/benchmarks.md).

The draw is exact for rho: block b is picked with probability W_b / W, centre i in it
with w_i / W_b. It regroups the sums of one cumulative sum over all candidates, so it
starts a run from the same centre as that did unless u * W falls within rounding error
of a boundary between two centres (about one draw in 10^5 or fewer;
tests/coordinator/test_sampler.py). Every sum is of the same float64 weights in the
same order whichever way a block was last summed, so the draws depend only on the
state, not on the bookkeeping (the same test checks a campaign's sampler against a
fresh build at every change).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from coordinator.unique import unique_ints

BLOCK = 256  # ids per block: a draw reads one row of BLOCK sums per run


class PrioritySampler:
    """Blocked cumulative weights over vertex ids [0, count)."""

    def __init__(self, alpha: Callable[[np.ndarray], np.ndarray]):
        self.alpha = alpha
        self.count = 0
        self.blocks = 0
        # per block (rows beyond ``blocks`` are spare capacity): the running sums of its
        # weights, the position of its last positive weight, its largest candidate
        # distance (-inf: no candidate)
        self.cum = np.zeros((0, BLOCK))
        self.last = np.zeros(0, dtype=np.int64)
        self.block_max = np.zeros(0)
        self.d_star: float | None = None
        self.top = np.zeros(0)  # running sums of the blocks' totals
        self._last_block = 0  # the last block with positive weight
        self._touched: list[np.ndarray] = []

    def touch(self, ids: np.ndarray) -> None:
        """Centres whose weight may have changed (killed, moved nearer a failure)."""
        if len(ids):
            self._touched.append(np.asarray(ids, dtype=np.int64))

    def invalidate(self) -> None:
        """Sum every block again at the next refresh (the candidates' rule changed)."""
        self.d_star = None

    def refresh(self, dist: np.ndarray, count: int, candidate: Callable[[np.ndarray], np.ndarray]) -> float:
        """Bring the sums up to date for vertex ids [0, ``count``) with distances ``dist``
        and ``candidate(ids) -> bool`` (may the centre be drawn); -> the total weight."""
        blocks = -(-count // BLOCK)
        if self.d_star is None:
            dirty = np.arange(blocks)
        else:
            parts = [np.arange(self.count // BLOCK, blocks)]  # blocks with new ids
            parts += [unique_ints(ids // BLOCK) for ids in self._touched]
            dirty = unique_ints(np.concatenate(parts))
        self._touched = []
        self._grow(blocks)
        self.count, self.blocks = count, blocks
        d = self._distances(dirty, dist, candidate)
        self.block_max[dirty] = d.max(axis=1) if len(dirty) else self.block_max[dirty]
        d_star = float(self.block_max[:blocks].max()) if blocks else -np.inf
        if d_star != self.d_star:  # every weight moves with d*
            if len(dirty) < blocks:
                dirty = np.arange(blocks)
                d = self._distances(dirty, dist, candidate)
            self.d_star = d_star
        self._sum(dirty, d)
        totals = self.cum[:blocks, -1]
        self.top = np.cumsum(totals)
        positive = np.flatnonzero(totals > 0)
        self._last_block = int(positive[-1]) if len(positive) else 0
        return float(self.top[-1]) if blocks else 0.0

    def draw(self, u: np.ndarray) -> np.ndarray:
        """Vertex ids for uniform numbers ``u`` in [0, 1) (after a refresh that found a
        positive total weight)."""
        target = u * self.top[-1]
        # 'right': a block (or centre) of zero weight adds nothing to the running sum
        # and is never picked; the clamps catch u * total rounding up to a block's end
        block = np.minimum(np.searchsorted(self.top, target, side="right"), self._last_block)
        rest = target - np.where(block > 0, self.top[block - 1], 0.0)
        return block * BLOCK + np.minimum(self._count_at_most(block, rest), self.last[block])

    def _count_at_most(self, block: np.ndarray, rest: np.ndarray) -> np.ndarray:
        """Per draw, how many of its block's running sums are <= its rest: a binary search
        per row, vectorized over the draws (the running sums never decrease: weights are
        >= 0), instead of comparing all BLOCK sums of each row. Binary lifting over the
        first BLOCK - 1 sums, then the last one: every step reads one sum per draw, with
        no masks (a masked step cost ~5 numpy calls more, 5% of a campaign's driver)."""
        flat = self.cum.reshape(-1)
        base = block * BLOCK - 1
        pos = np.zeros(len(block), dtype=np.int64)
        step = BLOCK // 2
        while step:
            pos += step * (flat[base + pos + step] <= rest)
            step //= 2
        pos += flat[base + pos + 1] <= rest  # pos <= BLOCK - 1 here: the last sum decides BLOCK
        return pos

    # -- internals --------------------------------------------------------------------------
    def _distances(self, blocks: np.ndarray, dist: np.ndarray, candidate) -> np.ndarray:
        """(len(blocks), BLOCK) the distances of the blocks' candidates, -inf elsewhere."""
        ids = (blocks[:, None] * BLOCK + np.arange(BLOCK)).ravel()
        d = np.full(len(ids), -np.inf)
        ok = ids < self.count
        ok[ok] = candidate(ids[ok])
        d[ok] = dist[ids[ok]]
        return d.reshape(len(blocks), BLOCK)

    def _sum(self, blocks: np.ndarray, d: np.ndarray) -> None:
        """Weights alpha(d* - d) of the candidates (d > -inf), zero elsewhere; their
        running sums, row by row."""
        ok = np.isfinite(d)
        w = np.zeros(d.shape)
        w[ok] = self.alpha(self.d_star - d[ok])
        self.cum[blocks] = np.cumsum(w, axis=1)
        positive = w > 0
        self.last[blocks] = np.where(positive.any(axis=1), BLOCK - 1 - np.argmax(positive[:, ::-1], axis=1), 0)

    def _grow(self, blocks: int) -> None:
        have = len(self.cum)
        if blocks <= have:
            return
        size = max(blocks, 2 * have, 64)  # doubling: appends cost O(1) per block
        cum = np.zeros((size, BLOCK))
        cum[:have] = self.cum
        last = np.zeros(size, dtype=np.int64)
        last[:have] = self.last
        block_max = np.full(size, -np.inf)
        block_max[:have] = self.block_max
        self.cum, self.last, self.block_max = cum, last, block_max
