"""Safety validation (paper Sec. 3): VAL^delta (Alg. 2), VAL^eps (Alg. 3) and
VAL^eps-delta (Alg. 4), with the boundary set (Thm. 3) and Gamma* (Def. 7) options.

Runs are simulated in batches on any executor, checked on the workers (``Checker`` is
the screen every chunk is sent with), and committed in sample-index order, so the
verdict and the first counterexample (the smallest violating index) do not depend on
the number of workers. A run *violates* when it reaches a failure facet, or visits a
state inside Sigma outside Phi (eps) or outside Phi_delta (delta, eps-delta). Leaving
Sigma through a truncating facet ends a run quietly (the hard-constraint rule).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from coordinator.sample_size import covering_size, n_eps
from coordinator.domain import Domain
from coordinator.spatial import PointIndex
from scenarios.streams import PURPOSE_START, RunStreams
from scenarios.base import FAILURE, OUTCOME_NAMES, TRUNCATED
from scenarios.errors import ConfigError


@dataclass(frozen=True)
class ValidationResult:
    """What a validation found: ``verdict`` "certified" or "counterexample", the runs it
    committed (``n_run``: up to and including the first violation) and simulated, and the
    first violating run (``counterexample``: JSON-able, as certificate.json holds it)."""

    verdict: str
    n_run: int
    runs_simulated: int
    steps_simulated: int
    counterexample: dict | None = None

    @property
    def certified(self) -> bool:
        return self.verdict == "certified"


@dataclass
class ValidationPlan:
    algorithm: str  # delta | eps | eps-delta
    n_required: int
    centres: np.ndarray | None  # the delta-covering centres (delta, eps-delta)
    reach: float | None  # sigma-bar, if sampling the boundary set only (Theorem 3)
    description: str  # what the sampled distribution is


def validation_plan(domain: Domain, algorithm: str, epsilon: float, beta: float, delta: float, boundary: bool,
         deterministic: bool) -> ValidationPlan:
    sc = domain.scenario
    reach = sc.step_bound() if boundary else None
    where = f"the {reach:g}-boundary set of Phi" if boundary else "Phi"
    if algorithm == "eps":
        return ValidationPlan("eps", n_eps(epsilon, beta), None, reach, f"start states i.i.d. uniform in {where}")
    centres = domain.lattice(delta, reach)
    if len(centres) == 0:
        raise ConfigError(f"validate.delta: no {delta:g}-covering centre lies in {where}; use a smaller delta")
    if algorithm == "delta":
        if not deterministic:
            raise ConfigError("validate.algorithm: 'delta' needs a deterministic system (actions.mode constant, "
                              "feedback, or adversarial with one action, and scenario.disturbance = 0)")
        # Lemma 1; a set of mixed sizes is its own covering (Domain.covering): its centres
        needed = covering_size(domain.volume(), delta, sc.n) if domain.covering(delta) is None else len(centres)
        what = (f"every {delta:g}-covering centre of {where} once" if domain.covering(delta) is None else
                f"every box centre of the set once (its own covering: {domain.covering_words(delta)})")
        return ValidationPlan("delta", max(len(centres), needed if not boundary else len(centres)), centres, reach,
                              what)
    over = (f"the {len(centres)} {delta:g}-covering centres of {where}" if domain.covering(delta) is None else
            f"the set's {len(centres)} box centres (its own covering: {domain.covering_words(delta)})")
    return ValidationPlan("eps-delta", n_eps(epsilon, beta), centres, reach, f"start states i.i.d. uniform over {over}")


def draw_starts(domain: Domain, p: ValidationPlan, streams: RunStreams) -> np.ndarray:
    if p.algorithm == "eps":
        return domain.sample(streams, p.reach)
    if p.algorithm == "delta":  # each centre once, in order (index i -> centre i mod M)
        return p.centres[(streams.indices % np.uint64(len(p.centres))).astype(np.int64)]
    u = streams.uniform(0, PURPOSE_START, 1)[:, 0]
    return p.centres[np.minimum((u * len(p.centres)).astype(np.int64), len(p.centres) - 1)]


class Checker:
    """Decides, per run, the first violating step (or none): the screen of a validation.

    Phi_delta is the union of the delta-boxes of the covering centres (for a set domain
    its own box centres); Definition 1 needs it to contain Phi, and centres kept inside
    a cut domain may leave slivers of Phi near its faces, so Phi counts too."""

    def __init__(self, domain: Domain, p: ValidationPlan, delta: float):
        self.domain, self.plan, self.delta = domain, p, delta
        self.cover = None
        self.mixed = domain.covering(delta)
        if p.centres is not None and self.mixed is None:
            self.cover = PointIndex(domain.scenario.n, 2 * delta, domain.lo - delta, bounds=(domain.lo, domain.hi))
            self.cover.insert(p.centres)

    def inside(self, states: np.ndarray) -> np.ndarray:
        if self.mixed is not None:
            # Phi_delta holds Phi, whose boxes overlap far less than their widened copies:
            # most states are decided by Phi's index, the rest by Phi_delta's
            inside = self.domain.safe_set.contains(states)
            inside[~inside] = self.mixed.contains(states[~inside])
            return inside
        if self.cover is not None and self.domain.is_set:
            return self.cover.any_within(states, self.delta)
        inside = self.domain.contains(states)
        if self.cover is not None:
            inside[~inside] = self.cover.any_within(states[~inside], self.delta)
        return inside

    def screen(self, states: np.ndarray, offsets: np.ndarray, outcomes: np.ndarray) -> np.ndarray:
        """(k,) int64: the step of each run's first violating state, -1 for none."""
        k = len(outcomes)
        counts = np.diff(offsets)
        run = np.repeat(np.arange(k), counts)
        t = np.arange(len(states)) - np.repeat(offsets[:-1], counts) + 1
        outside = ~self.inside(states)
        first = np.full(k, np.iinfo(np.int64).max)
        np.minimum.at(first, run[outside], t[outside])
        step = np.where(first < np.iinfo(np.int64).max, first, -1)
        # a failure is the run's terminal state, after every visited state
        failed = (outcomes == FAILURE) & (step < 0)
        step[failed] = counts[failed] + 1
        return step


def validate(domain: Domain, p: ValidationPlan, executor, *, seed: int, delta: float, batch_size: int,
             pipeline_depth: int, progress=None) -> ValidationResult:
    """Run up to p.n_required runs; stop at the first violation (smallest index)."""
    checker = Checker(domain, p, delta)
    pending: deque = deque()  # (first index, starts, handles)
    next_index = committed = simulated = steps = 0
    try:
        while committed < p.n_required:
            while len(pending) < pipeline_depth and next_index < p.n_required:
                size = min(batch_size, p.n_required - next_index)
                streams = RunStreams.of(seed, np.arange(next_index, next_index + size, dtype=np.uint64))
                starts = draw_starts(domain, p, streams)
                pending.append((next_index, starts, deque(executor.submit(next_index, starts, checker))))
                next_index += size
            first, starts, handles = pending[0]
            chunk = executor.result(handles.popleft())
            if not handles:
                pending.popleft()
            simulated += len(chunk)
            steps += chunk.steps
            violated = chunk.screening >= 0
            if violated.any():
                row = int(np.argmax(violated))
                committed += row + 1
                start = starts[chunk.first_index - first + row]
                return ValidationResult("counterexample", committed, simulated, steps,
                                        counterexample(domain, chunk, row, start, int(chunk.screening[row]), seed))
            committed += len(chunk)
            if progress:
                progress(committed, p.n_required)
    finally:
        for _, _, handles in pending:
            for handle in handles:
                executor.cancel(handle)
    return ValidationResult("certified", committed, simulated, steps)


def counterexample(domain: Domain, chunk, row: int, start: np.ndarray, step: int, seed: int) -> dict:
    sc = domain.scenario
    traj = chunk.trajectory(row, start)[: step + 1]
    last = traj[-1]
    failed_here = chunk.outcomes[row] == FAILURE and step == chunk.lengths[row] - 1
    if failed_here:
        crossed = [f.label for f, fail in sc.facets() if fail and
                   ((last[f.axis] > f.bound) if f.upper else (last[f.axis] < f.bound))]
        reason = f"failure: crossed {' and '.join(crossed) or 'a failure facet'} at step {step}"
    else:
        reason = f"left the claimed domain at step {step} (state {np.round(last, 6).tolist()})"
    index = chunk.first_index + row
    return {
        "sample_index": index,
        "stream_key": {"seed": seed, "index": index},
        "start_state": dict(zip(sc.state_names, map(float, traj[0]))),
        "violating_step": step,
        "reason": reason,
        # what happened at the violating step; the trajectory ends there
        "outcome": "failure" if failed_here else "left the domain",
        "run_outcome": OUTCOME_NAMES.get(int(chunk.outcomes[row]), "horizon"),
        "state_names": list(sc.state_names),
        "trajectory": traj.tolist(),
        "truncated": bool(chunk.outcomes[row] == TRUNCATED),
    }
