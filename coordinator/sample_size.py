"""How many runs a guarantee needs: Lemma 1 (resolution) and Lemma 2 (probability)."""

from __future__ import annotations

import functools

import numpy as np
from scipy import special  # bdtr, the binomial cdf: scipy.stats would add 1.6 s to every CLI command's start


def covering_size(volume: float, delta: float, n: int) -> int:
    """Lemma 1: N >= |Phi| / (2 delta)^n runs make VAL^delta resolution complete."""
    return int(np.ceil(volume / (2 * delta) ** n - 1e-9))


def n_eps_attempt(epsilon: float, beta: float, attempt: int, allowed: int = 0) -> int:
    """N for the ``attempt``-th certification of a changing set: beta_i = 6 beta /
    (pi^2 i^2), which sums to beta over all attempts. A set that fails its check is
    changed and checked again; each bad set passes its own check with probability
    <= beta_i, so the one finally exported is bad with probability <= beta (a union
    bound; N grows only with ln i). Measured without it: 4 of 20 exported sets above
    eps at beta = 0.1 (docs/guarantee.md). ``allowed``: violations the check may see
    and still pass (``n_eps_allowing``)."""
    return n_eps_allowing(epsilon, beta * 6 / (np.pi**2 * attempt**2), allowed)


@functools.lru_cache(maxsize=256)  # the driver asks for a check's N after every chunk: ~40 cdf evaluations each
def n_eps_allowing(epsilon: float, beta: float, allowed: int) -> int:
    """The least N such that N runs with at most ``allowed`` violations among them certify:
    a set whose violation rate exceeds eps shows at most ``allowed`` in N i.i.d. runs with
    probability P(Binomial(N, eps) <= allowed) <= beta (the binomial test; 0 allowed is
    Lemma 2's N_eps). A test that tolerates a few violations tells a rate of eps / 10 from
    one of eps far more often than one that tolerates none, for a few more runs
    (docs/certification.md)."""
    if allowed == 0:
        return n_eps(epsilon, beta)
    lo = n_eps(epsilon, beta)  # the cdf falls in N: search upward from the 0-allowed need
    hi = 2 * lo
    while special.bdtr(allowed, hi, epsilon) > beta:
        lo, hi = hi, 2 * hi
    while lo < hi:
        mid = (lo + hi) // 2
        if special.bdtr(allowed, mid, epsilon) <= beta:
            hi = mid
        else:
            lo = mid + 1
    return int(lo)


def n_eps(epsilon: float, beta: float) -> int:
    """Lemma 2: N_eps = ceil(ln(beta) / ln(1 - epsilon)) consecutive successes."""
    return int(np.ceil(np.log(beta) / np.log1p(-epsilon) - 1e-9))
