"""The blocked prioritized sampler: kept up to date where the state changed, yet equal
bit for bit to one built from scratch (its draws feed a hashed result), and drawing
rho_i ~ alpha(d* - d_i) over the candidates only."""

import numpy as np
import pytest

from coordinator import sampler as sampler_mod
from coordinator.sampler import BLOCK, PrioritySampler
from coordinator.spe import ALPHAS
from farm import config as config_mod
from farm.jobs.quantification import run


REFRESH = PrioritySampler.refresh  # as written (one test wraps it)


def fresh(dist, count, candidate, alpha):
    s = PrioritySampler(alpha)
    REFRESH(s, dist, count, candidate)
    return s


def assert_same(a: PrioritySampler, b: PrioritySampler):
    assert a.blocks == b.blocks and a.d_star == b.d_star
    assert np.array_equal(a.cum[: a.blocks], b.cum[: b.blocks])
    assert np.array_equal(a.last[: a.blocks], b.last[: b.blocks])
    assert np.array_equal(a.top, b.top)


@pytest.mark.parametrize("alpha", ["identity", "square", "sqrt"])
def test_updates_where_touched_equal_a_fresh_build_through_appends_kills_and_falling_distances(alpha):
    rng = np.random.default_rng(7)
    dist = rng.uniform(0, 5, 3000)
    alive = np.ones(3000, dtype=bool)
    count = 700
    s = PrioritySampler(ALPHAS[alpha])
    changes_of_d_star = 0
    for step in range(80):
        candidate = lambda ids: alive[ids]  # noqa: E731
        before = s.d_star
        s.refresh(dist, count, candidate)
        changes_of_d_star += s.d_star != before
        assert_same(s, fresh(dist, count, candidate, ALPHAS[alpha]))
        u = rng.random(2000)
        assert np.array_equal(s.draw(u), fresh(dist, count, candidate, ALPHAS[alpha]).draw(u))
        # the next change: some appended, some killed, some nearer a new failure
        count = min(3000, count + int(rng.integers(0, 40)))
        killed = rng.choice(count, size=int(rng.integers(0, 5)), replace=False)
        alive[killed] = False
        s.touch(killed)
        fell = rng.choice(count, size=int(rng.integers(0, 30)), replace=False)
        if step % 13 == 0:  # now and then the farthest centre moves: d* changes
            fell = np.append(fell, np.flatnonzero(alive[:count])[np.argmax(dist[:count][alive[:count]])])
        dist[fell] *= rng.uniform(0.2, 1.0, len(fell))
        s.touch(fell)
    assert changes_of_d_star >= 3  # the d* path was taken, not only the touched blocks


def test_draws_follow_the_weights_and_never_a_dead_or_zero_weight_centre():
    rng = np.random.default_rng(1)
    count = 5 * BLOCK + 17
    dist = rng.integers(0, 6, count).astype(float)  # many centres at d* = 5: weight 0
    alive = rng.random(count) < 0.8
    alive[BLOCK : 2 * BLOCK] = False  # a whole dead block
    s = PrioritySampler(ALPHAS["identity"])
    total = s.refresh(dist, count, lambda ids: alive[ids])
    d_star = dist[alive].max()
    w = np.where(alive, d_star - dist, 0.0)
    assert total == pytest.approx(w.sum())
    edges = np.array([0.0, 1 - 2**-53, 0.5])
    u = np.concatenate([edges, rng.random(400_000)])
    ids = s.draw(u)
    assert (w[ids] > 0).all()
    freq = np.bincount(ids[len(edges):], minlength=count) / (len(u) - len(edges))
    p = w / w.sum()
    # binomial standard error per centre; 5 sigma over ~1,000 centres
    assert np.all(np.abs(freq - p) <= 5 * np.sqrt(p * (1 - p) / (len(u) - len(edges))) + 1e-12)


def test_draws_match_one_cumulative_sum_except_at_rounding_boundaries():
    """The blocks only regroup the same sums: a run starts from another centre only when
    u * total falls within rounding error of a boundary between two centres."""
    rng = np.random.default_rng(2)
    count = 200_000
    dist = rng.uniform(0, 3, count)
    alive = rng.random(count) < 0.9
    s = PrioritySampler(ALPHAS["identity"])
    s.refresh(dist, count, lambda ids: alive[ids])
    ids = np.flatnonzero(alive)
    cdf = np.cumsum(dist[ids].max() - dist[ids])
    u = rng.random(200_000)
    one_sum = ids[np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(ids) - 1)]
    assert (s.draw(u) == one_sum).mean() > 0.9999


def test_a_prioritized_campaign_keeps_its_sampler_equal_to_a_fresh_one(tmp_path, monkeypatch):
    """Every refresh of a real campaign (kills, failures, appends, round ends, boundary
    band) is checked against a sampler built from scratch on the same state."""
    checked = {"refreshes": 0, "partial": 0}
    def checked_refresh(self, dist, count, candidate):
        partial = self.d_star is not None
        total = REFRESH(self, dist, count, candidate)
        assert_same(self, fresh(dist, count, candidate, self.alpha))
        checked["refreshes"] += 1
        checked["partial"] += partial
        return total

    monkeypatch.setattr(sampler_mod.PrioritySampler, "refresh", checked_refresh)
    for boundary in (False, True):
        raw = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
               "quantify": {"delta0": 4.0, "delta_min": 1.0, "epsilon": 0.01, "horizon": 30, "boundary": boundary,
                            "certify": False},
               "farm": {"executor": "local", "batch_size": 256, "seed": 3}}
        run(config_mod.normalize(raw), tmp_path / f"b{boundary}", resume=False)
    assert checked["refreshes"] > 50 and checked["partial"] > 40


def test_the_in_block_search_counts_the_running_sums_at_most_the_rest():
    """The per-row binary search equals counting every running sum <= the rest,
    zero weights (equal sums, ties with the rest) included."""
    rng = np.random.default_rng(3)
    s = PrioritySampler(ALPHAS["identity"])
    weights = rng.random((40, BLOCK)) * (rng.random((40, BLOCK)) < 0.6)  # many zero weights
    s.cum = np.cumsum(weights, axis=1)
    block = rng.integers(0, 40, size=20000)
    rest = rng.random(20000) * s.cum[block, -1] * 1.1  # some beyond the block's total
    rest[:2000] = s.cum[block[:2000], rng.integers(0, BLOCK, size=2000)]  # exactly a running sum
    rest[2000:2100] = 0.0
    np.testing.assert_array_equal(s._count_at_most(block, rest), (s.cum[block] <= rest[:, None]).sum(axis=1))
