"""How good a set is, without a reference: fresh runs from uniform start states in Sigma,
each set against the set's claim (docs/guarantee.md, "The holdout").

A start in the set whose run fails is an *overclaim*; for a deterministic system a start
outside the set whose run does not fail is a *miss* (its run decides it; under random
actions one run does not, so misses are not counted there). The shares come with exact
(Clopper-Pearson) 95 % intervals: P(fail | in the set) is one minus the set's precision,
as a user's uniform scenario would meet it.
"""

from __future__ import annotations

import numpy as np

from coordinator.binomial import LEVEL, clopper_pearson
from scenarios.base import FAILURE
from scenarios.streams import PURPOSE_START, RunStreams

HOLDOUT_INDEX = 1 << 62  # the holdout's sample indices: a stream range no campaign reaches


def holdout_starts(scenario, seed: int, runs: int) -> tuple[np.ndarray, np.ndarray]:
    """(sample indices, (runs, n) start states uniform in Sigma from each run's own stream)."""
    indices = np.arange(HOLDOUT_INDEX, HOLDOUT_INDEX + runs, dtype=np.uint64)
    u = RunStreams.of(seed, indices).uniform(0, PURPOSE_START, scenario.n)
    return indices, scenario.lower + u * (scenario.upper - scenario.lower)


def holdout_report(inside: np.ndarray, outcomes: np.ndarray, deterministic: bool) -> dict:
    """``inside`` (M,) bool: the starts the set claims; ``outcomes`` (M,): their runs'."""
    failed = outcomes == FAILURE
    m, claimed = len(inside), int(np.count_nonzero(inside))
    over = int(np.count_nonzero(inside & failed))
    out = {"runs": m, "in_set": claimed, "overclaims": over,
           "overclaim_share": over / claimed if claimed else 0.0,
           "overclaim_interval": list(clopper_pearson(over, claimed)), "level": LEVEL,
           "deterministic": deterministic}
    if deterministic:
        missed = int(np.count_nonzero(~inside & ~failed))
        wrong = over + missed
        out.update(misses=missed, miss_share=missed / (m - claimed) if m > claimed else 0.0,
                   miss_interval=list(clopper_pearson(missed, m - claimed)), disagreements=wrong,
                   disagreement_share=wrong / m if m else 0.0, disagreement_interval=list(clopper_pearson(wrong, m)))
    return out
