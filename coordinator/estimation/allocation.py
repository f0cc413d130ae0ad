"""How many runs each stratum gets in each stage.

An estimate runs in stages: a pilot of ``pilot`` runs, then stages that grow by
``GROWTH``. Stage t's allocation is a function of the outcomes of stages before it only
(never of its own), which is what keeps each stage's estimate unbiased
(docs/guarantee.md). The pilot splits its runs equally among the strata (the sizes of
the strata's standard deviations are unknown yet); every later stage splits by Neyman,
n_h proportional to W_h sigma_h, with sigma_h estimated from the earlier stages at the
posterior mean of the stratum's rate under Jeffreys' prior (``Tally.sigmas``).

Both mix in a defensive share ``DEFENSIVE`` of proportional allocation (n_h proportional
to W_h): a stratum where few runs have failed yet may still fail rarely, and a stratum
of rare failures carries variance that only its share of runs can reveal (without it, the
interval's coverage on the stochastic evidence case fell from 95 % to 90 %; docs/estimate.md). Every stratum gets at least ``FLOOR`` runs per stage, so that every
stage estimates every stratum.
"""

from __future__ import annotations

import numpy as np

GROWTH = 2.0  # each stage after the pilot's first successor doubles: few stage barriers (log N)
DEFENSIVE = 0.1  # share of each stage allocated proportionally to the masses
FLOOR = 2  # runs per stratum and stage at least


def stage_size(stage: int, pilot: int) -> int:
    """Planned runs of stage ``stage`` (0: the pilot; then pilot, 2 pilot, 4 pilot, ...)."""
    return pilot if stage == 0 else int(round(pilot * GROWTH ** (stage - 1)))


def smallest_stage(strata: int) -> int:
    """Fewer runs than this cannot give every stratum its floor."""
    return FLOOR * strata


def allocate(size: int, masses: np.ndarray, sigmas: np.ndarray | None) -> np.ndarray:
    """(H,) runs per stratum for a stage of ``size`` runs (at least ``smallest_stage``):
    ``sigmas`` (H,) the strata's estimated standard deviations, or None for the pilot's
    equal split; the largest remainders get the runs that rounding leaves."""
    masses = np.asarray(masses, dtype=float)
    strata = len(masses)
    if size < smallest_stage(strata):
        raise ValueError(f"a stage of {size} runs cannot give {strata} strata {FLOOR} runs each")
    if sigmas is None or not np.any(np.asarray(sigmas) > 0):
        target = np.full(strata, 1.0 / strata)  # nothing known (or nothing failed yet): equal shares
    else:
        need = masses * np.asarray(sigmas, dtype=float)
        target = need / need.sum()
    share = (1 - DEFENSIVE) * target + DEFENSIVE * masses / masses.sum()
    free = size - FLOOR * strata
    exact = share * free
    counts = np.floor(exact).astype(np.int64)
    left = free - int(counts.sum())
    if left:
        counts[np.argsort(-(exact - counts), kind="stable")[:left]] += 1
    return counts + FLOOR
