"""Lemma 2 in practice: a domain that is not eps-almost invariant is certified at most
beta of the time (experiments/guarantee_check.py, 300 independent seeds), by validate (no
violation allowed) and by the binomial test a certification check makes (a few allowed)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))

from guarantee_check import BETA, EPS, experiment  # noqa: E402


def test_false_certification_rate_is_at_most_beta():
    # the tolerant checks on 100 seeds (6,679 runs each; the docs' JSON has 300)
    r = experiment(seeds=300, b=4.0, tolerant_seeds=100)
    assert r["true_violation_rate"] > EPS  # the domain really is not eps-almost invariant
    assert r["false_certification_rate"] <= BETA
    lo, hi = r["ci95"]
    assert lo <= r["predicted_false_certification"] <= hi  # (1 - p)^N, as the proof says
    t = r["tolerant_check"]
    assert t["allowed"] >= 1 and t["n"] > r["n_eps"]
    assert t["false_certification_rate"] <= BETA
    assert t["ci95"][0] <= t["predicted_false_certification"] <= t["ci95"][1]  # P(Bin(N, p) <= k)
