"""Points with alive flags: what the point indexes share (``coordinator.spatial.PointIndex``
and ``coordinator.levels.LeveledIndex``), and what is left of one when its campaign is done."""

from __future__ import annotations

import numpy as np


class AlivePoints:
    """What the point indexes share (this one and ``coordinator.levels.LeveledIndex``):
    ``points`` (count, n) with ``alive`` flags, and the common part of their snapshot."""

    def alive_ids(self) -> np.ndarray:
        return np.nonzero(self.alive[: self.count])[0]

    @property
    def alive_count(self) -> int:
        return int(self.alive[: self.count].sum())

    def alive_points(self) -> np.ndarray:
        return self.points[self.alive_ids()]

    def _snapshot(self) -> dict:
        out = {"points": self.points[: self.count].copy(), "alive": self.alive[: self.count].copy(),
               "cell": np.array(self.cell), "origin": self.origin.copy()}
        if self.bounds is not None:
            out["bounds"] = np.stack(self.bounds)
        return out

    @classmethod
    def _empty_for(cls, state: dict):
        """An empty index with the cell, origin and bounds of snapshot ``state``, room for its points."""
        pts, bounds = state["points"], state.get("bounds")
        return cls(pts.shape[1], float(state["cell"]), state["origin"], capacity=2 * len(pts) + 16,
                   bounds=None if bounds is None else (bounds[0], bounds[1]))


class FrozenPoints(AlivePoints):
    """The points, alive flags and half-widths of an index whose campaign is done: what
    its result still reads, without the index structures (the bulk of its memory)."""

    def __init__(self, index: AlivePoints, half_width: np.ndarray | None):
        """``half_width``: one per point (mixed sizes), or None."""
        self.n, self.cell, self.origin, self.bounds = index.n, index.cell, index.origin, index.bounds
        self.count = index.count
        self.points = index.points[: index.count].copy()
        self.alive = index.alive[: index.count].copy()
        self.half_width = None if half_width is None else half_width[: index.count].copy()
