"""SPE's certification round (coordinator/certification.py has the scheme): the *edge*
its closing rounds draw from, the switches between closing rounds and checks, and a
deterministic system's run over every final centre (coordinator/enumeration.py,
coordinator/checked_centres.py). A mixin of ``coordinator.spe.SPE``: it reads SPE's state."""

from __future__ import annotations

import numpy as np

from coordinator.certification import CHECK, CLOSING
from coordinator.coverage import Strict
from coordinator.priorities import FailureDistances


class SPECertification:
    @property
    def closing(self) -> bool:
        """In a closing round of a sampled certification (coordinator/certification.py)."""
        return self.certifying and self.phase == CLOSING

    def _edge_mask(self) -> np.ndarray:
        """(count,) bool, per version: the closing law's candidates, the alive centres
        within sigma-bar + delta of the set's boundary toward failure (``_near_boundary``)
        or of a hole in it: a centre of the last round pruned since (its box is outside
        the set now, and runs that reach it leave the set; measured: a third of the
        violations checks found came from such centres when the edge ignored them). The
        whole set when the edge is empty. Ids whose membership changed since the last
        mask are touched: their slots move draws."""
        if self._edge is not None and self._edge[0] == self.version:
            return self._edge[1]
        count = self.vertices.count
        # ``_near_boundary`` over every id at once, without gathering the alive ones' points:
        # this runs after every change of a closing round
        reach = self.scenario.step_bound() + self.delta
        near = self._facet_near(count, reach).copy()
        if self.failures.count:
            near |= self._failure_distances()[:count] <= reach + self.delta
        if self.hole_ids.size:
            radius = self.scenario.step_bound() + 2 * self.delta
            if self._holes is None or self._holes.cap != 2 * radius:  # only "within radius" is asked
                self._holes = FailureDistances(self.scenario.lower, self.scenario.upper, cap=2 * radius)
            holes = self._gathered_holes()
            near |= self._holes.update(self.vertices.points, count, holes, len(holes))[:count] <= radius
        alive = self.vertices.alive[:count]
        mask = alive & near
        if not mask.any():
            mask = alive.copy()
        if self._edge is not None:
            old = self._edge[1]
            self._stable.touch(np.flatnonzero(mask[: len(old)] != old), self.version)
        self._edge = (self.version, mask)
        return mask

    def _gathered_holes(self) -> np.ndarray:
        """The points of ``hole_ids`` (which only grows), each gathered once, not all of
        them again after every change."""
        ids, known = self.hole_ids.view, self._hole_points
        if known.size < len(ids):
            known.extend(self.vertices.points[ids[known.size :]])
        return known.view

    def closing_share(self) -> float:
        """The edge's share of the alive centres (closing rounds: coordinator/certification.py)."""
        mask = self._edge_mask()
        if self._edge_share is None or self._edge_share[0] != self.version:
            self._edge_share = (self.version, float(np.count_nonzero(mask)) / max(self.vertices.alive_count, 1))
        return self._edge_share[1]

    def begin_check(self) -> None:
        """A closing round ended: check the set (uniform over the final centres)."""
        self.version += 1
        self.phase = CHECK

    def begin_closing(self) -> None:
        """A check found a violation (already applied): close the set again."""
        self.version += 1
        self.phase = CLOSING

    def certify_runs(self, start_ids: np.ndarray, witnesses) -> int:
        """Deterministic certification: quiet runs from alive centres among ``start_ids``
        certify them (``Algorithm.certify_runs``); a run from a pruned centre certifies
        nothing, and its witnesses are not asked for. Returns the position of the run
        after which every alive centre is certified, or -1."""
        sel = np.flatnonzero(self.vertices.alive[start_ids])
        if len(sel) == 0:
            return -1
        offsets, ids = witnesses(sel)
        reached = self.enumeration.record(self.vertices, self.checked, start_ids[sel], offsets, ids)
        return int(sel[reached]) if reached >= 0 else -1  # the run that certified the last centre

    def begin_certification(self) -> None:
        """Check the final set the way validate will (see the module docstring)."""
        self.version += 1
        self.certifying = True
        self.phase = CHECK if self.deterministic else CLOSING
        self.coverage.apply(Strict(True), self.version)
        self._stable.restart(self.vertices.count, self.version)
