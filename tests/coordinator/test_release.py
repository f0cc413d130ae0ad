"""A finished SPE campaign releases its indexes (Algorithm.release): the result, the
counts and the failure points answer as before, from the points alone."""

import numpy as np

from coordinator.alive_points import FrozenPoints
from coordinator.spe import SPE, SPESettings
from coordinator.coverage import AddFailures
from scenarios.registry import make_scenario


def test_release_keeps_the_result_counts_and_failures_and_drops_the_indexes():
    sc = make_scenario("lead-follow", "idm")
    for refine in ("band", "all"):
        spe = SPE(sc, SPESettings(delta0=2.0, delta_min=0.5, refine=refine))
        spe.end_round()
        spe.coverage.apply(AddFailures(spe.vertices.points[:3] + 0.1), spe.version + 1)
        spe._prune(np.array([0, 1, 2]))
        before = (spe.result(), spe.counts(), spe.failure_points())
        spe.release()
        assert isinstance(spe.vertices, FrozenPoints) and isinstance(spe.failures, FrozenPoints)
        after = (spe.result(), spe.counts(), spe.failure_points())
        assert after[0].result_hash == before[0].result_hash
        assert np.array_equal(after[0].half_widths, before[0].half_widths)
        assert after[1] == before[1]
        assert np.array_equal(after[2], before[2])
