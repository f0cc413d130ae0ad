"""QNT^SPE (paper Alg. 8): synchronous pruning and exploration, with prioritized
sampling and experience replay (Sec. 4.4).

The algorithm state is explicit (``SPE`` holds arrays, no hidden globals) and is
driven ask/tell-style by ``coordinator.campaign``:

    draw(streams)                 start vertices for a batch, from the state as it is now
    scan(batch, rows, ids)        offset of the first run in ``rows`` that changes the state
    apply(batch, row, id)         apply that run's change (prune or explore)
    record(batch, rows, ids)      keep committed runs' states for experience replay
    end_round()                   delta decay (lines 25-27); False after the last round

A run *changes the state* when it fails (line 9: prune reachable(sigma), add sigma to
PhiBar) or visits a state sigma' with d(sigma', Phi_delta) > delta and d(sigma', PhiBar)
> delta (line 15, checked on sigma' as shared/spec/algorithms.md decides).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from coordinator.covering import Lattice
from coordinator.graph import ExplorationForest
from coordinator.runs import first_true_per_run, visited_states
from coordinator.spatial import PointIndex
from scenarios.streams import PURPOSE_START, RunStreams
from scenarios.base import FAILURE, Scenario
from scenarios.run import RunBatch

ALPHAS = {"identity": lambda x: x, "square": np.square, "sqrt": np.sqrt}


@dataclass(frozen=True)
class SPESettings:
    delta0: float = 2.0
    gamma: float = 0.5
    delta_min: float = 0.5
    prioritized: bool = True
    alpha: str = "identity"
    replay: bool = True
    replay_capacity: int = 20_000_000
    reachable: str = "undirected"
    boundary: bool = False


def greedy_uncovered(points: np.ndarray, delta: float) -> np.ndarray:
    """Indices of ``points`` kept when adding them in order and skipping any point
    within l-inf ``delta`` of one already kept (line 15 applied point by point)."""
    kept: list[int] = []
    covered = np.zeros(len(points), dtype=bool)
    for i in range(len(points)):
        if covered[i]:
            continue
        kept.append(i)
        covered[i:] |= np.abs(points[i:] - points[i]).max(axis=1) <= delta + 1e-9
    return np.asarray(kept, dtype=np.int64)


class SPE:
    name = "spe"
    decays = True

    def __init__(self, scenario: Scenario, settings: SPESettings):
        self.scenario = scenario
        self.settings = settings
        n = scenario.n
        self.lattice = Lattice.tiling(scenario.lower, scenario.upper, settings.delta0)
        self.delta = settings.delta0
        bounds = (scenario.lower, scenario.upper)
        self.vertices = PointIndex(n, 2 * self.delta, self.lattice.anchor, bounds=bounds)
        self.failures = PointIndex(n, 2 * self.delta, self.lattice.anchor)
        self.graph = ExplorationForest()
        self._add_roots(self.lattice.box_centres(self.delta))
        self.version = 0
        self.round = 0
        self._replay_states: list[np.ndarray] = []
        self._replay_parents: list[np.ndarray] = []
        self._replay_size = 0
        self._dist: tuple[np.ndarray, int, int] | None = None  # (distances, vertices, failures) seen
        self._draw_cache: tuple | None = None

    # -- helpers --------------------------------------------------------------------------
    def _add_roots(self, centres: np.ndarray) -> None:
        self.vertices.insert(centres)
        self.graph.add_roots(len(centres))

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    def _weights(self, ids: np.ndarray) -> np.ndarray | None:
        """Prioritized sampling: rho_i ~ alpha(d* - d_i), d_i = d(sigma_i, PhiBar)."""
        if not self.settings.prioritized or self.failures.count == 0:
            return None
        dist = self._failure_distances()[ids]
        weights = ALPHAS[self.settings.alpha](dist.max() - dist)
        return weights if weights.sum() > 0 else None  # all equidistant: rho is uniform

    def _failure_distances(self) -> np.ndarray:
        """d(sigma_i, PhiBar) for every vertex id, kept up to date incrementally: a new
        failure lowers every distance in one vectorized pass (failures are few), a new
        vertex asks a KD-tree of the failures (vertices come in bulk)."""
        nv, nf = self.vertices.count, self.failures.count
        pts, fails = self.vertices.points, self.failures.points
        dist, seen_v, seen_f = self._dist if self._dist is not None else (np.empty(0), 0, 0)
        if seen_f == 0:
            seen_v = 0  # nothing known yet: every vertex is new
        if nf > seen_f and seen_v:
            new_f = fails[seen_f:nf]
            if len(new_f) > 32:
                d_new, _ = cKDTree(new_f).query(pts[:seen_v], p=np.inf)
                np.minimum(dist[:seen_v], d_new, out=dist[:seen_v])
            else:
                columns = [np.ascontiguousarray(pts[:seen_v, axis]) for axis in range(pts.shape[1])]
                gap, axis_gap = np.empty(seen_v), np.empty(seen_v)
                for f in new_f:  # l-inf distance per axis: a (V, n) max over n is ~5x slower
                    np.subtract(columns[0], f[0], out=gap)
                    np.abs(gap, out=gap)
                    for axis in range(1, len(columns)):
                        np.subtract(columns[axis], f[axis], out=axis_gap)
                        np.abs(axis_gap, out=axis_gap)
                        np.maximum(gap, axis_gap, out=gap)
                    np.minimum(dist[:seen_v], gap, out=dist[:seen_v])
        if nv > seen_v:
            d_new, _ = cKDTree(fails[:nf]).query(pts[seen_v:nv], p=np.inf)
            dist = np.concatenate([dist[:seen_v], d_new])
        self._dist = (dist, nv, nf)
        return dist

    def _band(self, ids: np.ndarray) -> np.ndarray:
        """Theorem 3 for the quantified set: the alive centres whose boxes come within
        sigma-bar of the set's boundary toward failure. SPE's covering starts as all of
        Sigma, so that boundary is made of pruned regions (within delta of PhiBar) and
        of Sigma's failure facets; truncating facets are not of concern."""
        reach = self.scenario.step_bound() + self.delta
        pts = self.vertices.points[ids]
        near = np.zeros(len(ids), dtype=bool)
        for facet, failure in self.scenario.facets():
            if failure:
                near |= np.abs(pts[:, facet.axis] - facet.bound) <= reach
        if self.failures.count:
            near |= self._failure_distances()[ids] <= reach + self.delta
        return ids[near] if near.any() else ids

    def sampling_description(self) -> str:
        where = (f"the alive centres within sigma-bar + delta = {self.scenario.step_bound() + self.delta:g} of the "
                 f"set's boundary (PhiBar and failure facets, Theorem 3)" if self.settings.boundary
                 else "the alive centres")
        if self.settings.prioritized and self.failures.count:
            return (f"start states drawn over {where} with probability "
                    f"alpha(d* - d_i), alpha = {self.settings.alpha}, d_i = d(sigma_i, PhiBar)")
        return f"start states uniform over {where}"

    # -- ask ----------------------------------------------------------------------------
    def _distribution(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The sampling distribution of the state as it is now: candidate vertex ids and
        their cumulative weights (None: uniform). Cached per state version: in the long
        quiet stretches that end a round, many batches are drawn from one version."""
        if self._draw_cache is not None and self._draw_cache[0] == self.version:
            return self._draw_cache[1], self._draw_cache[2]
        ids = self.vertices.alive_ids()
        if len(ids) == 0:
            raise EmptySetError("the safe set is empty: every centre was pruned")
        if self.settings.boundary:
            ids = self._band(ids)
        weights = self._weights(ids)
        cdf = None if weights is None else np.cumsum(weights)
        self._draw_cache = (self.version, ids, cdf)
        return ids, cdf

    def draw(self, streams: RunStreams) -> tuple[np.ndarray, np.ndarray]:
        ids, cdf = self._distribution()
        u = streams.uniform(0, PURPOSE_START, 1)[:, 0]
        if cdf is None:
            pick = np.minimum((u * len(ids)).astype(np.int64), len(ids) - 1)
        else:
            pick = np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(ids) - 1)
        chosen = ids[pick]
        return self.vertices.points[chosen].copy(), chosen

    # -- tell ---------------------------------------------------------------------------
    def scan(self, batch: RunBatch, rows: np.ndarray, start_ids: np.ndarray):
        """-> (offset of the first state-changing run in ``rows`` or len(rows),
        (offset,) bool: quiet runs that left Phi_delta within delta of PhiBar)."""
        fail = batch.outcomes[rows] == FAILURE
        states, pos = visited_states(batch, rows)
        covered = self.vertices.any_within(states, self.delta)
        uncovered = np.nonzero(~covered)[0]
        near = np.zeros(len(states), dtype=bool)
        if len(uncovered):
            near[uncovered] = self.failures.any_within(states[uncovered], self.delta)
        explore = ~covered & ~near
        change = fail | first_true_per_run(explore, pos, len(rows))
        offset = int(np.argmax(change)) if change.any() else len(rows)
        escaped = first_true_per_run(~covered & near, pos, len(rows))[:offset]
        return offset, escaped

    def apply(self, batch: RunBatch, row: int, start_id: int) -> str:
        """Apply the change of run ``row``; returns "pruned" or "explored"."""
        self.version += 1
        if batch.outcomes[row] == FAILURE:
            # A failing run's explored states would be pruned with sigma at once (they are
            # in reachable(sigma)), so only sigma enters PhiBar and its tree is pruned.
            self.failures.insert(batch.trajectories[0, row][None, :])
            self.vertices.kill(self.graph.reachable(int(start_id), self.settings.reachable))
            return "pruned"
        states, _ = visited_states(batch, np.array([row]))
        new = ~self.vertices.any_within(states, self.delta)
        new[new] = ~self.failures.any_within(states[new], self.delta)
        candidates = states[new]
        kept = candidates[greedy_uncovered(candidates, self.delta)]
        self.vertices.insert(kept)
        self.graph.add_children(int(start_id), len(kept))
        return "explored"

    def record(self, batch: RunBatch, rows: np.ndarray, start_ids: np.ndarray) -> None:
        """Keep the states of committed, non-failing runs for experience replay."""
        if not self.settings.replay or self._replay_size >= self.settings.replay_capacity:
            return
        ok = rows[batch.outcomes[rows] != FAILURE]
        if len(ok) == 0:
            return
        states, pos = visited_states(batch, ok)
        room = self.settings.replay_capacity - self._replay_size
        states, pos = states[:room], pos[:room]
        self._replay_states.append(states)
        self._replay_parents.append(start_ids[np.searchsorted(rows, ok)][pos])
        self._replay_size += len(states)

    # -- round end ---------------------------------------------------------------------
    def end_round(self) -> bool:
        if self.final_round:
            return False
        new_delta = max(self.settings.gamma * self.delta, self.settings.delta_min)
        centres = self.vertices.alive_points()
        children = self.lattice.children(centres, self.delta, new_delta)
        self.delta = new_delta
        self.vertices.recell(2 * new_delta)
        self.failures.recell(2 * new_delta)
        if len(children):
            children = children[~self.failures.any_within(children, new_delta)]
        self._add_roots(children)
        self.round += 1
        self.version += 1
        if self.settings.replay:
            self._replay()
        return True

    def _replay(self) -> int:
        """Experience replay: re-apply line 15 to every stored state at the new delta."""
        if not self._replay_states:
            return 0
        states = np.concatenate(self._replay_states)
        parents = np.concatenate(self._replay_parents)
        new = ~self.vertices.any_within(states, self.delta)
        new[new] = ~self.failures.any_within(states[new], self.delta)
        states, parents = states[new], parents[new]
        added = 0
        chunk = 4096
        for lo in range(0, len(states), chunk):
            part, part_parents = states[lo : lo + chunk], parents[lo : lo + chunk]
            if added:  # points added by earlier chunks may cover these
                fresh = ~self.vertices.any_within(part, self.delta)
                part, part_parents = part[fresh], part_parents[fresh]
            kept = greedy_uncovered(part, self.delta)
            self.vertices.insert(part[kept])
            for parent in part_parents[kept]:
                self.graph.add_children(int(parent), 1)
            added += len(kept)
        return added

    # -- output ---------------------------------------------------------------------------
    def result(self) -> tuple[np.ndarray, float]:
        return self.vertices.alive_points(), self.delta

    def counts(self) -> dict:
        return {"boxes": self.vertices.alive_count, "vertices": self.vertices.count,
                "failures": self.failures.count, "delta": self.delta, "round": self.round}

    # -- persistence --------------------------------------------------------------------
    def state(self) -> dict:
        out = {f"vertices.{k}": v for k, v in self.vertices.state().items()}
        out.update({f"failures.{k}": v for k, v in self.failures.state().items()})
        out["graph.parent"] = self.graph.parent.copy()
        out["scalars"] = np.array([self.delta, self.round, self.version], dtype=float)
        out["replay.states"] = (np.concatenate(self._replay_states) if self._replay_states
                                else np.empty((0, self.scenario.n)))
        out["replay.parents"] = (np.concatenate(self._replay_parents) if self._replay_parents
                                 else np.empty(0, dtype=np.int64))
        return out

    def load_state(self, state: dict) -> None:
        self.vertices = PointIndex.from_state({k[9:]: v for k, v in state.items() if k.startswith("vertices.")})
        self.failures = PointIndex.from_state({k[9:]: v for k, v in state.items() if k.startswith("failures.")})
        self.graph = ExplorationForest.from_state({"parent": state["graph.parent"]})
        delta, rnd, version = state["scalars"]
        self.delta, self.round, self.version = float(delta), int(rnd), int(version)
        self._replay_states = [state["replay.states"]] if len(state["replay.states"]) else []
        self._replay_parents = [state["replay.parents"]] if len(state["replay.parents"]) else []
        self._replay_size = len(state["replay.states"])
        self._dist = None
        self._draw_cache = None


class EmptySetError(RuntimeError):
    """Every candidate was pruned: the quantified safe set is empty."""
