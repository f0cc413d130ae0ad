"""The lattice of delta-covering sets (paper Definition 1) of boxes and of unions of boxes.

The delta-covering of a box is the grid of centres spaced 2*delta whose l-infinity boxes
of half-width delta tile it; when the box's extent is not a multiple of 2*delta the
tiling overhangs both ends equally, so every centre stays inside the box. Finer
coverings (delta shrinks by gamma) use the same anchor, so with gamma = 1/2 each box
splits exactly into 2^n children.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coordinator.unique import unique_rows


@dataclass(frozen=True)
class Lattice:
    """Centres ``anchor + delta + 2*delta*k`` (k integer vectors), clamped into [lo, hi]."""

    anchor: np.ndarray  # (n,) lower corner of the tiling
    lo: np.ndarray
    hi: np.ndarray

    @staticmethod
    def tiling(lo, hi, delta: float) -> "Lattice":
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        extent = hi - lo
        count = np.maximum(1, np.ceil(extent / (2 * delta) - 1e-9))
        overhang = count * 2 * delta - extent
        return Lattice(lo - overhang / 2, lo, hi)

    def box_centres(self, delta: float) -> np.ndarray:
        """All centres at resolution ``delta`` covering [lo, hi]: (M, n)."""
        axes = []
        for a, lo, hi in zip(self.anchor, self.lo, self.hi):
            k0 = int(np.floor((lo - a) / (2 * delta)))
            k1 = int(np.ceil((hi - a) / (2 * delta)))
            c = a + delta + 2 * delta * np.arange(k0, k1 + 1)
            c = c[(c + delta > lo + 1e-12) & (c - delta < hi - 1e-12)]
            axes.append(np.clip(c, lo, hi))
        grids = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grids], axis=1)

    def children(self, centres: np.ndarray, half_width: float, delta: float) -> np.ndarray:
        """Centres at resolution ``delta`` whose boxes meet the union of the boxes
        ``centres +- half_width``: the covering of that union (deduplicated, sorted)."""
        if len(centres) == 0:
            return np.empty((0, len(self.anchor)))
        k_lo = np.ceil((centres - half_width - self.anchor - delta) / (2 * delta) - 1e-9).astype(np.int64)
        k_hi = np.floor((centres + half_width - self.anchor - delta) / (2 * delta) + 1e-9).astype(np.int64)
        span = (k_hi - k_lo + 1).max(axis=0)
        offsets = np.stack(np.meshgrid(*[np.arange(s) for s in span], indexing="ij"), axis=-1).reshape(-1, len(span))
        ks = (k_lo[:, None, :] + offsets[None, :, :]).reshape(-1, len(span))
        valid = (ks <= np.repeat(k_hi, len(offsets), axis=0)).all(axis=1)
        ks = unique_rows(ks[valid])
        out = self.anchor + delta + 2 * delta * ks
        out = out[((out + delta > self.lo + 1e-12) & (out - delta < self.hi - 1e-12)).all(axis=1)]
        return np.clip(out, self.lo, self.hi)
