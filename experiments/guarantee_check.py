"""Is the validation guarantee true? Repeat VAL^eps on a domain that is NOT eps-almost
invariant and count how often it is wrongly certified; Lemma 2 promises at most beta.

Domain: lead-follow / brake, Phi = {p10 in [10, 70], v0 - v1 <= b}, uniform lead actions.
Its true violation rate p (probability that a run from a uniform start in Phi leaves Phi
or fails within K states) is measured by a large Monte Carlo run on separate seeds; b is
chosen so that p > eps. A certificate is then wrong, and P(wrong) = (1 - p)^N <= beta.

    python experiments/guarantee_check.py [--seeds 300]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy import stats

from coordinator.domain import Domain
from coordinator.validation import Checker, validation_plan
from farm import api
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios.streams import RunStreams

EPS, BETA, HORIZON = 0.001, 0.1, 50
SCENARIO = {"name": "lead-follow", "sv_policy": "brake"}


def domain_section(b: float) -> dict:
    return {"domain": {"p10": [10.0, 70.0]}, "constraints": [{"a": {"v0": 1.0, "v1": -1.0}, "b": b}]}


def config(b: float, seed: int) -> dict:
    return {"scenario": SCENARIO, "actions": {"mode": "uniform"},
            "validate": {**domain_section(b), "algorithm": "eps", "epsilon": EPS, "beta": BETA, "horizon": HORIZON},
            "farm": {"executor": "local", "seed": seed, "batch_size": 256, "pipeline_depth": 1}}


def true_violation_rate(b: float, runs: int = 400_000, seed: int = 10**9) -> tuple[float, int]:
    ex = LocalExecutor(SimSpec(SCENARIO, {"mode": "uniform"}, HORIZON, seed))
    domain = Domain.from_config(ex.simulator.scenario, domain_section(b))
    checker = Checker(domain, validation_plan(domain, "eps", EPS, BETA, 1.0, False, False), 1.0)
    bad = 0
    for first in range(0, runs, 50_000):
        starts = domain.sample(RunStreams.of(seed, np.arange(first, first + 50_000, dtype=np.uint64)))
        (handle,) = ex.submit(first, starts, checker)
        bad += int((ex.result(handle).screening >= 0).sum())
    return bad / runs, runs


def experiment(seeds: int, b: float) -> dict:
    p_true, mc_runs = true_violation_rate(b)
    wrong, n = 0, None
    for seed in range(seeds):
        cert = api.validate(config(b, seed))
        wrong += cert.certified
        n = cert.n_required
    lo, hi = stats.binomtest(wrong, seeds).proportion_ci(0.95, method="exact")
    return {"epsilon": EPS, "beta": BETA, "n_eps": n, "cut_b": b, "true_violation_rate": p_true,
            "true_rate_mc_runs": mc_runs, "predicted_false_certification": (1 - p_true) ** n,
            "seeds": seeds, "false_certifications": wrong, "false_certification_rate": wrong / seeds,
            "ci95": [lo, hi]}


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=300)
    ap.add_argument("--b", type=float, default=4.0)
    args = ap.parse_args()
    print(json.dumps(experiment(args.seeds, args.b), indent=2))
