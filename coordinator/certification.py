"""The certification of a stochastic campaign's exported set: closing rounds and checks.

Certification is SPE's last round (at delta_min; a campaign of one round certifies from
its first run): the set is checked the way ``validate`` checks it (VAL^eps-delta: runs uniform
over the final centres, strict: a run must neither fail nor leave Phi_delta, near a known
failure or not). SPE's own rounds excuse a run that leaves only toward a known failure,
and they draw near failures (prioritized sampling), so the set they hand over violates
the strict rule several times as often as eps allows, nearly all of it in the boxes near
failures (docs/benchmarks.md, "Certification that converges"). Settling the set at
delta_min by SPE's lenient rule first and then again by the strict one cost 2.20x the
uncertified runs where closing it strictly at once costs 1.60x (docs/certification.md).

The scheme alternates two kinds of round, both strict:

- a *closing* round changes the set as SPE does (a failure prunes, a new state is
  explored, a run that leaves only toward known failures prunes its start's tree) and
  spends no beta. It draws uniformly over the *edge*: the alive centres within
  sigma-bar + delta of the set's failure-side boundary (Theorem 3: only their runs can
  leave the set in one step; SPE's ``_near_boundary``), where the violations are. It ends
  after ``closing_quiet`` runs in a row that change nothing.
- a *check* draws uniformly over all final centres and changes nothing while it runs:
  check i passes after ``check_quiet(i)`` runs since it began with at most ``tolerance``
  violations among them (the binomial test at beta_i = 6 beta / (pi^2 i^2),
  coordinator/sample_size.py; tolerance 0 is N_eps in a row). A violation within the
  tolerance is counted and not applied (the set must stay the one checked); the one
  past it ends the check: its change is applied and a closing round follows.

Why the exported set keeps its guarantee (docs/guarantee.md has the sketch): only checks
certify, each on runs drawn after the set it checks was fixed, and their betas sum to
beta; the closing rounds choose which set is checked and when, which the union bound
over checks allows.

The closing round's length is chosen so that a check usually passes at its first try: a
violation rate p_edge over the edge is, if only the edge can violate, a rate
share x p_edge over all centres (share: the edge's share of the centres), so
N_eps(eps / (margin x share)) quiet edge runs say about as much as N_eps(eps / margin)
uniform runs would, and the check (N_eps at eps) then fails with probability about
1 - (1 - eps / margin)^N_eps (the margin's choice: docs/certification.md).

Why checks tolerate violations (``TOLERANCE``): a closing round leaves a residual rate thin
over the whole edge, about eps / 5 over all centres (docs/certification_tail.md,
docs/guarantee.md), which a check allowing none fails 43 % of the time at check 1 and more
at later checks (N grows with i), each failure costing a closing round that finds only the
few violations then left and a longer check. The binomial test allowing a few tells eps / 5
from eps with far more power for a few thousand more runs: check 1 passes such a set with
probability 0.57 allowing none (2,799 runs) and 0.94 allowing three (7,456 runs). Three,
at the margin 4, measured on 16 seeds: docs/certification.md, "The tolerance".
"""

from __future__ import annotations

from coordinator.sample_size import n_eps, n_eps_attempt

CLOSING, CHECK = "closing", "check"
MARGIN = 4.0  # quantify.certify_margin's default (docs/certification.md)
TOLERANCE = 3  # quantify.certify_tolerance's default (docs/certification.md)
MAX_CLOSING_EPSILON = 0.5  # a tiny edge: a few runs (N_eps at 0.5) still close it


def closing_quiet(epsilon: float, beta: float, margin: float, share: float) -> int:
    """Quiet edge runs in a row that end a closing round: N_eps at eps / (margin x share),
    ``share`` the edge's share of the alive centres (1: the edge is the whole set)."""
    return n_eps(min(epsilon / (margin * max(share, 1e-12)), MAX_CLOSING_EPSILON), beta)


def check_quiet(epsilon: float, beta: float, attempt: int, tolerance: int = 0) -> int:
    """Uniform runs that pass check ``attempt`` (1, 2, ...) with at most ``tolerance``
    violations among them."""
    return n_eps_attempt(epsilon, beta, attempt, tolerance)
