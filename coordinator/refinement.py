"""Boundary refinement (Theorem 3, issue 36): which boxes a round end re-tiles.

A box farther than sigma-bar + delta from the failure-side boundary of the set cannot
leave Phi_delta in one step whatever its size, so refining it changes nothing; SPE with
``refine = "band"`` splits only the boxes near that boundary. The boundary toward failure
is made of

- Sigma's failure facets,
- the neighbourhoods (half-width delta) of the known failures PhiBar, and
- the boxes pruned so far (the holes they left; a coarse box split by a pruning left
  its children, not a hole: ``replaced``).

Box i (centre c, half-width h) is near when a facet lies within sigma-bar + delta + h of
c along its axis, or a hole of half-width h' has its centre within sigma-bar + delta + h +
h' of c on every axis (per axis when the scenario bounds each axis's step). Holes and
boxes come in few half-widths, so each pair of widths is one proximity query in
coordinates scaled to that pair's radii.
"""

from __future__ import annotations

import numpy as np

from coordinator.spatial import PointIndex
from coordinator.unique import unique_ints
from scenarios.base import Scenario


class Band:
    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        self._replaced: list[np.ndarray] = []  # ids of coarse boxes split by a pruning

    def sigma_bar(self) -> np.ndarray:
        """(n,) the step bound per axis (the scenario's, or its scalar one on every axis)."""
        return np.asarray(self.scenario.step_bounds(), dtype=float)

    def coarse(self, spe, ids: np.ndarray) -> np.ndarray:
        """The alive centres among ``ids`` whose boxes are coarser than delta."""
        ids = unique_ints(np.asarray(ids, dtype=np.int64))
        ids = ids[spe.vertices.alive[ids]]
        return ids[spe.coverage.half_widths(ids) > spe.delta * (1 + 1e-9)]

    def replaced(self, ids: np.ndarray) -> None:
        self._replaced.append(np.asarray(ids, dtype=np.int64))

    def _holes(self, spe) -> tuple[np.ndarray, np.ndarray]:
        """(points, half-widths) of what the set lost toward failure."""
        count = spe.vertices.count
        dead = ~spe.vertices.alive[:count]
        if self._replaced:
            dead[np.concatenate(self._replaced)] = False
        ids = np.flatnonzero(dead)
        failures = spe.failures.points[: spe.failures.count]
        points = np.concatenate([spe.vertices.points[ids], failures])
        widths = np.concatenate([spe.coverage.half_widths(ids), np.full(len(failures), spe.delta)])
        return points, widths

    def near(self, spe, ids: np.ndarray, delta: float) -> np.ndarray:
        """(len(ids),) bool: is the box of each alive centre ``ids`` within sigma-bar +
        ``delta`` of the set's failure-side boundary?"""
        sc = self.scenario
        reach = self.sigma_bar() + delta
        centres = spe.vertices.points[ids]
        widths = spe.coverage.half_widths(ids)
        near = np.zeros(len(ids), dtype=bool)
        for facet, failure in sc.facets():
            if failure:
                near |= np.abs(centres[:, facet.axis] - facet.bound) <= reach[facet.axis] + widths
        holes, hole_widths = self._holes(spe)
        if len(holes) == 0:
            return near
        for h in np.unique(widths):
            rows = np.flatnonzero((widths == h) & ~near)
            for h2 in np.unique(hole_widths):
                if len(rows) == 0:
                    break
                radius = reach + h + h2  # (n,): scaled to 1 on every axis
                lo = sc.lower / radius
                index = PointIndex(sc.n, 2.0, lo - 1.0, bounds=(lo, sc.upper / radius))
                index.insert(holes[hole_widths == h2] / radius)
                hit = index.any_within(centres[rows] / radius, 1.0)
                near[rows[hit]] = True
                rows = rows[~hit]
        return near

    def split(self, spe, new_delta: float) -> tuple[np.ndarray, np.ndarray]:
        """A round end: (the alive centres near the boundary, the centres at
        ``new_delta`` tiling their boxes)."""
        ids = spe.vertices.alive_ids()
        near = ids[self.near(spe, ids, spe.delta)]
        return near, self.children(spe, near, new_delta) if len(near) else np.empty((0, self.scenario.n))

    def children(self, spe, ids: np.ndarray, delta: float) -> np.ndarray:
        """The centres at ``delta`` tiling the boxes of centres ``ids`` (at their own
        half-widths), but for those within ``delta`` of a failure."""
        centres = spe.vertices.points[ids]
        widths = spe.coverage.half_widths(ids)
        parts = [spe.lattice.children(centres[widths == w], float(w), delta) for w in np.unique(widths)]
        if not parts:
            return np.empty((0, self.scenario.n))
        children = np.unique(np.concatenate(parts), axis=0) if len(parts) > 1 else parts[0]
        if len(children) and spe.failures.count:
            children = children[~spe.failures.any_within(children, delta)]
        return children

    # -- persistence -------------------------------------------------------------------------
    def state(self) -> dict:
        ids = np.concatenate(self._replaced) if self._replaced else np.zeros(0, dtype=np.int64)
        return {"refine.replaced": ids}

    def load_state(self, state: dict) -> None:
        self._replaced = [np.asarray(state.get("refine.replaced", np.zeros(0)), dtype=np.int64)]
