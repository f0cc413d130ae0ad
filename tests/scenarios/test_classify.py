import numpy as np

from scenarios.base import CONTINUE, FAILURE, TRUNCATED
from scenarios.fleet3 import Fleet3
from scenarios.lead_follow import LeadFollow
from scenarios.registry import make_scenario


def test_classification_of_each_facet():
    sc = LeadFollow(sv_policy="idm")
    states = np.array([
        [10.0, 10.0, 30.0],   # inside
        [10.0, 10.0, -0.1],   # through the failure facet p10 < 0
        [20.5, 10.0, 30.0],   # v0 > 20: truncating
        [10.0, 10.0, 70.5],   # p10 > 70: truncating
        [21.0, 10.0, -1.0],   # failure and truncation in one step: failure wins
        [10.0, 10.0, 0.0],    # exactly on the facet: inside
        [10.0, 10.0, -5e-10],  # crossed by less than 1e-9: inside
    ])
    assert sc.classify(states).tolist() == [CONTINUE, FAILURE, TRUNCATED, TRUNCATED, FAILURE, CONTINUE, CONTINUE]


def test_only_the_named_failure_facets_count():
    both = Fleet3(sv_policy="idm")
    lead_only = Fleet3(sv_policy="idm", failure_facets=["p10"])
    follower_contact = np.array([[3.0, 3.0, 3.0, 15.0, -4.0]])  # p20 > -5
    lead_contact = np.array([[3.0, 3.0, 3.0, 4.0, -15.0]])  # p10 < 5
    assert both.classify(follower_contact)[0] == FAILURE
    assert lead_only.classify(follower_contact)[0] == TRUNCATED
    assert lead_only.classify(lead_contact)[0] == FAILURE


def test_unknown_failure_facet_is_a_clear_error():
    import pytest

    with pytest.raises(ValueError, match="scenario.failure_facets: unknown facet 'v0'"):
        Fleet3(failure_facets=["v0"])


def test_one_state_is_classified_as_in_a_batch():
    """classify's one-state path (per-run simulators) decides as the batch path does,
    on facets, on the 1e-9 tolerance and across failure/truncation ties."""
    for name, facets in (("fleet3", None), ("fleet3", ["p10"]), ("lead-follow", None)):
        sc = make_scenario(name, failure_facets=facets)
        rng = np.random.default_rng(1)
        span = sc.upper - sc.lower
        states = rng.uniform(sc.lower - 0.2 * span, sc.upper + 0.2 * span, (3000, sc.n))
        edge = rng.integers(0, sc.n, 1000)
        states[np.arange(1000), edge] = np.where(rng.random(1000) < 0.5, sc.lower[edge], sc.upper[edge]) + \
            rng.choice([-2e-9, -1e-9, 0.0, 1e-9, 2e-9], 1000)
        batch = sc.classify(states)
        one = np.concatenate([sc.classify(states[i : i + 1]) for i in range(len(states))])
        assert np.array_equal(batch, one) and len(set(batch.tolist())) == 3
