"""Sampled certification (coordinator/certification.py): the last round is closing rounds
and checks; closing rounds spend no beta, checks do; a real campaign ends on a passed
check after a bounded number of attempts, accounts for the runs certification took, and
exports a set a fresh validate certifies more often than not; a check passes with at most
quantify.certify_tolerance violations (the binomial test) and exports the set it checked."""

import numpy as np
import pytest

from scipy import stats

from coordinator.certification import TOLERANCE, check_quiet, closing_quiet
from coordinator.sample_size import n_eps, n_eps_allowing, n_eps_attempt
from farm import api
from farm import config as config_mod
from farm.jobs.campaign_setup import build_algorithm, build_campaign
from farm.execution.process import spec_of
from farm.execution.local import LocalExecutor

EPS, BETA = 0.01, 0.1
LF_IDM = {"name": "lead-follow", "sv_policy": "idm"}


def test_closing_rounds_aim_at_eps_over_margin_and_shrink_with_the_band():
    assert closing_quiet(EPS, BETA, 4.0, 1.0) == n_eps(EPS / 4, BETA)
    # a band of a tenth of the centres: as much evidence about the whole set's rate, if
    # only the band can violate, from a tenth of the runs
    assert closing_quiet(EPS, BETA, 4.0, 0.1) == n_eps(EPS / 0.4, BETA) < closing_quiet(EPS, BETA, 4.0, 1.0)
    assert closing_quiet(EPS, BETA, 16.0, 0.1) > closing_quiet(EPS, BETA, 4.0, 0.1)
    assert closing_quiet(EPS, BETA, 1.0, 1e-9) == n_eps(0.5, BETA)  # a tiny band: a few runs still close it
    assert [check_quiet(EPS, BETA, i) for i in (1, 2, 10)] == [n_eps_attempt(EPS, BETA, i) for i in (1, 2, 10)]


@pytest.mark.parametrize("eps,beta", [(0.001, 0.1), (0.01, 0.05), (0.1, 0.001)])
def test_a_check_allowing_k_violations_runs_the_least_n_of_the_binomial_test(eps, beta):
    assert n_eps_allowing(eps, beta, 0) == n_eps(eps, beta)
    needs = [n_eps_allowing(eps, beta, k) for k in range(6)]
    assert needs == sorted(set(needs))  # each violation allowed costs runs
    for k, n in enumerate(needs):
        # a set at exactly eps passes with probability at most beta, and with one run less more than beta
        assert stats.binom.cdf(k, n, eps) <= beta < stats.binom.cdf(k, n - 1, eps)
    assert n_eps_attempt(eps, beta, 3, 2) == n_eps_allowing(eps, beta * 6 / (np.pi**2 * 9), 2)


def test_a_check_passes_with_violations_within_its_tolerance_and_exports_the_set_it_checked():
    """Seed 3: the first check sees one violation. Allowing none, it fails and more
    closing rounds and checks follow; allowing two, it passes, and the set exported is the one
    the check began on (a campaign stopped there holds the same set)."""
    strict, _, _, _ = run_in_process(_config(3, certify_tolerance=0))
    tolerant, algo, _, _ = run_in_process(_config(3, certify_tolerance=2))
    assert strict.attempts > 1 and strict.check_violations == 0
    assert tolerant.attempts == 1 and tolerant.check_violations == tolerant.violations_tolerated(2) == 1
    assert tolerant.closing_ends == strict.closing_ends[:1]  # the same first closing round
    assert tolerant.committed - tolerant.closing_ends[0] == check_quiet(EPS, BETA, 1, 2) > check_quiet(EPS, BETA, 1, 0)
    stopped, at_check, _, _ = run_in_process(_config(3, certify_tolerance=2, budget=tolerant.closing_ends[0]))
    assert not stopped.converged and at_check.result().result_hash == algo.result().result_hash


def run_in_process(cfg):
    executor = LocalExecutor(spec_of(cfg))
    algo = build_algorithm(cfg, executor.simulator)
    return build_campaign(cfg, algo, executor.simulator, executor).run(), algo, None, None


def _config(seed: int, certify: bool = True, **quantify):
    return config_mod.normalize({
        "scenario": LF_IDM, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": EPS, "beta": BETA, "horizon": 30,
                     "certify": certify, **quantify},
        "farm": {"executor": "local", "seed": seed, "batch_size": 256}})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_certified_campaign_ends_on_a_passed_check_in_few_attempts(seed):
    counters, algo, _, _ = run_in_process(_config(seed))
    assert counters.converged and algo.certifying and not algo.closing  # it ended on a passed check
    assert 1 <= counters.attempts <= 10, counters.attempts
    # certification is the last round (at delta_min): it took everything after the round
    # before it, and SPE's rounds before it are the uncertified campaign's, run for run
    before_last = counters.round_ends[algo.round - 1]
    assert counters.certification_from == before_last
    assert counters.runs_certification == counters.committed - before_last > 0
    # ended by a passed check after the last closing round: each check follows a closing round
    assert len(counters.round_ends) == algo.round + 1 and counters.round_ends[-1] == counters.committed
    assert len(counters.closing_ends) == counters.attempts
    assert counters.committed - counters.closing_ends[-1] == check_quiet(EPS, BETA, counters.attempts, TOLERANCE)
    # each failed check saw one violation past the tolerance; the passing one at most the tolerance
    assert counters.check_violations <= TOLERANCE
    uncertified, plain, _, _ = run_in_process(_config(seed, certify=False))
    assert uncertified.round_ends[: algo.round] == counters.round_ends[: algo.round]
    # it ran the last round by SPE's rule instead
    assert plain.round == algo.round and len(uncertified.round_ends) == algo.round + 1


def test_the_certified_set_passes_a_fresh_validate_more_often_than_not(tmp_path):
    result = api.quantify(_config(3), out=tmp_path / "q")
    assert result.summary["runs_certification"] > 0 and result.summary["certification_attempts"] >= 1
    passed = []
    for seed in range(5):
        cert = api.validate({"scenario": LF_IDM, "actions": {"mode": "uniform"},
                             "validate": {"algorithm": "eps-delta", "epsilon": EPS, "beta": BETA, "horizon": 30,
                                          "delta": result.half_width,
                                          "domain_set": str(tmp_path / "q" / "safe_set.parquet")},
                             "farm": {"executor": "local", "seed": 1000 + seed}})
        passed.append(cert.certified)
    assert sum(passed) >= 3, passed


def test_a_larger_margin_closes_longer_and_checks_no_more_often():
    small, _, _, _ = run_in_process(_config(1, certify_margin=1.0))
    large, _, _, _ = run_in_process(_config(1, certify_margin=64.0))
    first_closing = [c.closing_ends[0] - c.certification_from for c in (small, large)]
    assert first_closing[1] > first_closing[0]
    assert large.attempts <= small.attempts
    assert np.all([c.converged for c in (small, large)])
