"""QNT^SPE (paper Alg. 8): synchronous pruning and exploration, with prioritized
sampling and experience replay (Sec. 4.4), over explicit state (``SPE`` holds arrays,
no hidden globals), driven ask/tell-style by ``coordinator.campaign`` (the contract is
coordinator/algorithm.py).

A run *changes the state* when it fails (line 9: prune reachable(sigma), add sigma to
PhiBar) or visits a state sigma' with d(sigma', Phi_delta) > delta and d(sigma', PhiBar)
> delta (line 15, checked on sigma' as shared/spec/algorithms.md decides).

Certification (after the last round, ``begin_certification``): the final set is checked
the way ``validate`` checks a set: a run must neither fail nor leave Phi_delta, near a
known failure or not. A deterministic system runs every final centre once (VAL^delta);
otherwise start states are drawn uniformly over the final centres (VAL^eps-delta) until
N_eps runs in a row pass. A run that fails or leaves the set re-opens SPE: a failure
prunes as usual, a new state is explored as usual, and a run that leaves only toward a
known failure prunes its start's tree as a failure would (removing the start alone, with
or without adding it to PhiBar, makes certification peel or churn for many more runs:
docs/benchmarks.md), without adding it to PhiBar: it did not fail.
Certification then starts again, so the set exported is the one the last one passed.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from coordinator.algorithm import Algorithm, EmptySetError, Event, greedy_uncovered, uniform_index, uniform_pick
from coordinator.certificates import Certificates
from coordinator.coverage import AddFailures, Coverage, Insert, Kill, Recell, Strict
from coordinator.lattice import Lattice
from coordinator.enumeration import Enumeration
from coordinator.graph import ExplorationForest
from coordinator.priorities import FailureDistances
from coordinator.experience_replay import ReplayBuffer
from coordinator.sampler import PrioritySampler
from scenarios.base import Scenario
from scenarios.streams import PURPOSE_START, RunStreams

ALPHAS = {"identity": lambda x: x, "square": np.square, "sqrt": np.sqrt}
REPLAY_CHUNK = 4096  # stored states per greedy pass in experience replay


def _cumulative_index(ids: np.ndarray, cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """One of ``ids`` per uniform number u, by the running sums ``cdf`` of their weights."""
    return ids[np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(ids) - 1)]


@dataclass(frozen=True)
class SPESettings:
    """The algorithm's parameters (the config's [quantify] section carries the same
    names and takes its defaults from here)."""

    delta0: float = 2.0
    gamma: float = 0.5
    delta_min: float = 0.5
    prioritized: bool = True
    alpha: str = "identity"
    replay: bool = True
    replay_capacity: int = 20_000_000
    reachable: str = "undirected"
    boundary: bool = False


class SPE(Algorithm):
    name = "spe"
    decays = True
    certifies = True
    # certificates' entries too: the bulk of a certified campaign's state
    append_only = ("vertices.points", "failures.points", "graph.parent", "replay.index", "replay.take",
                   "replay.parent", "replay.start", "cert.vertex", "cert.offsets", "cert.witness")

    def __init__(self, scenario: Scenario, settings: SPESettings, deterministic: bool = False):
        """``deterministic``: a run is a function of its start state (one adversarial
        action, no disturbance); experience replay then stores each vertex's run once."""
        self.scenario = scenario
        self.settings = settings
        self.deterministic = deterministic
        self.lattice = Lattice.tiling(scenario.lower, scenario.upper, settings.delta0)
        self.coverage = Coverage(scenario.n, settings.delta0, self.lattice.anchor,
                                 bounds=(scenario.lower, scenario.upper), failures=True)
        self.graph = ExplorationForest()
        self.version = 0
        self.round = 0
        self._add_roots(self.lattice.box_centres(self.delta))
        self.replay = ReplayBuffer(settings.replay_capacity if settings.replay else 0, deterministic, scenario.n)
        self._dist = FailureDistances(scenario.lower, scenario.upper, track_lowered=settings.prioritized)
        self._sampler = PrioritySampler(ALPHAS[settings.alpha])
        self._draw_cache: tuple | None = None
        self.certifying = False
        self.enumeration = Enumeration()  # deterministic certification: the passes over the centres
        self.certificates = Certificates()  # deterministic certification: centres checked

    @property
    def failures(self):
        return self.coverage.failures

    # -- helpers --------------------------------------------------------------------------
    def _add_roots(self, centres: np.ndarray) -> None:
        self.coverage.apply(Insert(centres), self.version)
        self.graph.add_roots(len(centres))

    def failure_points(self) -> np.ndarray:
        return self.failures.points[: self.failures.count].copy()

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    def _weights(self, ids: np.ndarray) -> np.ndarray | None:
        """Prioritized sampling: rho_i ~ alpha(d* - d_i), d_i = d(sigma_i, PhiBar), over
        ``ids`` in one array (the sampler's fallback, see ``_distribution``)."""
        if not self.settings.prioritized or self.failures.count == 0:
            return None
        dist = self._failure_distances()[ids]
        weights = ALPHAS[self.settings.alpha](dist.max() - dist)
        return weights if weights.sum() > 0 else None  # all equidistant: rho is uniform

    def _failure_distances(self) -> np.ndarray:
        """d(sigma_i, PhiBar) for every vertex id, kept up to date incrementally
        (coordinator/priorities.py)."""
        return self._dist.update(self.vertices.points, self.vertices.count, self.failures.points,
                                 self.failures.count)

    def _band(self, ids: np.ndarray) -> np.ndarray:
        """Theorem 3 for the quantified set: the alive centres whose boxes come within
        sigma-bar of the set's boundary toward failure. SPE's covering starts as all of
        Sigma, so that boundary is made of pruned regions (within delta of PhiBar) and
        of Sigma's failure facets; truncating facets are not of concern."""
        near = self._near_boundary(ids)
        return ids[near] if near.any() else ids

    def _near_boundary(self, ids: np.ndarray) -> np.ndarray:
        reach = self.scenario.step_bound() + self.delta
        pts = self.vertices.points[ids]
        near = np.zeros(len(ids), dtype=bool)
        for facet, failure in self.scenario.facets():
            if failure:
                near |= np.abs(pts[:, facet.axis] - facet.bound) <= reach
        if self.failures.count:
            near |= self._failure_distances()[ids] <= reach + self.delta
        return near

    def _candidate(self, ids: np.ndarray) -> np.ndarray:
        """May centre ``ids`` be drawn (prioritized sampling): alive, and in the band
        near the boundary when ``boundary`` is on."""
        ok = self.vertices.alive[ids]
        if self.settings.boundary:
            ok[ok] = self._near_boundary(ids[ok])
        return ok

    def sampling_description(self) -> str:
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
    def _distribution(self):
        """The sampling distribution of the state as it is now: ``pick(u) -> vertex ids``
        for uniform numbers u. Cached per state version: in the long quiet stretches
        that end a round, many batches are drawn from one version.

        Prioritized sampling keeps its weights up to date where the state changed
        (coordinator/sampler.py); when they are all zero (every candidate at d*, or no
        centre in the boundary band) rho is as ``_weights`` says over all candidates."""
        if self._draw_cache is not None and self._draw_cache[0] == self.version:
            return self._draw_cache[1]
        pick = None  # a positive total weight implies an alive centre
        if self.settings.prioritized and self.failures.count:
            dist = self._failure_distances()
            self._sampler.touch(self._dist.take_lowered())
            if self._sampler.refresh(dist, self.vertices.count, self._candidate) > 0:
                pick = self._sampler.draw
        if pick is None:
            ids = self.vertices.alive_ids()
            if len(ids) == 0:
                raise EmptySetError("the safe set is empty: every centre was pruned")
            if self.settings.boundary:
                ids = self._band(ids)
            weights = self._weights(ids)
            pick = partial(uniform_index, ids) if weights is None else partial(_cumulative_index, ids,
                                                                                 np.cumsum(weights))
        self._draw_cache = (self.version, pick)
        return pick

    def draw(self, streams: RunStreams) -> tuple[np.ndarray, np.ndarray]:
        if self.certifying:
            return self._draw_certification(streams)
        pick = self._distribution()
        chosen = pick(streams.uniform(0, PURPOSE_START, 1)[:, 0])
        return self.vertices.points[chosen].copy(), chosen

    def _draw_certification(self, streams: RunStreams) -> tuple[np.ndarray, np.ndarray]:
        if self.deterministic:
            chosen = self.enumeration.next(self.vertices, self.certificates, len(streams))
        else:
            ids = self.vertices.alive_ids()
            if len(ids) == 0:
                raise EmptySetError("the safe set is empty: every centre was pruned")
            chosen = uniform_pick(ids, streams)
        return self.vertices.points[chosen].copy(), chosen

    def certify_runs(self, chunk, rows: np.ndarray, start_ids: np.ndarray, trusted: np.ndarray) -> int:
        """Deterministic certification: quiet runs ``rows`` of ``chunk`` (``trusted``: their
        screening's witnesses are current) certify their start centres. Returns the row
        after which every alive centre is certified, or -1."""
        sc = chunk.screening
        keep = trusted & self.vertices.alive[start_ids]
        if keep.any():
            sel = rows[keep]
            counts = sc.witness_offsets[sel + 1] - sc.witness_offsets[sel]
            run = np.repeat(np.arange(len(sel)), counts)
            within = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
            witnesses = sc.witnesses[sc.witness_offsets[sel][run] + within]
            offsets = np.zeros(len(sel) + 1, dtype=np.int64)
            np.cumsum(counts, out=offsets[1:])
            reached = self.enumeration.record(self.vertices, self.certificates, start_ids[keep], offsets, witnesses)
            if reached >= 0:  # the row at which the last uncertified centre got its certificate
                return int(sel[reached])
        return -1

    def begin_certification(self) -> None:
        """Check the final set the way validate will (see the module docstring)."""
        self.version += 1
        self.certifying = True
        self.coverage.apply(Strict(True), self.version)

    # -- tell ---------------------------------------------------------------------------
    def apply(self, event: Event) -> str:
        """Apply the change of one run; returns "pruned", "explored" or "escaped"."""
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
        self.coverage.apply(Insert(kept), self.version)
        self.graph.add_children(event.start_id, len(kept))
        return "explored"

    def _prune(self, ids: np.ndarray) -> None:
        self.enumeration.before_prune(self.vertices, self.certificates, ids)
        self.coverage.apply(Kill(ids), self.version)
        if self.settings.prioritized:  # the sampler's blocks holding them are summed again
            self._sampler.touch(ids)
        self.enumeration.reopened(self.certificates.invalidate(ids))

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
        centres = self.vertices.alive_points()
        children = self.lattice.children(centres, self.delta, new_delta)
        self.version += 1
        self.coverage.apply(Recell(new_delta), self.version)
        self._sampler.invalidate()  # the boundary band's reach moves with delta
        if len(children):
            children = children[~self.failures.any_within(children, new_delta)]
        self._add_roots(children)
        self.round += 1
        return True

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
            self.coverage.apply(Insert(part[kept]), self.version)
            for parent in part_parents[kept]:
                self.graph.add_children(int(parent), 1)
            added += len(kept)
        return added

    def stop_committing(self) -> None:
        self.certificates.release_index()  # the reverse index: large, and only prunes use it

    def release(self) -> None:
        self.certificates.release()  # its entries

    # -- output ---------------------------------------------------------------------------
    def counts(self) -> dict:
        out = {"boxes": self.vertices.alive_count, "vertices": self.vertices.count,
               "failures": self.failures.count, "delta": self.delta, "round": self.round}
        if self.enumerates:
            alive = self.vertices.alive[: self.vertices.count]
            out["certified"] = int(np.count_nonzero(self.certificates.certified(self.vertices.count) & alive))
        return out

    # -- persistence --------------------------------------------------------------------
    def state(self) -> dict:
        out = self.coverage.state()
        out["graph.parent"] = self.graph.parent.copy()
        out["scalars"] = np.array([self.delta, self.round, self.version], dtype=float)
        out["certification"] = np.array([self.certifying], dtype=np.int64)
        out["certification.drawn"] = np.flatnonzero(self.enumeration.drawn)
        out.update(self.certificates.state())
        out.update(self.replay.state())
        return out

    def load_state(self, state: dict) -> None:
        self.coverage = Coverage.from_state(state)
        self.graph = ExplorationForest.from_state({"parent": state["graph.parent"]})
        _, rnd, version = state["scalars"]
        self.round, self.version = int(rnd), int(version)
        self.certifying = bool(state["certification"][0])
        drawn = np.zeros(self.vertices.count, dtype=bool)
        drawn[state["certification.drawn"]] = True
        self.enumeration = Enumeration(drawn)
        self.certificates = Certificates.from_state(state)
        self.replay.load_state(state)
        self._dist = FailureDistances(self.scenario.lower, self.scenario.upper,
                                      track_lowered=self.settings.prioritized)
        self._sampler = PrioritySampler(ALPHAS[self.settings.alpha])
        self._draw_cache = None
