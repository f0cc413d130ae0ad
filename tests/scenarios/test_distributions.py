"""Scenario distributions D over Sigma (scenarios/distributions.py): truncated per-axis laws
drawn inside boxes by inverse CDF, exact box masses, recorded start states, one-line refusals."""

import numpy as np
import pytest
from scipy import stats

from scenarios.distributions import EmpiricalLaw, LogNormal, Normal, ProductLaw, Uniform, axis_law, empirical_law
from scenarios.errors import ConfigError

U = np.random.default_rng(3).random(200_000)


def _ks(draws, cdf) -> float:
    return stats.kstest(draws, cdf).statistic


def test_truncated_normal_draws_follow_the_truncated_law():
    law = Normal(15.0, 2.5, 0.0, 20.0)
    draws = law.between(U, np.zeros(len(U)), np.full(len(U), 20.0))
    truth = stats.truncnorm((0 - 15) / 2.5, (20 - 15) / 2.5, loc=15, scale=2.5)
    assert _ks(draws, truth.cdf) < 0.005
    assert draws.min() >= 0.0 and draws.max() <= 20.0


def test_lognormal_draws_inside_a_cell_follow_the_law_restricted_to_it():
    law = LogNormal(np.log(25.0), 0.6, 0.0, 70.0)
    a, b = 30.0, 45.0
    draws = law.between(U, np.full(len(U), a), np.full(len(U), b))
    base = stats.lognorm(0.6, scale=25.0)
    cdf = lambda x: (base.cdf(x) - base.cdf(a)) / (base.cdf(b) - base.cdf(a))  # noqa: E731
    assert _ks(draws, cdf) < 0.005
    assert law.masses(np.array([a, b]))[0] == pytest.approx((base.cdf(b) - base.cdf(a)) / base.cdf(70.0), rel=1e-12)


def test_far_tail_cells_keep_their_digits_and_their_order():
    law = Normal(0.0, 1.0, -50.0, 50.0)
    mass = law.masses(np.array([8.0, 9.0]))[0]
    assert mass == pytest.approx(stats.norm.sf(8.0) - stats.norm.sf(9.0), rel=1e-9)  # 1 - Phi would read 0
    draws = law.between(np.array([0.0, 0.5, 0.999]), np.full(3, 8.0), np.full(3, 9.0))
    assert draws[0] == pytest.approx(8.0) and 8.0 < draws[1] < draws[2] < 9.0  # increasing in u on the far side
    mirrored = law.between(np.array([0.0, 0.5]), np.full(2, -9.0), np.full(2, -8.0))
    assert mirrored[1] == pytest.approx(-draws[1])


def test_cell_masses_sum_to_one_and_a_product_law_multiplies_them():
    axes = (Normal(15.0, 2.5, 0.0, 20.0), Uniform(0.0, 20.0), LogNormal(3.2, 0.6, 5.0, 70.0))
    law = ProductLaw(axes, ("v0", "v1", "p10"))
    for axis, (lo, hi) in zip(axes, ((0, 20), (0, 20), (0, 70))):
        assert axis.masses(np.linspace(lo, hi, 37)).sum() == pytest.approx(1.0, abs=1e-12)
    assert (law.sample(np.random.default_rng(0).random((1000, 3)))[:, 2] >= 5.0).all()  # its own truncation
    assert law.digest == ProductLaw(axes, ("v0", "v1", "p10")).digest
    assert law.digest != ProductLaw((Normal(15.0, 2.0, 0.0, 20.0), *axes[1:]), ("v0", "v1", "p10")).digest


def test_a_law_outside_sigma_is_refused_in_one_line():
    with pytest.raises(ConfigError, match=r"estimate.axes.v0: the normal law \(mean = 60, std = 0.5\) puts no mass "
                                          r"inside \[0, 20\]"):
        axis_law("estimate.axes.v0", "normal", {"mean": 60.0, "std": 0.5}, 0.0, 20.0)
    with pytest.raises(ConfigError, match=r"estimate.axes.p10: \[low, high\] = \[-5, 10\] is not an interval inside "
                                          r"Sigma; allowed 0 <= low < high <= 70"):
        axis_law("estimate.axes.p10", "uniform", {"low": -5.0, "high": 10.0}, 0.0, 70.0)


def test_recorded_starts_are_drawn_row_by_row_and_checked_against_sigma():
    points = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    law = empirical_law("estimate.data", points, ("a", "b"), np.zeros(2), np.full(2, 10.0), {"file": "x.parquet"})
    assert isinstance(law, EmpiricalLaw)
    drawn = law.sample(np.array([0.0, 0.34, 0.99]))
    assert drawn.tolist() == points.tolist()
    with pytest.raises(ConfigError, match=r"estimate.data: 1 of 3 rows of x.parquet lie outside Sigma \(row 2: b = 16\)"
                                          r"; allowed b in \[0, 10\]"):
        empirical_law("estimate.data", points + [[0, 0], [0, 0], [0, 10]], ("a", "b"), np.zeros(2),
                      np.full(2, 10.0), {"file": "x.parquet"})
