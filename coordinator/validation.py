"""Safety validation (paper Sec. 3): VAL^delta (Alg. 2), VAL^eps (Alg. 3) and
VAL^eps-delta (Alg. 4), with the boundary band (Thm. 3) and Gamma* (Def. 7) options.

Runs are simulated in batches on any executor and committed in sample-index order, so
the verdict and the first counterexample (the smallest violating index) do not depend
on the number of workers. A run *violates* when it reaches a failure facet, or visits a
state inside Sigma outside Phi (eps) or outside Phi_delta (delta, eps-delta). Leaving
Sigma through a truncating facet ends a run quietly (the hard-constraint rule).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from coordinator.covering import covering_size, n_eps
from coordinator.domain import Domain
from coordinator.runs import visited_states
from coordinator.spatial import PointIndex
from scenarios.streams import PURPOSE_START, RunStreams
from scenarios.base import FAILURE, OUTCOME_NAMES, TRUNCATED


@dataclass
class ValidationPlan:
    algorithm: str  # delta | eps | eps-delta
    n_required: int
    centres: np.ndarray | None  # the delta-covering centres (delta, eps-delta)
    band: float | None  # sigma-bar, if sampling the boundary band only
    description: str  # what the sampled distribution is


def plan(domain: Domain, algorithm: str, epsilon: float, beta: float, delta: float, boundary: bool,
         deterministic: bool) -> ValidationPlan:
    sc = domain.scenario
    band = sc.step_bound() if boundary else None
    where = f"the {band:g}-boundary band of Phi" if boundary else "Phi"
    if algorithm == "eps":
        return ValidationPlan("eps", n_eps(epsilon, beta), None, band, f"start states i.i.d. uniform in {where}")
    centres = domain.lattice(delta, band)
    if len(centres) == 0:
        raise ValueError(f"validate.delta: no {delta:g}-covering centre lies in {where}; use a smaller delta")
    if algorithm == "delta":
        if not deterministic:
            raise ValueError("validate.algorithm: 'delta' needs a deterministic system (actions.mode constant, "
                             "feedback, or adversarial with one action, and scenario.disturbance = 0)")
        needed = covering_size(domain.volume(), delta, sc.n)  # Lemma 1
        return ValidationPlan("delta", max(len(centres), needed if not boundary else len(centres)), centres, band,
                              f"every {delta:g}-covering centre of {where} once")
    return ValidationPlan("eps-delta", n_eps(epsilon, beta), centres, band,
                          f"start states i.i.d. uniform over the {len(centres)} {delta:g}-covering centres of {where}")


def draw_starts(domain: Domain, p: ValidationPlan, streams: RunStreams) -> np.ndarray:
    if p.algorithm == "eps":
        return domain.sample(streams, p.band)
    if p.algorithm == "delta":  # each centre once, in order (index i -> centre i mod M)
        return p.centres[(streams.indices % np.uint64(len(p.centres))).astype(np.int64)]
    u = streams.uniform(0, PURPOSE_START, 1)[:, 0]
    return p.centres[np.minimum((u * len(p.centres)).astype(np.int64), len(p.centres) - 1)]


class Checker:
    """Decides, per run, the first violating step (or none)."""

    def __init__(self, domain: Domain, p: ValidationPlan, delta: float):
        self.domain, self.plan, self.delta = domain, p, delta
        if p.centres is not None:
            self.cover = PointIndex(domain.scenario.n, 2 * delta, domain.lo - delta,
                                    bounds=(domain.lo, domain.hi))
            self.cover.insert(p.centres)

    def inside(self, states: np.ndarray) -> np.ndarray:
        inside = self.domain.contains(states)
        if self.plan.algorithm == "eps":
            return inside
        # Definition 1 needs Phi_delta to contain Phi; centres kept inside a cut or a set
        # domain may leave slivers of Phi uncovered near its faces, so Phi counts too.
        inside[~inside] = self.cover.any_within(states[~inside], self.delta)
        return inside

    def violations(self, batch) -> tuple[np.ndarray, np.ndarray]:
        """(B,) bool violated, (B,) int step of the first violating state (or -1)."""
        rows = np.arange(len(batch))
        states, pos = visited_states(batch, rows)
        outside = ~self.inside(states)
        step = np.full(len(batch), -1, dtype=np.int64)
        if outside.any():
            # visited states are in time order within a run: first outside state per run
            first = np.full(len(batch), np.iinfo(np.int64).max)
            t = np.arange(len(states)) - np.searchsorted(pos, pos) + 1
            np.minimum.at(first, pos[outside], t[outside])
            hit = first < np.iinfo(np.int64).max
            step[hit] = first[hit]
        failed = batch.outcomes == FAILURE
        step[failed & (step < 0)] = batch.lengths[failed & (step < 0)] - 1
        return step >= 0, step


def validate(domain: Domain, p: ValidationPlan, executor, *, seed: int, delta: float, batch_size: int,
             pipeline_depth: int, progress=None) -> dict:
    """Run up to p.n_required runs; stop at the first violation (smallest index)."""
    checker = Checker(domain, p, delta)
    pending: deque = deque()
    next_index = 0
    committed = 0
    simulated = 0
    steps = 0
    while committed < p.n_required:
        while len(pending) < pipeline_depth and next_index < p.n_required:
            size = min(batch_size, p.n_required - next_index)
            streams = RunStreams.of(seed, np.arange(next_index, next_index + size, dtype=np.uint64))
            starts = draw_starts(domain, p, streams)
            pending.append((next_index, executor.submit(next_index, starts)))
            next_index += size
        first, handle = pending.popleft()
        batch = executor.result(handle)
        simulated += len(batch)
        steps += batch.steps
        violated, step = checker.violations(batch)
        if violated.any():
            row = int(np.argmax(violated))
            for _, h in pending:
                executor.cancel(h)
            committed += row + 1
            return {"verdict": "counterexample", "n_run": committed, "runs_simulated": simulated,
                    "steps_simulated": steps,
                    "counterexample": counterexample(domain, batch, row, int(step[row]), seed)}
        committed += len(batch)
        if progress:
            progress(committed, p.n_required)
    return {"verdict": "certified", "n_run": committed, "runs_simulated": simulated, "steps_simulated": steps,
            "counterexample": None}


def counterexample(domain: Domain, batch, row: int, step: int, seed: int) -> dict:
    sc = domain.scenario
    traj = batch.trajectory(row)[: step + 1]
    last = traj[-1]
    if batch.outcomes[row] == FAILURE and step == batch.lengths[row] - 1:
        crossed = [f.label for f, fail in sc.facets() if fail and
                   ((last[f.axis] > f.bound) if f.upper else (last[f.axis] < f.bound))]
        reason = f"failure: crossed {' and '.join(crossed) or 'a failure facet'} at step {step}"
    else:
        reason = f"left the claimed domain at step {step} (state {np.round(last, 6).tolist()})"
    return {
        "sample_index": int(batch.indices[row]),
        "stream_key": {"seed": seed, "index": int(batch.indices[row])},
        "start_state": dict(zip(sc.state_names, map(float, traj[0]))),
        "violating_step": step,
        "reason": reason,
        "outcome": OUTCOME_NAMES.get(int(batch.outcomes[row]), "horizon"),
        "state_names": list(sc.state_names),
        "trajectory": traj.tolist(),
        "truncated": bool(batch.outcomes[row] == TRUNCATED),
    }


def verdict_sentence(result: dict, p: ValidationPlan, *, epsilon: float, beta: float, delta: float, seed: int,
                     action_description: str, adversarial: bool) -> str:
    gamma = "Gamma* (the adversarial set, Definition 7)" if adversarial else "Gamma"
    if result["verdict"] == "counterexample":
        ce = result["counterexample"]
        return (f"Phi is NOT forward invariant: sample {ce['sample_index']} (stream key seed={seed}, "
                f"index={ce['sample_index']}) from {ce['start_state']} {ce['reason']}.")
    n = result["n_run"]
    conf = 1 - beta
    if p.algorithm == "delta":
        return (f"Phi is {delta:g}-almost forward invariant (resolution complete, Lemma 1) for {action_description} "
                f"with probability one (N = {n} runs, {p.description}, seed {seed}).")
    kind = f"{epsilon:g}-almost" if p.algorithm == "eps" else f"({epsilon:g}, {delta:g})-almost"
    return (f"Phi is {kind} robustly controlled forward invariant w.r.t. {gamma} with confidence {conf:g} "
            f"(N = {n} runs, {p.description}, actions {action_description}, seed {seed}).")
