"""Margin refinement: the safe set of a deterministic system (one adversarial action, no
disturbance) found by refining a partition of Sigma only where its boundary lies, along
only the axes the boundary crosses there (docs/refinement.md, "Margin refinement").

Every box of the partition (coordinator/margin/partition.py) is decided by one run from
its centre: safe, or failing; the run's *margin* (its smallest distance to a failure
facet, negative past one: scenarios/rollout.py) says how close it came. Waves of runs
alternate with decisions: a box is split, along the axes coordinator/margin/split_rule.py
picks from its own and its face neighbours' margins, when the boundary may cross it and
its half-width there is above the round's delta; its children form the next wave.
Rounds lower delta from delta0 by gamma down to delta_min, as SPE's do: a round ends
when no box wants a split it may make, and the boxes that wanted one but were at the
round's delta are looked at again in the next round. Boxes far from the boundary keep
the size they had: the runs go where the boundary is.

The last round (at delta_min) places the boundary by the margin rather than by halving:
a box whose claim is in doubt is bisected there only while it is more than one halving
coarser than delta_min along some axis (the cut cannot finish it), and then
``CUT_PASSES`` passes cut every box the boundary crosses at the margin's zero crossing
along one axis (coordinator/margin/cut_rule.py): two runs per box, where halving down
to delta_min on both sides of the boundary took four per box, wave after wave
(docs/margin_refinement.md, "The last round cuts", has the measurements).

The set is then certified without new runs (coordinator/margin/invariance.py): the
largest set of claimed boxes whose centre runs visit only boxes of the set. A safe box
is *claimed* when its centre's margin clears the change the margin may make across the
box (``m > KAPPA R``, the split rule's own test of "the boundary may cross this box"):
at the finest resolution a box the boundary may still cross is left out rather than
claimed whole. This is what keeps the set's precision up in 7 and 9 dimensions, where a
box split along its steepest axes stays coarse along the others.
"""

from __future__ import annotations

import numpy as np

from coordinator.algorithm_settings import SPESettings
from coordinator.margin.invariance import largest_invariant
from coordinator.margin.cut_rule import CUT_PASSES, cuts
from coordinator.margin.partition import Partition
from coordinator.margin.split_rule import KAPPA, Neighbourhood, choose, first_order_change, spans_sigma, wanted_axes
from coordinator.margin.visits import Visits
from coordinator.safe_set import COVERING_MARGIN, SafeSet
from coordinator.unique import unique_ints
from scenarios.base import FAILURE, Scenario

DECIDE_BLOCK = 1 << 16  # boxes decided at once (their neighbourhoods held together)


class MarginRefinement:
    name = "margin"
    deterministic = True
    certifying = False  # (the driver's phases: status and progress ask)
    enumerates = False
    closing = False
    append_only = ("part.lo", "part.hi")  # boxes never change once made
    state_epoch = 0

    def __init__(self, scenario: Scenario, settings: SPESettings):
        self.scenario = scenario
        self.settings = settings
        self.partition = Partition(scenario.lower, scenario.upper, settings.delta0)
        self.round = 0
        self.delta = settings.delta0
        size = self.partition.size
        self.margin = np.full(size, np.nan)
        self.failed = np.zeros(size, dtype=bool)
        self.index = np.full(size, -1, dtype=np.int64)  # each box's sample index (its run's key)
        self.wave = np.arange(self.partition.roots)  # boxes to run now
        self.wave_first = 0  # the sample index of the wave's first run
        self.wave_done = 0  # its runs told so far
        self.todo = np.zeros(0, dtype=np.int64)  # boxes to decide once the wave is in
        self.blocked = np.zeros(0, dtype=np.int64)  # boxes that wanted a split below the round's delta
        self.finished = False
        self.kept: np.ndarray | None = None  # the certified boxes
        self.invariance_rounds = 0
        self.visits = Visits(scenario.n)
        self.splits = 0
        self.cut_passes = 0  # passes of the last round's cuts made

    # -- the runs ------------------------------------------------------------------------------
    def starts(self, boxes: np.ndarray) -> np.ndarray:
        return self.partition.centres(boxes)

    def tell(self, boxes: np.ndarray, indices: np.ndarray, chunk, rows: np.ndarray) -> None:
        """Runs ``rows`` of ``chunk`` were the runs of ``boxes`` (sample ``indices``)."""
        self._fit(self.partition.size)
        self.margin[boxes] = chunk.margins[rows]
        self.failed[boxes] = chunk.outcomes[rows] == FAILURE
        self.index[boxes] = indices
        safe = ~self.failed[boxes]
        if safe.any():
            self.remember(boxes[safe], chunk, rows[safe])

    def remember(self, boxes: np.ndarray, chunk, rows: np.ndarray | None = None) -> None:
        """Keep the visited states of runs ``rows`` of ``chunk`` (all: None), the runs of ``boxes``."""
        states, offsets = chunk.visited()
        rows = np.arange(len(chunk)) if rows is None else rows
        counts = offsets[rows + 1] - offsets[rows]
        at = np.repeat(offsets[rows] - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
        self.visits.add(boxes, states[at], np.concatenate([[0], np.cumsum(counts)]))

    def next_wave(self) -> np.ndarray:
        """The boxes to run next (after the last wave's runs are told); empty when the
        refinement is done."""
        self.todo = np.union1d(self.todo, self.wave) if len(self.wave) else self.todo
        self.wave = np.zeros(0, dtype=np.int64)
        while not self.finished:
            children = self._decide(self._near_changes(self.todo))
            self.todo = np.zeros(0, dtype=np.int64)
            if len(children):
                self.wave = children
                return children
            if self.final_round:
                if self.cut_passes < CUT_PASSES:
                    self.cut_passes += 1
                    children = self._cut()
                    if len(children):
                        self.wave = children
                        return children
                self.finished = True
                break
            self.round += 1
            self.delta = max(self.settings.gamma * self.delta, self.settings.delta_min)
            self.todo, self.blocked = self.blocked, np.zeros(0, dtype=np.int64)
        return self.wave

    @property
    def final_round(self) -> bool:
        return self.delta <= self.settings.delta_min * (1 + 1e-12)

    # -- deciding --------------------------------------------------------------------------------
    def _near_changes(self, boxes: np.ndarray) -> np.ndarray:
        """The leaves among ``boxes`` and their face neighbours: where a new run can change
        a decision."""
        p = self.partition
        boxes = boxes[p.is_leaf(boxes)] if len(boxes) else boxes
        found = [boxes]
        for axis in range(p.n):
            for side in (-1, 1):
                nb = p.neighbours(boxes, axis, side)
                found.append(nb[nb >= 0])
        return unique_ints(np.concatenate(found))

    def _decide(self, boxes: np.ndarray) -> np.ndarray:
        """Split the boxes that want it and may; -> the children (the next wave). Every
        box is decided on the partition as it stands, before any of them splits."""
        masks = np.zeros(len(boxes), dtype=np.int64)
        last = self.final_round
        for lo in range(0, len(boxes), DECIDE_BLOCK):
            part = boxes[lo : lo + DECIDE_BLOCK]
            hood = self._neighbourhood(part)
            wanted, priority = wanted_axes(hood, self.settings.delta_min, last)
            wanted |= self._on_failure_facets(part)
            half_widths = self.partition.half_widths(part)
            splittable = half_widths > self.delta * (1 + 1e-9)
            lonely = spans_sigma(hood) & splittable
            if last:  # one halving from delta_min, a box is the cut's (the module's docstring)
                splittable &= (half_widths.max(axis=1) > 2 * self.delta * (1 + 1e-9))[:, None]
            splittable |= lonely
            masks[lo : lo + DECIDE_BLOCK] = choose(wanted | lonely, np.where(lonely, np.inf, priority), splittable)
            waiting = (wanted & ~splittable).any(axis=1) & (masks[lo : lo + DECIDE_BLOCK] == 0)
            self.blocked = np.union1d(self.blocked, part[waiting])
        split = masks > 0
        if not split.any():
            return np.zeros(0, dtype=np.int64)
        children = self.partition.split(boxes[split], masks[split])
        self.visits.drop(boxes[split])
        self.splits += int(split.sum())
        self._fit(self.partition.size)
        return children

    def _cut(self) -> np.ndarray:
        """One pass of the last round's cuts over the leaves (coordinator/margin/cut_rule.py);
        -> the children (the next wave)."""
        p = self.partition
        leaves = p.leaves()
        found = []
        for lo in range(0, len(leaves), DECIDE_BLOCK):
            part = leaves[lo : lo + DECIDE_BLOCK]
            cut, axis, at = cuts(self._neighbourhood(part), p.lo[part], p.hi[part])
            found.append((part[cut], np.left_shift(np.int64(1), axis[cut]), at[cut]))
        boxes = np.concatenate([f[0] for f in found])
        if not len(boxes):
            return boxes
        children = p.split(boxes, np.concatenate([f[1] for f in found]), np.concatenate([f[2] for f in found]))
        self.visits.drop(boxes)
        self.splits += len(boxes)
        self._fit(p.size)
        return children

    def _on_failure_facets(self, boxes: np.ndarray) -> np.ndarray:
        """(B, n) bool: the box lies on a failure facet of Sigma along that axis. The
        safe set's boundary meets the facet, and there the margin, a minimum taken from the
        start on, says little about the box's far side (Theorem 3 counts the facets as
        boundary too)."""
        out = np.zeros((len(boxes), self.partition.n), dtype=bool)
        lo, hi = self.partition.lo[boxes], self.partition.hi[boxes]
        for facet, failure in self.scenario.facets():
            if failure:
                side = hi[:, facet.axis] >= facet.bound if facet.upper else lo[:, facet.axis] <= facet.bound
                out[:, facet.axis] |= side
        return out

    def _neighbourhood(self, boxes: np.ndarray) -> Neighbourhood:
        p, n = self.partition, self.partition.n
        exists = np.zeros((len(boxes), n, 2), dtype=bool)
        at = np.zeros((len(boxes), n, 2))
        margins = np.zeros((len(boxes), n, 2))
        labels = np.zeros((len(boxes), n, 2), dtype=bool)
        for axis in range(n):
            for s, side in enumerate((-1, 1)):
                nb = p.neighbours(boxes, axis, side)
                ok = nb >= 0
                exists[:, axis, s] = ok
                at[ok, axis, s] = p.centres(nb[ok])[:, axis]
                margins[ok, axis, s] = self.margin[nb[ok]]
                labels[ok, axis, s] = ~self.failed[nb[ok]]
        return Neighbourhood(p.centres(boxes), p.half_widths(boxes), self.margin[boxes], ~self.failed[boxes],
                             exists, at, margins, labels)

    def _fit(self, size: int) -> None:
        grow = size - len(self.margin)
        if grow > 0:
            self.margin = np.concatenate([self.margin, np.full(grow, np.nan)])
            self.failed = np.concatenate([self.failed, np.zeros(grow, dtype=bool)])
            self.index = np.concatenate([self.index, np.full(grow, -1, dtype=np.int64)])

    # -- certification -----------------------------------------------------------------------------
    def safe_leaves(self) -> np.ndarray:
        leaves = self.partition.leaves()
        return leaves[~self.failed[leaves]]

    def claimed_leaves(self) -> np.ndarray:
        """The safe leaves whose centre's margin exceeds KAPPA x its first-order change over
        the box (the module's docstring): the candidates of the set."""
        safe = self.safe_leaves()
        keep = np.ones(len(safe), dtype=bool)
        for lo in range(0, len(safe), DECIDE_BLOCK):
            part = safe[lo : lo + DECIDE_BLOCK]
            keep[lo : lo + DECIDE_BLOCK] = self.margin[part] > KAPPA * first_order_change(self._neighbourhood(part))
        return safe[keep]

    def missing_visits(self) -> np.ndarray:
        """Claimed leaves whose run's states are not held (after a resume): to run again."""
        safe = self.claimed_leaves()
        return safe[np.array([b not in self.visits for b in safe.tolist()], dtype=bool)] if len(safe) else safe

    @property
    def covering(self) -> float:
        """How far past its boxes a run of the set may go (its delta-covering: each box
        widened by delta_min on every axis, the paper's Definition 5 with a delta per box)."""
        return self.settings.delta_min

    def certify(self) -> None:
        """Keep the largest set of claimed leaves whose runs stay within ``covering`` of the set."""
        safe = self.claimed_leaves()
        states, offsets = self.visits.of(safe)
        p = self.partition
        kept, self.invariance_rounds = largest_invariant(safe, states, offsets, p.locate, p.size, self.covering,
                                                         self.scenario.lower, self.scenario.upper)
        self.kept = safe[kept]
        self.certifying = True

    # -- the result ------------------------------------------------------------------------------
    def result(self) -> SafeSet:
        boxes = self.kept if self.kept is not None else self.claimed_leaves()
        p = self.partition
        return SafeSet(p.centres(boxes), p.half_widths(boxes), self.scenario.state_names,
                       {COVERING_MARGIN: repr(self.covering)}, disjoint=True)

    def failure_points(self) -> np.ndarray:
        """(F, n) the centres of the failing leaves: the starts of the runs that failed."""
        leaves = self.partition.leaves()
        return self.partition.centres(leaves[self.failed[leaves]])

    @property
    def held(self) -> int:
        """The partition's boxes, leaves and split ones: what the refinement's memory follows."""
        return self.partition.size

    def counts(self) -> dict:
        leaves = self.partition.leaves()
        out = {"boxes": int(np.count_nonzero(~self.failed[leaves])), "leaves": len(leaves),
               "failures": int(np.count_nonzero(self.failed[leaves])), "delta": self.delta, "round": self.round,
               "splits": self.splits}
        if self.kept is not None:
            out["boxes"] = out["certified"] = len(self.kept)
        return out

    def sampling_description(self) -> str:
        return "the centre of every box of the final partition, once (the system is deterministic)"

    def stop_committing(self) -> None:
        """(The driver's interface: nothing to drop before the last checkpoint.)"""

    def release(self) -> None:
        self.visits = Visits(self.scenario.n)

    # -- persistence -----------------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        out = self.partition.state()
        size = self.partition.size
        out.update({"box.margin": self.margin[:size].copy(), "box.failed": self.failed[:size].copy(),
                    "box.index": self.index[:size].copy(), "wave": self.wave.copy(), "todo": self.todo.copy(),
                    "blocked": self.blocked.copy(),
                    "scalars": np.array([self.round, self.delta, self.finished, self.splits, self.wave_first,
                                         self.wave_done, self.cut_passes], dtype=float)})
        if self.kept is not None:
            out["kept"] = self.kept.copy()
        return out

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        self.partition.load_state(state)
        size = self.partition.size
        for name in ("box.margin", "box.failed", "box.index"):
            if state[name].shape != (size,):
                raise ValueError(f"{name}: shape {state[name].shape}, expected ({size},)")
        self.margin, self.failed = state["box.margin"].astype(float), state["box.failed"].astype(bool)
        self.index = state["box.index"].astype(np.int64)
        self.wave, self.todo = state["wave"].astype(np.int64), state["todo"].astype(np.int64)
        self.blocked = state["blocked"].astype(np.int64)
        if state["scalars"].shape != (7,):
            raise ValueError(f"scalars: shape {state['scalars'].shape}, expected (7,) (a checkpoint of an earlier "
                             "margin refinement: start it again)")
        rnd, delta, finished, splits, first, done, cut_passes = state["scalars"]
        self.round, self.delta, self.finished, self.splits = int(rnd), float(delta), bool(finished), int(splits)
        self.wave_first, self.wave_done, self.cut_passes = int(first), int(done), int(cut_passes)
        self.kept = state["kept"].astype(np.int64) if "kept" in state else None
        self.certifying = self.kept is not None
        self.visits = Visits(self.scenario.n)
