"""Estimators and confidence intervals of a failure rate from stratified stages.

With strata of masses W_h under D, stage t running n_th runs in stratum h of which x_th
fail, and stage weights lambda_t = m_t / M (m_t the stage's runs, M = sum_t m_t):

    p_hat = sum_t lambda_t sum_h W_h x_th / n_th                        (unbiased: each stage is)
    V_hat = sum_h W_h^2 s_h^2 sum_t lambda_t^2 / n_th                   (s_h^2: stratum h's sample
                                                                         variance, all stages pooled)
    interval: p_hat +- z_{1 - alpha/2} sqrt(V_hat), clipped to [0, 1]

The difference of two controllers run on the same starts and streams is the same
estimator over d = fail_A - fail_B in {-1, 0, 1} (paired: common random numbers).
Exact bounds (Clopper-Pearson) take over where the normal approximation has nothing to
stand on: plain Monte Carlo (one stratum) and no failure at all, where the one-sided
bound 1 - alpha^(1/N) is the N_eps rule read backwards (N = ln alpha / ln(1 - bound)).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.special import ndtri

from coordinator.binomial import clopper_pearson


@dataclass(frozen=True)
class Interval:
    """An estimate with its interval at ``confidence``; ``method`` says how it was made;
    ``standard_error``: sqrt(V_hat) (None for an exact bound)."""

    estimate: float
    low: float
    high: float
    confidence: float
    method: str
    standard_error: float | None = None

    @property
    def half_width(self) -> float:
        return 0.5 * (self.high - self.low)

    def to_json(self) -> dict:
        return {**asdict(self), "half_width": self.half_width}


def z_value(confidence: float) -> float:
    """The two-sided normal quantile z_{1 - alpha/2}."""
    return float(ndtri(0.5 + confidence / 2))


def stage_weights(runs: np.ndarray) -> np.ndarray:
    """(T,) lambda_t = m_t / M from the runs (T, H) of each stage."""
    per_stage = runs.sum(axis=1).astype(float)
    return per_stage / per_stage.sum()


def zero_failure_bound(masses: np.ndarray, runs_per_stratum: np.ndarray, confidence: float) -> float:
    """With no failure in any stratum: p <= sum_h W_h (1 - (alpha / H)^(1 / n_h)), each
    stratum's one-sided Clopper-Pearson bound at alpha / H (all hold together with
    probability at least 1 - alpha); one stratum: 1 - alpha^(1/N), the N_eps rule."""
    alpha = 1 - confidence
    per = alpha / len(masses)
    return float(np.sum(masses * -np.expm1(np.log(per) / np.maximum(runs_per_stratum, 1))))


def _pooled_variance(n: np.ndarray, total: np.ndarray, squares: np.ndarray) -> np.ndarray:
    """Per stratum, the unbiased sample variance from n runs, the sum and the sum of squares."""
    with np.errstate(invalid="ignore", divide="ignore"):
        var = (squares - total**2 / n) / (n - 1)
    return np.where(n > 1, np.maximum(var, 0.0), 0.0)


def _stratified(masses, runs, sums, pooled_var, confidence, method) -> Interval:
    lam = stage_weights(runs)
    estimate = float(np.sum(lam[:, None] * masses[None, :] * sums / runs))
    variance = float(np.sum(masses**2 * pooled_var * np.sum(lam[:, None] ** 2 / runs, axis=0)))
    se = float(np.sqrt(variance))
    z = z_value(confidence)
    return Interval(estimate, estimate - z * se, estimate + z * se, confidence, method, se)


def rate_interval(masses: np.ndarray, runs: np.ndarray, failures: np.ndarray, confidence: float) -> Interval:
    """P(failure) from stages: ``runs`` and ``failures`` (T, H), every entry of ``runs`` >= 1."""
    masses = np.asarray(masses, dtype=float)
    n_h, x_h = runs.sum(axis=0), failures.sum(axis=0)
    if x_h.sum() == 0:
        bound = zero_failure_bound(masses, n_h, confidence)
        return Interval(0.0, 0.0, bound, confidence, "no failure: exact one-sided bound (Clopper-Pearson, "
                        + ("the N_eps rule)" if len(masses) == 1 else "per stratum at alpha / H)"))
    if len(masses) == 1:
        low, high = clopper_pearson(int(x_h[0]), int(n_h[0]), confidence)
        return Interval(float(x_h[0] / n_h[0]), low, high, confidence, "plain Monte Carlo: exact (Clopper-Pearson)",
                        float(np.sqrt(x_h[0] / n_h[0] * (1 - x_h[0] / n_h[0]) / n_h[0])))
    out = _stratified(masses, runs, failures, _pooled_variance(n_h, x_h, x_h), confidence,
                      "stratified: normal, stage-weighted")
    return Interval(out.estimate, max(out.low, 0.0), min(out.high, 1.0), confidence, out.method, out.standard_error)


def difference_interval(masses: np.ndarray, runs: np.ndarray, a_only: np.ndarray, b_only: np.ndarray,
                        confidence: float) -> Interval:
    """P(A fails) - P(B fails) from paired runs: ``a_only`` (T, H) runs where A failed and B
    did not, ``b_only`` the converse (d = +1 and -1; both or neither: d = 0)."""
    masses = np.asarray(masses, dtype=float)
    n_h = runs.sum(axis=0)
    total = (a_only - b_only).sum(axis=0)
    squares = (a_only + b_only).sum(axis=0)
    if squares.sum() == 0:  # the two never differed: bound how often they could
        bound = zero_failure_bound(masses, n_h, confidence)
        return Interval(0.0, -bound, bound, confidence, "no run where they differ: exact bound on P(A and B differ)")
    out = _stratified(masses, runs, a_only - b_only, _pooled_variance(n_h, total, squares), confidence,
                      "paired (same starts and streams): normal, stage-weighted")
    return Interval(out.estimate, max(out.low, -1.0), min(out.high, 1.0), confidence, out.method, out.standard_error)


def plain_half_width(rate: float, runs: int, confidence: float) -> float:
    """The half-width plain Monte Carlo's interval would have at ``runs`` runs, at ``rate``."""
    return z_value(confidence) * float(np.sqrt(max(rate * (1 - rate), 0.0) / max(runs, 1)))
