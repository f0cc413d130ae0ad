"""SPE's certification round (coordinator/certification.py has the scheme): the *edge*
its closing rounds draw from, the switches between closing rounds and checks, and a
deterministic system's run over every final centre (coordinator/enumeration.py,
coordinator/checked_centres.py). A mixin of ``coordinator.spe.SPE``: it reads SPE's state."""

from __future__ import annotations

import heapq

import numpy as np

from coordinator.certification import CHECK, CLOSING
from coordinator.closing_edge import EdgeMembership
from coordinator.coverage import Strict
from coordinator.buffers import Appendable
from coordinator.priorities import FailureDistances
from coordinator.stable_sampler import TableLaw

EDGE_REACH = "edge_reach"  # a checkpoint's keys of the edge's distances


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
        whole set when the edge is empty. Within a closing round it is kept change by
        change (coordinator/closing_edge.py), and the slots of the ids whose membership
        changed since the last mask are touched (``_edge_slots_moved``)."""
        if self._edge is not None and self._edge[0] == self.version:
            return self._edge[1]
        count = self.vertices.count
        reach, radius = self._edge_radii()
        track = self._edge_track
        source_d = self._edge_distances(count, radius)
        if track is not None and track.fits(reach, radius):
            was_whole = track.size == 0
            lowered = self._edge_reach.take_lowered() if source_d is not None else np.empty(0, dtype=np.int64)
            ids = track.candidates(count, lowered)
            member = self._edge_near(ids, count, reach, radius, source_d) & self.vertices.alive[ids]
            moved = track.update(ids, member, count)
            if track.size and not was_whole:
                mask = track.core()
                if self._edge_table is not None:
                    self._edge_slots_moved(moved, mask)
                self._edge = (self.version, mask)
                return mask
            core = track.core().copy()
            if not was_whole:  # the last mask was the core's view, written over: as it was
                old = core.copy()
                old[moved] = ~old[moved]
                self._edge = (self._edge[0], old)
        else:
            core = self._edge_core(count, reach, radius, source_d)
            if self.closing:  # kept by change from here on: what fell since is looked at again
                self._edge_track = EdgeMembership(reach, radius, core)
                if source_d is not None:
                    self._edge_reach.take_lowered()
        mask = self._edge_or_set(core)
        if self._edge is not None and self._edge_table is not None:
            old = self._edge[1]
            changed = np.flatnonzero(mask[: len(old)] != old)
            joined = len(old) + np.flatnonzero(mask[len(old) :])
            self._edge_slots_moved(np.concatenate([changed, joined]), mask)
        self._edge = (self.version, mask)
        return mask

    def _edge_radii(self) -> tuple[float, float]:
        """sigma-bar + delta (a failure facet's reach) and sigma-bar + 2 delta (a failure's
        or a hole's: a failure's box reaches delta further)."""
        reach = self.scenario.step_bound() + self.delta
        return reach, reach + self.delta

    def _edge_core(self, count: int, reach: float, radius: float, source_d) -> np.ndarray:
        """(count,) bool over every id: alive and near (the edge computed whole)."""
        return self._edge_near(slice(0, count), count, reach, radius, source_d) & self.vertices.alive[:count]

    def edge_whole(self) -> np.ndarray:
        """The edge as ``_edge_mask`` would compute it whole now: the reference the edge
        kept by change must equal (tests/coordinator/test_closing_edge.py)."""
        count = self.vertices.count
        reach, radius = self._edge_radii()
        return self._edge_or_set(self._edge_core(count, reach, radius, self._edge_distances(count, radius)))

    def _edge_or_set(self, core: np.ndarray) -> np.ndarray:
        """The edge's mask from its membership: the whole set when the edge is empty."""
        return core if core.any() else self.vertices.alive[: len(core)].copy()

    def _edge_near(self, ids, count: int, reach: float, radius: float, source_d) -> np.ndarray:
        """Are centres ``ids`` within ``reach`` of a failure facet or ``radius`` of a
        failure or a hole (``source_d``: their distances, None without either)."""
        near = self._facet_near(count, reach)[ids].copy()  # a slice's view is the facet cache
        if source_d is not None:
            near |= source_d[ids] <= radius
        return near

    def _edge_distances(self, count: int, radius: float) -> np.ndarray | None:
        """min(d(centre, failure or hole), cap) of centres [0, count), the cap just above
        ``radius``, brought up to date (None: no failure and no hole). One structure for
        both, capped: only "within radius" is asked, so a change's new failure and holes
        reach only the buckets within radius of them, not every vertex whose nearest
        failure is farther (in 7-D the uncapped failure distances cost most of a change:
        docs/benchmarks.md)."""
        sources = self._edge_sources()
        if not len(sources):
            return None
        cap = np.nextafter(radius, np.inf)  # min(d, cap) <= radius exactly where d <= radius
        if self._edge_reach is None or self._edge_reach.cap != cap:
            self._edge_reach = FailureDistances(self.scenario.lower, self.scenario.upper, track_lowered=True, cap=cap)
        return self._edge_reach.update(self.vertices.points, count, sources, len(sources))

    def _edge_reach_state(self) -> dict[str, np.ndarray]:
        """The edge's distances for a checkpoint, if they cover every failure and hole and
        vertex now (a closing round's always do: every change brings them up to date)."""
        reach = self._edge_reach
        if reach is None or self._edge_sources_in != (self.failures.count, len(self.hole_ids.view)) or \
                reach.seen_failures != self._edge_source_points.size or reach.seen_vertices != self.vertices.count:
            return {}
        return {f"{EDGE_REACH}.{key}": value for key, value in reach.state().items()}

    def _load_edge_reach(self, state: dict) -> None:
        """The edge's distances as a checkpoint kept them (not computed again from every
        vertex: docs/benchmarks.md); the failures and holes gathered as they cover them."""
        kept = {key[len(EDGE_REACH) + 1 :]: value for key, value in state.items() if key.startswith(EDGE_REACH + ".")}
        if not kept:
            return
        reach = FailureDistances.from_state(self.scenario.lower, self.scenario.upper, kept, track_lowered=True)
        sources = self._edge_sources()
        if reach.seen_failures != len(sources) or reach.seen_vertices != self.vertices.count:
            raise ValueError(f"the kept edge distances cover {reach.seen_vertices} vertices and {reach.seen_failures} "
                             f"failures and holes, the state has {self.vertices.count} and {len(sources)}")
        self._edge_reach = reach

    def _edge_sources(self) -> np.ndarray:
        """The failures' and the holes' points (both only grow), each gathered once, not
        all of them again after every change."""
        known, (failures_in, holes_in) = self._edge_source_points, self._edge_sources_in
        if failures_in < self.failures.count:
            known.extend(self.failures.points[failures_in : self.failures.count])
        holes = self.hole_ids.view
        if holes_in < len(holes):
            known.extend(self.vertices.points[holes[holes_in:]])
        self._edge_sources_in = (self.failures.count, len(holes))
        return known.view

    # -- the closing law's slots: a table of the edge's ids (coordinator/stable_sampler.py TableLaw)
    def _closing_law(self) -> TableLaw:
        """Uniform over the edge, drawn in a slot space of the edge's own ids: the edge is a
        small share of the vertex ids, so draws over the vertex ids mostly fell back to the
        direct draw, which every change moves (docs/benchmarks.md)."""
        mask = self._edge_mask()
        return TableLaw(self._edge_table.view, mask.__getitem__)

    def _new_edge_table(self) -> None:
        """A closing round starts: its slots are the edge's ids in id order (a function of
        the state). The sampler's cap leaves room for the edge to double within the round:
        a cap that grows moves every draw in flight (docs/benchmarks.md)."""
        self._load_edge_table(None)
        self._stable.restart(2 * self._edge_table.size, self.version)

    def _load_edge_table(self, table: np.ndarray | None) -> None:
        """The closing round's slots: ``table`` (a checkpoint's: -1 at a free slot), or
        the edge's ids now."""
        self._edge_table = None  # the mask at this version, nothing touched
        mask = self._edge_mask()
        self._edge_table = Appendable(np.int64, np.flatnonzero(mask) if table is None else table)
        view = self._edge_table.view
        listed = np.flatnonzero(view >= 0)
        self._edge_slot = np.full(len(mask), -1, dtype=np.int64)
        self._edge_slot[view[listed]] = listed
        # the free slots as a heap, lowest first: a search of the table per change is O(edge)
        self._edge_free = np.flatnonzero(view < 0).tolist()  # ascending: a heap already

    def _edge_after_change(self) -> None:
        """A change was applied in a closing round: the ids it brought into the edge take
        their slots now, in the order of the changes. (Left to the next time the law is
        asked, the order would follow when that is, which depends on what is in flight,
        and a result would depend on the window.)"""
        if self._edge_table is not None:
            self._edge_mask()

    def _edge_slots_moved(self, ids: np.ndarray, mask: np.ndarray) -> None:
        """Ids ``ids`` joined or left the edge. The slots of those that left are freed
        (listed -1: never accepted, so no id holds two slots); those new to it take the
        free slots, lowest first, then the next ones (in id order); every slot of theirs
        is touched. Reusing the free slots keeps the table the edge's size, not the count
        of every id that was ever in it: a table that outgrows its cap moves every draw."""
        if len(mask) > len(self._edge_slot):
            grown = np.full(max(len(mask), 2 * len(self._edge_slot)), -1, dtype=np.int64)
            grown[: len(self._edge_slot)] = self._edge_slot
            self._edge_slot = grown
        slots = self._edge_slot[ids]
        inside = mask[ids]
        leaving = (slots >= 0) & ~inside
        left = slots[leaving]
        new = ids[(slots < 0) & inside]
        table = self._edge_table
        free = self._edge_free
        if len(left):
            table.view[left] = -1
            self._edge_slot[ids[leaving]] = -1
            for slot in left.tolist():
                heapq.heappush(free, slot)
        if len(new):
            # the free slots, lowest first
            reused = np.array([heapq.heappop(free) for _ in range(min(len(new), len(free)))], dtype=np.int64)
            fresh = np.arange(table.size, table.size + len(new) - len(reused))
            table.extend(np.zeros(len(fresh), dtype=np.int64))
            at = np.concatenate([reused, fresh])
            table.view[at] = new
            self._edge_slot[new] = at
        self._stable.touch(np.concatenate([left, self._edge_slot[new]]), self.version)

    def _slot_count(self) -> int:
        """The current law's slots: the edge table's in a closing round, else the vertex ids."""
        return self._edge_table.size if self._edge_table is not None else self.vertices.count

    def closing_share(self) -> float:
        """The edge's share of the alive centres (closing rounds: coordinator/certification.py)."""
        mask = self._edge_mask()
        if self._edge_share is None or self._edge_share[0] != self.version:
            track = self._edge_track
            size = track.size if track is not None and track.size else np.count_nonzero(mask)  # (counted: O(ids))
            self._edge_share = (self.version, float(size) / max(self.vertices.alive_count, 1))
        return self._edge_share[1]

    def begin_check(self) -> None:
        """A closing round ended: check the set (uniform over the final centres)."""
        self.version += 1
        self.phase = CHECK
        self._edge_table = self._edge_slot = self._edge_track = None
        self._edge_free = []
        self._stable.restart(self.vertices.count, self.version)

    def begin_closing(self) -> None:
        """A check found a violation (already applied): close the set again."""
        self.version += 1
        self.phase = CLOSING
        self._new_edge_table()

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
        if self.closing:
            self._new_edge_table()
        else:
            self._stable.restart(self.vertices.count, self.version)
