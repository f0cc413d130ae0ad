"""Exact (Clopper-Pearson) intervals of a binomial share: the holdout's, the references'
and the failure-rate estimate's one home.

``scipy.special.betaincinv`` rather than ``scipy.stats.beta.ppf``: the same quantile,
without scipy.stats, whose import is most of a CLI command's start (docs/benchmarks.md,
"Imports")."""

from __future__ import annotations

from scipy.special import betaincinv

LEVEL = 0.95


def clopper_pearson(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """The exact two-sided interval, at ``level``, for a share of ``k`` in ``n`` (0 to 1 when n is 0)."""
    if n == 0:
        return 0.0, 1.0
    alpha = 1.0 - level
    low = 0.0 if k == 0 else float(betaincinv(k, n - k + 1, alpha / 2))
    high = 1.0 if k == n else float(betaincinv(k + 1, n - k, 1 - alpha / 2))
    return low, high
