"""QNT^SPE (paper Alg. 8): synchronous pruning and exploration, with prioritized
sampling and experience replay (Sec. 4.4), over explicit state (``SPE`` holds arrays,
no hidden globals), driven ask/tell-style by ``coordinator.driver`` (the contract is
coordinator/algorithm.py).

A run *changes the state* when it fails (line 9: prune reachable(sigma), add sigma to
PhiBar) or visits a state sigma' with d(sigma', Phi_delta) > delta and d(sigma', PhiBar)
> delta (line 15, checked on sigma' as shared/spec/algorithms.md decides).

Certification (the last round, at delta_min: ``begin_certification``): the final set is checked
the way ``validate`` checks a set: a run must neither fail nor leave Phi_delta, near a
known failure or not. A deterministic system runs every final centre once (VAL^delta);
otherwise closing rounds (drawn over the edge: the centres near the failure-side boundary) and checks
(drawn uniformly over the final centres, VAL^eps-delta) alternate as
coordinator/certification.py describes. A run that fails or leaves the set re-opens SPE:
a failure prunes as usual, a new state is explored as usual, and a run that leaves only
toward a known failure prunes its start's tree as a failure would (removing the start
alone, with or without adding it to PhiBar, makes certification peel or churn for many
more runs: docs/benchmarks.md), without adding it to PhiBar: it did not fail. Pruning
on a new state instead of exploring it peels the whole set away (docs/benchmarks.md).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from coordinator.algorithm import Algorithm, EmptySetError, Event, greedy_uncovered
from coordinator.algorithm_settings import SPESettings
from coordinator.spe_certification import SPECertification
from coordinator.buffers import Appendable
from coordinator.certification import CHECK, CLOSING
from coordinator.checked_centres import CheckedCentres
from coordinator.closing_edge import EdgeMembership
from coordinator.coverage import AddFailures, Coverage, Insert, Kill, Recell, Resize
from coordinator.lattice import Lattice
from coordinator.safe_set import SafeSet
from coordinator.enumeration import Enumeration
from coordinator.graph import ExplorationForest
from coordinator.priorities import FailureDistances
from coordinator.experience_replay import ReplayBuffer
from coordinator.refinement import Band
from coordinator.sampler import PrioritySampler
from coordinator.stable_sampler import Draws, Law, StableSampler, UniformLaw, WeightedLaw
from scenarios.base import Scenario
from scenarios.streams import RunStreams

ALPHAS = {"identity": lambda x: x, "square": np.square, "sqrt": np.sqrt}
REPLAY_CHUNK = 4096  # stored states per greedy pass in experience replay


def _cumulative_index(ids: np.ndarray, cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """One of ``ids`` per uniform number u, by the running sums ``cdf`` of their weights."""
    return ids[np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(ids) - 1)]


class SPE(SPECertification, Algorithm):
    name = "spe"
    decays = True
    certifies = True
    restorable = True
    # the checked centres' entries too: the bulk of a certified campaign's state
    append_only = ("vertices.points", "failures.points", "graph.parent", "replay.index", "replay.take",
                   "replay.parent", "replay.start", "cert.vertex", "cert.offsets", "cert.witness", "holes.ids")

    def __init__(self, scenario: Scenario, settings: SPESettings, deterministic: bool = False):
        """``deterministic``: a run is a function of its start state (one adversarial
        action, no disturbance); experience replay then stores each vertex's run once."""
        self.scenario = scenario
        self.settings = settings
        self.deterministic = deterministic
        self.lattice = Lattice.tiling(scenario.lower, scenario.upper, settings.delta0)
        self.coverage = Coverage(scenario.n, settings.delta0, self.lattice.anchor,
                                 bounds=(scenario.lower, scenario.upper), failures=True,
                                 mixed=settings.refine == "band")
        self.band = Band(scenario) if settings.refine == "band" else None
        self.graph = ExplorationForest()
        self.version = 0
        self.round = 0
        self._fresh_samplers()
        self._add_roots(self.lattice.box_centres(self.delta))
        self._stable.restart(self.vertices.count, self.version)
        self.replay = ReplayBuffer(settings.replay_capacity if settings.replay else 0, deterministic, scenario.n)
        self.certifying = False
        self.phase = CHECK  # while certifying a sampled system: CLOSING or CHECK
        self.hole_ids = Appendable(np.int64)  # centres pruned in the last round or since: holes in the set
        self.enumeration = Enumeration()  # deterministic certification: the passes over the centres
        self.checked = CheckedCentres()  # deterministic certification: centres checked

    @property
    def failures(self):
        return self.coverage.failures

    # -- helpers --------------------------------------------------------------------------
    def _fresh_samplers(self) -> None:
        """The samplers' bookkeeping, rebuilt from the state (at start and on resume)."""
        settings = self.settings
        self._dist = FailureDistances(self.scenario.lower, self.scenario.upper,
                                      track_lowered=settings.prioritized or settings.boundary)
        self._sampler = PrioritySampler(ALPHAS[settings.alpha])
        self._stable = StableSampler()
        self._law_cache: tuple | None = None
        self._law_kind: tuple | None = None
        self._edge: tuple[int, np.ndarray] | None = None  # (version, mask): the closing law's candidates
        self._edge_table: Appendable | None = None  # a closing round's slots: per slot, its edge id
        self._edge_slot: np.ndarray | None = None  # per vertex id, its slot in the table (-1: none)
        self._edge_free: list[int] = []  # the table's free slots (-1 there), a heap
        self._edge_track: EdgeMembership | None = None  # a closing round's edge, kept by change
        # min(d(vertex, failure or hole), cap), and those points: ``SPECertification._edge_distances``
        self._edge_reach: FailureDistances | None = None
        self._edge_source_points = Appendable(float, np.empty((0, self.coverage.n)))
        self._edge_sources_in = (0, 0)  # (failures, holes) gathered
        self._edge_share: tuple[int, float] | None = None  # (version, its share of the alive centres)
        self._facet_cache: tuple[float, np.ndarray, int] | None = None  # (reach, per id: near a failure facet, ids filled)

    def _add_roots(self, centres: np.ndarray) -> None:
        self._insert(centres)
        self.graph.add_roots(len(centres))

    def _insert(self, points: np.ndarray, half_width: float | None = None) -> None:
        """New alive centres (their ids follow the count): their slots move draws."""
        first = self.vertices.count
        self.coverage.apply(Insert(points, half_width), self.version)
        self._touch(np.arange(first, self.vertices.count))

    def _touch(self, ids: np.ndarray) -> None:
        """Vertices ``ids`` were inserted or killed: their slots move draws. A closing
        round's slots are the edge table's: the edge's membership changes touch them
        (``_edge_mask``), these ids are not slots there."""
        if self._edge_table is None:
            self._stable.touch(ids, self.version)
        if self._edge_track is not None:
            self._edge_track.touched.append(ids)

    def failure_points(self) -> np.ndarray:
        return self.failures.points[: self.failures.count].copy()

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    def _failure_distances(self) -> np.ndarray:
        """d(sigma_i, PhiBar) for every vertex id, kept up to date incrementally
        (coordinator/priorities.py)."""
        return self._dist.update(self.vertices.points, self.vertices.count, self.failures.points,
                                 self.failures.count)

    def _near_boundary(self, ids: np.ndarray) -> np.ndarray:
        """Theorem 3 for the quantified set: do the boxes of centres ``ids`` come within
        sigma-bar of the set's boundary toward failure? SPE's covering starts as all of
        Sigma, so that boundary is made of pruned regions (within delta of PhiBar) and of
        Sigma's failure facets; truncating facets are not of concern."""
        reach = self.scenario.step_bound() + self.delta
        near = self._facet_near(self.vertices.count, reach)[ids]
        if self.failures.count:
            near |= self._failure_distances()[ids] <= reach + self.delta
        return near

    def _facet_near(self, count: int, reach: float) -> np.ndarray:
        """(count,) bool: the centres within ``reach`` of a failure facet (the part of
        ``_near_boundary`` that never changes for a centre: kept per id, extended to new
        ids in a buffer that doubles, so that inserts between draws cost their own ids)."""
        known = self._facet_cache
        if known is None or known[0] != reach:
            known = (reach, np.zeros(0, dtype=bool), 0)
        _, buffer, filled = known
        if filled < count:
            if count > len(buffer):
                buffer = np.concatenate([buffer[:filled], np.zeros(max(count, 2 * len(buffer)) - filled, dtype=bool)])
            pts = self.vertices.points[filled:count]
            fresh = buffer[filled:count]
            fresh[:] = False
            for facet, failure in self.scenario.facets():
                if failure:
                    fresh |= np.abs(pts[:, facet.axis] - facet.bound) <= reach
            filled = count
        self._facet_cache = (reach, buffer, filled)
        return buffer[:count]

    def _candidate(self, ids: np.ndarray) -> np.ndarray:
        """May centre ``ids`` be drawn (prioritized sampling): alive, and in the boundary
        set (Theorem 3) when ``boundary`` is on."""
        ok = self.vertices.alive[ids]
        if self.settings.boundary:
            ok[ok] = self._near_boundary(ids[ok])
        return ok

    def sampling_description(self) -> str:
        if self.closing:
            return "start states uniform over the alive centres near the failure-side boundary (closing round: the edge)"
        if self.certifying:
            return ("every final box centre once (VAL^delta)" if self.deterministic
                    else "start states uniform over the final box centres (VAL^eps-delta)")
        where = (f"the alive centres within sigma-bar + delta = {self.scenario.step_bound() + self.delta:g} of the "
                 f"set's boundary (PhiBar and failure facets, Theorem 3)" if self.settings.boundary
                 else "the alive centres")
        if self.settings.prioritized and self.failures.count:
            return (f"start states drawn over {where} with probability "
                    f"alpha(d* - d_i), alpha = {self.settings.alpha}, d_i = d(sigma_i, PhiBar)")
        return f"start states uniform over {where}"

    # -- ask ----------------------------------------------------------------------------
    def _alive(self, ids: np.ndarray) -> np.ndarray:
        return self.vertices.alive[ids]

    def _law(self) -> Law:
        """The sampling law of the state as it is now (cached per version): start states
        are drawn from it by each run's own stream (coordinator/stable_sampler.py). What
        changed since the last law is stamped for ``moved``: distances that fell move
        their slots, a new law as a whole (d*, the boundary set emptied, a switch between
        uniform and weighted) moves every draw."""
        if self._law_cache is not None and self._law_cache[0] == self.version:
            return self._law_cache[1]
        if self.vertices.alive_count == 0:
            raise EmptySetError("the safe set is empty: every centre was pruned")
        count = self.vertices.count
        if self.failures.count and (self.settings.prioritized or self.settings.boundary) and not self.certifying:
            # (certification's laws ask no distance of it: its failures are taken in when one does)
            self._failure_distances()
            lowered = self._dist.take_lowered()
            self._stable.touch(lowered, self.version)
            self._sampler.touch(lowered)
        law, kind = self._make_law(count)
        self._stable.fit(law.count, self.version)
        if kind != self._law_kind:
            self._stable.touch_all(self.version)
            self._law_kind = kind
        self._law_cache = (self.version, law)
        return law

    def _make_law(self, count: int) -> tuple[Law, tuple]:
        """-> the law and what identifies it as a whole (a change of it moves every draw).

        Candidates: the alive centres, within the boundary set when ``boundary`` is on
        and it holds any. Prioritized, once a failure is known: rho = alpha(d* - d)
        over the candidates (d* their largest distance), kept up to date where the state
        changed (coordinator/sampler.py); uniform when every weight is zero."""
        if self.closing:
            return self._closing_law(), ("closing",)
        if self.certifying:
            return UniformLaw(count, self._alive, self.vertices.alive_ids), ("certification",)
        alpha = ALPHAS[self.settings.alpha]
        if self.settings.prioritized and self.failures.count:
            if self._sampler.refresh(self._failure_distances(), count, self._candidate) > 0:
                d_star = self._sampler.d_star
                weight = partial(self._weight, d_star, self._failure_distances())
                return WeightedLaw(count, weight, self._sampler.draw, float(alpha(d_star))), ("weighted", d_star)
        ids = self.vertices.alive_ids()
        in_set = False  # the boundary set (Theorem 3) holds any centre
        if self.settings.boundary:
            near = self._near_boundary(ids)
            in_set = bool(near.any())
            ids = ids[near] if in_set else ids
        candidate = self._candidate if in_set else self._alive
        if self.settings.prioritized and self.failures.count:  # rare: every weight zero, or no boundary set
            dist = self._failure_distances()
            weights = np.zeros(count)
            weights[ids] = alpha(dist[ids].max() - dist[ids])
            if weights.sum() > 0:
                cdf = np.cumsum(weights[ids])
                return (WeightedLaw(count, weights.__getitem__, partial(_cumulative_index, ids, cdf),
                                    float(weights.max())), ("explicit", self.version))
        return UniformLaw(count, candidate, lambda: ids), ("uniform", in_set)

    def _weight(self, d_star: float, dist: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """rho = alpha(d* - d) of candidates ``ids``, zero for the others."""
        w = np.zeros(len(ids))
        ok = self._candidate(ids)
        w[ok] = ALPHAS[self.settings.alpha](d_star - dist[ids[ok]])
        return w

    def draw(self, streams: RunStreams) -> Draws:
        if self.certifying and self.deterministic:
            chosen = self.enumeration.next(self.vertices, self.checked, len(streams))
            return Draws.fixed_at(chosen, self.version)
        return self._stable.draw(streams, self._law(), self.version)

    def _forget_draws(self, left: dict, since: int) -> None:
        self._stable.forked(left["_stable"], since, self.version, self.vertices.count)

    def moved(self, draws: Draws) -> np.ndarray:
        if draws.fixed:
            return np.zeros(len(draws), dtype=bool)
        return self._stable.moved(draws, self._law(), self.version)  # the law first: it stamps what changed

    # -- tell ---------------------------------------------------------------------------
    def apply(self, event: Event) -> str:
        """Apply the change of one run; returns "pruned", "explored" or "escaped"."""
        kind = self._apply(event)
        self._edge_after_change()
        return kind

    def _apply(self, event: Event) -> str:
        self.version += 1
        if event.failed:
            # A failing run's explored states would be pruned with sigma at once (they are
            # in reachable(sigma)), so only sigma enters PhiBar and its tree is pruned.
            self.coverage.apply(AddFailures(event.start[None, :]), self.version)
            self._prune(self.graph.reachable(event.start_id, self.settings.reachable))
            return "pruned"
        states = event.states
        new = event.uncovered.copy() if event.uncovered is not None else ~self.vertices.any_within(states, self.delta)
        if event.near_failure is not None:
            new &= ~event.near_failure
        else:
            new[new] = ~self.failures.any_within(states[new], self.delta)
        candidates = states[new]
        if self.certifying and len(candidates) == 0:
            # it left the set only toward known failures: its start's box is not invariant
            self._prune(self.graph.reachable(event.start_id, self.settings.reachable))
            return "escaped"
        kept = candidates[greedy_uncovered(candidates, self.delta)]
        self._insert(kept)
        self.graph.add_children(event.start_id, len(kept))
        return "explored"

    def _prune(self, ids: np.ndarray) -> None:
        """Kill centres ``ids``. With boundary refinement a box coarser than delta is
        split instead: its children at delta take its place, but for those within delta
        of a failure (the pruning reaches it, not all of its volume)."""
        coarse = self.band.coarse(self, ids) if self.band is not None else None
        if self.final_round:
            self.hole_ids.extend(ids[self.vertices.alive[ids]])
        self.enumeration.before_prune(self.vertices, self.checked, ids)
        self.coverage.apply(Kill(ids), self.version)
        self._touch(ids)
        if self.settings.prioritized:  # the sampler's blocks holding them are summed again
            self._sampler.touch(ids)
        self.enumeration.reopened(self.checked.invalidate(ids))
        if coarse is not None and len(coarse):
            self.band.replaced(coarse)
            self._add_roots(self.band.children(self, coarse, self.delta))

    def record(self, chunk, rows: np.ndarray, start_ids: np.ndarray, starts: np.ndarray) -> None:
        """Keep committed, non-failing runs for experience replay (coordinator/experience_replay.py).
        Runs of the final round (and of certification) are not kept: no round end
        follows to replay them, and they are most of a campaign's runs and of the memory
        their trajectories would hold."""
        if self.final_round:
            return
        self.replay.add(chunk, rows, start_ids, starts, self.vertices.count)

    # -- round end ---------------------------------------------------------------------
    def end_round(self) -> bool:
        """Decay delta (lines 25-27): the surviving boxes split into their children at
        the new delta, except children within delta of a failure. Experience replay
        follows (``replay_pieces``, ``apply_replay``)."""
        if self.final_round:
            return False
        new_delta = max(self.settings.gamma * self.delta, self.settings.delta_min)
        if self.band is not None:
            self._refine_band(new_delta)
        else:
            centres = self.vertices.alive_points()
            children = self.lattice.children(centres, self.delta, new_delta)
            self.version += 1
            self.coverage.apply(Recell(new_delta), self.version)
            self._sampler.invalidate()  # the boundary set's reach moves with delta
            if len(children):
                children = children[~self.failures.any_within(children, new_delta)]
            self._add_roots(children)
        self._stable.restart(self.vertices.count, self.version)
        self.round += 1
        return True

    def _refine_band(self, new_delta: float) -> None:
        """Boundary refinement (Theorem 3): only the boxes within sigma-bar + delta of
        the set's failure-side boundary split into their children at ``new_delta`` (and
        become boxes of ``new_delta`` themselves, as every box does under "all"); the
        others keep their size: no run of theirs can leave the set in one step."""
        near, children = self.band.split(self, new_delta)
        self.version += 1
        self.coverage.apply(Recell(new_delta), self.version)
        self.coverage.apply(Resize(near, new_delta), self.version)
        self._sampler.invalidate()  # the boundary set's reach moves with delta
        self._add_roots(children)

    def replay_pieces(self) -> list:
        """Experience replay: every stored run, for its states that are new at the new delta."""
        return list(self.replay.pieces) if self.settings.replay else []

    def apply_replay(self, pieces: list, found: list) -> None:
        """Re-apply line 15 to every stored state that is new at the new delta, in the
        order stored (``found``: per piece, its new states and their runs' positions, as
        the executor screened them)."""
        states, parents = self.replay.candidates(pieces, found)
        self._add_replayed(states, parents)
        if self.final_round:
            self.replay.release()  # no round end follows: the stored states are not needed

    def _add_replayed(self, states: np.ndarray, parents: np.ndarray) -> int:
        added = 0
        for lo in range(0, len(states), REPLAY_CHUNK):
            part, part_parents = states[lo : lo + REPLAY_CHUNK], parents[lo : lo + REPLAY_CHUNK]
            if added:  # points added by earlier chunks may cover these
                fresh = ~self.vertices.any_within(part, self.delta)
                part, part_parents = part[fresh], part_parents[fresh]
            kept = greedy_uncovered(part, self.delta)
            self._insert(part[kept])
            for parent in part_parents[kept]:
                self.graph.add_children(int(parent), 1)
            added += len(kept)
        return added

    def stop_committing(self) -> None:
        self.checked.release_index()  # the reverse index: large, and only prunes use it

    def release(self) -> None:
        self.checked.release()  # its entries
        self.coverage.freeze()  # the spatial indexes: most of a finished campaign's memory
        self.graph = ExplorationForest()
        self._fresh_samplers()

    # -- output ---------------------------------------------------------------------------
    def result(self) -> SafeSet:
        """The quantified set: a box around every alive centre, each at its own half-width."""
        if self.band is None:
            return super().result()
        ids = self.vertices.alive_ids()
        return SafeSet(self.vertices.points[ids], self.coverage.half_widths(ids), self.scenario.state_names)

    def counts(self) -> dict:
        out = {"boxes": self.vertices.alive_count, "vertices": self.vertices.count,
               "failures": self.failures.count, "delta": self.delta, "round": self.round}
        if self.enumerates:
            alive = self.vertices.alive[: self.vertices.count]
            out["certified"] = int(np.count_nonzero(self.checked.certified(self.vertices.count) & alive))
        return out

    # -- persistence --------------------------------------------------------------------
    def state(self) -> dict:
        out = self.coverage.state()
        out["graph.parent"] = self.graph.parent.copy()
        out["scalars"] = np.array([self.delta, self.round, self.version], dtype=float)
        out["certification"] = np.array([self.certifying, self.phase == CLOSING], dtype=np.int64)
        out["certification.drawn"] = np.flatnonzero(self.enumeration.drawn)
        out["holes.ids"] = self.hole_ids.view.copy()
        out.update(self.checked.state())
        out.update(self.replay.state())
        out.update(self._stable.state())
        if self._edge_table is not None:
            out["closing.slots"] = self._edge_table.view.copy()
        out.update(self._edge_reach_state())
        if self.band is not None:
            out.update(self.band.state())
        return out

    def load_state(self, state: dict) -> None:
        self.coverage = Coverage.from_state(state)
        self.graph = ExplorationForest.from_state({"parent": state["graph.parent"]})
        _, rnd, version = state["scalars"]
        self.round, self.version = int(rnd), int(version)
        self.certifying = bool(state["certification"][0])
        closing = len(state["certification"]) > 1 and bool(state["certification"][1])
        self.phase = CLOSING if closing else CHECK
        drawn = np.zeros(self.vertices.count, dtype=bool)
        drawn[state["certification.drawn"]] = True
        self.enumeration = Enumeration(drawn)
        self.hole_ids = Appendable(np.int64, state.get("holes.ids", ()))
        self.checked = CheckedCentres.from_state(state)
        self.replay.load_state(state)
        self._fresh_samplers()
        self._load_edge_reach(state)
        if self.closing:
            self._load_edge_table(state.get("closing.slots"))
        self._stable.load_state(state, self._slot_count(), self.version)
        if self.band is not None:
            self.band.load_state(state)
