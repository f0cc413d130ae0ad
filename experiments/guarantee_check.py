"""Is the validation guarantee true? Repeat VAL^eps on a domain that is NOT eps-almost
invariant and count how often it is wrongly certified; Lemma 2 promises at most beta.
Then the same for the binomial test a certification check makes when it tolerates
quantify.certify_tolerance violations (coordinator/certification.py): at most beta too.

Domain: lead-follow / brake, Phi = {p10 in [10, 70], v0 - v1 <= b}, uniform lead actions.
Its true violation rate p (probability that a run from a uniform start in Phi leaves Phi
or fails within K states) is measured by a large Monte Carlo run on separate seeds; b is
chosen so that p > eps. A certificate is then wrong, and P(wrong) = (1 - p)^N <= beta.

    python experiments/guarantee_check.py [--seeds 300]   # docs/guarantee_check.json and docs/guarantee.md's table
    python experiments/guarantee_check.py --render        # the table from the JSON only
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy import stats

from coordinator.certification import TOLERANCE
from coordinator.domain import Domain
from coordinator.sample_size import n_eps_allowing
from coordinator.validation import Checker, validation_plan
from farm import api
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios.streams import RunStreams

EPS, BETA, HORIZON = 0.001, 0.1, 50
SCENARIO = {"name": "lead-follow", "sv_policy": "brake"}
TOLERANT_SEED = 2 * 10**9  # the tolerant checks' streams, apart from the validations' and the Monte Carlo's


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


def tolerant_checks(seeds: int, b: float, allowed: int = TOLERANCE) -> dict:
    """The binomial test a certification check makes (coordinator/certification.py): N runs
    from uniform starts in the same not-eps-almost-invariant domain, certified if at most
    ``allowed`` of them violate; N the least with P(Bin(N, eps) <= allowed) <= beta. Each
    check's runs have sample indices of their own (apart from the validations')."""
    ex = LocalExecutor(SimSpec(SCENARIO, {"mode": "uniform"}, HORIZON, TOLERANT_SEED))
    domain = Domain.from_config(ex.simulator.scenario, domain_section(b))
    checker = Checker(domain, validation_plan(domain, "eps", EPS, BETA, 1.0, False, False), 1.0)
    n = n_eps_allowing(EPS, BETA, allowed)
    passed = 0
    for seed in range(seeds):
        # each check its own sample indices: its runs' starts and actions drawn apart from every other's
        first = seed * n
        starts = domain.sample(RunStreams.of(TOLERANT_SEED, np.arange(first, first + n, dtype=np.uint64)))
        (handle,) = ex.submit(first, starts, checker)
        passed += int((ex.result(handle).screening >= 0).sum()) <= allowed
    lo, hi = stats.binomtest(passed, seeds).proportion_ci(0.95, method="exact")
    return {"allowed": allowed, "n": n, "seeds": seeds, "false_certifications": passed, "false_certification_rate": passed / seeds,
            "ci95": [lo, hi]}


def experiment(seeds: int, b: float, tolerant_seeds: int | None = None) -> dict:
    """``seeds`` validations, then ``tolerant_seeds`` (default as many) tolerant checks."""
    p_true, mc_runs = true_violation_rate(b)
    wrong, n = 0, None
    for seed in range(seeds):
        cert = api.validate(config(b, seed))
        wrong += cert.certified
        n = cert.n_required
    lo, hi = stats.binomtest(wrong, seeds).proportion_ci(0.95, method="exact")
    tolerant = tolerant_checks(seeds if tolerant_seeds is None else tolerant_seeds, b)
    tolerant["predicted_false_certification"] = float(stats.binom.cdf(tolerant["allowed"], tolerant["n"], p_true))
    return {"epsilon": EPS, "beta": BETA, "n_eps": n, "cut_b": b, "true_violation_rate": p_true,
            "true_rate_mc_runs": mc_runs, "predicted_false_certification": (1 - p_true) ** n,
            "seeds": seeds, "false_certifications": wrong, "false_certification_rate": wrong / seeds,
            "ci95": [lo, hi], "tolerant_check": tolerant}


JSON = Path(__file__).resolve().parents[1] / "docs" / "guarantee_check.json"
DOC = JSON.with_name("guarantee.md")
BEGIN, END = "<!-- guarantee-check:begin", "<!-- guarantee-check:end -->"


def render(data: dict) -> str:
    """The table of docs/guarantee.md's first section, from the experiment's JSON."""
    t = data.get("tolerant_check")
    rows = [f"| validate (none allowed) | {data['n_eps']} | {data['predicted_false_certification']:.4f} | "
            f"{data['false_certifications']} / {data['seeds']} | {data['false_certification_rate']:.3f} | "
            f"[{data['ci95'][0]:.3f}, {data['ci95'][1]:.3f}] |"]
    if t:
        rows.append(f"| a certification check allowing {t['allowed']} | {t['n']} | "
                    f"{t['predicted_false_certification']:.4f} | {t['false_certifications']} / {t.get('seeds', data['seeds'])} | "
                    f"{t['false_certification_rate']:.3f} | [{t['ci95'][0]:.3f}, {t['ci95'][1]:.3f}] |")
    return "\n".join([
        f"{BEGIN} (generated by experiments/guarantee_check.py --render from docs/guarantee_check.json) -->",
        f"eps = {data['epsilon']:g}, beta = {data['beta']:g}, true p = {data['true_violation_rate']:.5f} "
        f"({data['true_rate_mc_runs']:,} runs).", "",
        "| test | N | predicted P(certify) | certified / seeds | rate | 95% CI (Clopper-Pearson) |",
        "| --- | ---: | ---: | ---: | ---: | --- |", *rows, END])


def write_doc(data: dict) -> Path:
    text = DOC.read_text()
    head, rest = text.split(BEGIN, 1)
    DOC.write_text(head + render(data) + rest.split(END, 1)[1])
    return DOC


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=300)
    ap.add_argument("--b", type=float, default=4.0)
    ap.add_argument("--render", action="store_true", help="docs/guarantee.md's table from the JSON only")
    args = ap.parse_args()
    if not args.render:
        result = experiment(args.seeds, args.b)
        JSON.write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2))
    print(write_doc(json.loads(JSON.read_text())))
