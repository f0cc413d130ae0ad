"""A failure rate beside the set: P(failure) of runs started from a scenario distribution D,
estimated with an interval by stratifying Sigma around a quantified set S.

- ``Strata`` (``strata.py``): inside S, layers across its boundary, outside S; masses under D
  without simulation (``set_strata``; ``whole_strata`` is plain Monte Carlo);
- ``allocate`` (``allocation.py``): the pilot's equal split, then Neyman, with a defensive share;
- ``rate_interval``, ``difference_interval``, ``clopper_pearson``, ``zero_failure_bound``
  (``intervals.py``): the stage-weighted stratified estimator, paired differences, exact bounds;
- ``Tally`` (``tally.py``): runs and failures per stage and stratum;
- ``StageRun`` (``stages.py``): the stages on executors, in index order, keyed streams.

The distributions themselves are ``scenarios.distributions``. docs/guarantee.md sketches
why the estimator is unbiased and what the interval covers; docs/estimate.md measures it.
"""

from coordinator.estimation.allocation import allocate
from coordinator.estimation.intervals import (Interval, clopper_pearson, difference_interval, plain_half_width,
                                              rate_interval, zero_failure_bound)
from coordinator.estimation.stages import CommittedBatch, EstimateSettings, StageRun, draw_starts, estimate_seed
from coordinator.estimation.strata import Strata, set_strata, whole_strata
from coordinator.estimation.tally import Tally

__all__ = ["CommittedBatch", "EstimateSettings", "Interval", "StageRun", "Strata", "Tally", "allocate",
           "clopper_pearson", "difference_interval", "draw_starts", "estimate_seed", "plain_half_width",
           "rate_interval", "set_strata", "whole_strata", "zero_failure_bound"]
