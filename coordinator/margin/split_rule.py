"""Which axes of a box the boundary crosses, from the margins of its centre and of its
face neighbours' centres: the split rule of margin refinement (2n neighbours per box, so
its cost is linear in n, and a box splits only along the axes the boundary crosses).

A box needs refining along axis a when

- a neighbour across a face on axis a has the other label (safe against failing): the
  boundary lies between the two centres; or
- the margin's first-order change over the box, ``R = sum_a |g_a| h_a`` (``g`` estimated
  from the neighbours' margins by differences along each axis, ``h`` the half-widths),
  could reach zero inside it (``|m| <= KAPPA R``, with room for curvature), and axis a
  carries a fair share of that change (``|g_a| h_a >= TAU max_b |g_b| h_b``).

An axis along which a box has no neighbour at all (it spans Sigma there: a parameter
narrower than delta0) shows no change; it splits once the round's delta allows
(``spans_sigma``), or the set would claim the whole axis from runs at its middle.

At most ``MAX_AXES`` axes split at once (a box crossed obliquely in many axes is
refined over several waves, not into 2^n children at once), those whose label differs
first, then by their share of the change.

In the last round (at ``delta_min``) a box the boundary crosses is cut at the crossing
instead (coordinator/margin/cut_rule.py): bisection is left only to the safe boxes whose
claim is in doubt, those whose margin clears the claim's test (``m > KAPPA R``, first
order) but not the split's, which trusts a coarse box less. A bisection there decides
the claim with finer neighbours; a differing label or a margin near zero asks for the
cut, which places the boundary for two runs where bisection down to ``delta_min`` on both
of its sides took four per box and wave after wave.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KAPPA = 0.5  # a margin within 0.5 x its first-order change over the box (more in coarse boxes) may cross zero in it
TAU = 0.5  # an axis splits if it carries at least half of the largest axis's change
MAX_AXES = 2  # at most 2^2 children per split


@dataclass
class Neighbourhood:
    """For boxes (B) and each axis (n) and side (2: lower, upper face): the neighbour's
    centre coordinate along that axis, its margin and label; ``exists`` False where the
    face is Sigma's."""

    centre: np.ndarray  # (B, n) the boxes' centres
    half_width: np.ndarray  # (B, n)
    margin: np.ndarray  # (B,)
    safe: np.ndarray  # (B,) bool
    exists: np.ndarray  # (B, n, 2) bool
    at: np.ndarray  # (B, n, 2) the neighbour's centre along the axis
    margins: np.ndarray  # (B, n, 2)
    labels: np.ndarray  # (B, n, 2) bool: the neighbour is safe


def gradient(hood: Neighbourhood) -> np.ndarray:
    """(B, n) the margin's slope along each axis: a central difference where both
    neighbours exist, one-sided where one does, 0 where none."""
    lo_ok, hi_ok = hood.exists[..., 0], hood.exists[..., 1]
    c, m = hood.centre, hood.margin[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        both = (hood.margins[..., 1] - hood.margins[..., 0]) / (hood.at[..., 1] - hood.at[..., 0])
        upper = (hood.margins[..., 1] - m) / (hood.at[..., 1] - c)
        lower = (m - hood.margins[..., 0]) / (c - hood.at[..., 0])
    g = np.where(lo_ok & hi_ok, both, np.where(hi_ok, upper, np.where(lo_ok, lower, 0.0)))
    return np.nan_to_num(g, nan=0.0, posinf=0.0, neginf=0.0)


def curvature(hood: Neighbourhood) -> np.ndarray:
    """(B, n) the margin's second difference along each axis where both neighbours exist
    (0 elsewhere): how far a straight line through the centre misjudges it."""
    both = hood.exists[..., 0] & hood.exists[..., 1]
    c, m = hood.centre, hood.margin[:, None]
    d_lo, d_hi = c - hood.at[..., 0], hood.at[..., 1] - c
    with np.errstate(divide="ignore", invalid="ignore"):
        second = 2 * ((hood.margins[..., 1] - m) / d_hi - (m - hood.margins[..., 0]) / d_lo) / (d_lo + d_hi)
    return np.nan_to_num(np.where(both, second, 0.0), nan=0.0, posinf=0.0, neginf=0.0)


def first_order_change(hood: Neighbourhood) -> np.ndarray:
    """(B,) ``R = sum_a |g_a| h_a``: how much the margin may change from the centre to a
    corner of the box, to first order."""
    return (np.abs(gradient(hood)) * hood.half_width).sum(axis=1)


def wanted_axes(hood: Neighbourhood, finest: float, last_round: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """-> ((B, n) bool: the axes the boundary may cross, (B, n) float: each axis's
    priority, higher first: a differing label beats any share of the change). A box
    ``2^k`` times the ``finest`` half-width trusts its first-order estimate ``1 + k``
    times less: the margin is a minimum over time, smooth only piece by piece.
    ``last_round``: only the safe boxes whose claim is in doubt (the module's docstring)."""
    other = hood.exists & (hood.labels != hood.safe[:, None, None])
    differs = other.any(axis=2)
    h = hood.half_width
    change = np.abs(gradient(hood)) * h + 0.5 * np.abs(curvature(hood)) * h * h
    spread = change.sum(axis=1)
    coarse = 1.0 + np.log2(np.maximum(h.max(axis=1) / finest, 1.0))
    near = np.abs(hood.margin) <= KAPPA * coarse * spread
    share = change >= TAU * change.max(axis=1, keepdims=True)
    wanted = differs | (near[:, None] & share & (change > 0))
    if last_round:
        claimable = hood.margin > KAPPA * (np.abs(gradient(hood)) * h).sum(axis=1)  # refinement.claimed_leaves' test
        wanted &= (hood.safe & claimable & near)[:, None]
    priority = change + np.where(differs, np.inf, 0.0)
    return wanted, priority


def spans_sigma(hood: Neighbourhood) -> np.ndarray:
    """(B, n) bool: the box has no neighbour on either side along the axis (it spans Sigma
    there, as a parameter axis narrower than delta0 does): no neighbour shows how the
    margin changes along it, so the gradient reads 0 there and only a split can tell.
    Refinement splits such an axis once the round's delta allows it, whatever the margins."""
    return ~hood.exists.any(axis=2)


def choose(wanted: np.ndarray, priority: np.ndarray, splittable: np.ndarray) -> np.ndarray:
    """(B,) int64 bit masks: the wanted axes that may still split (``splittable``), at
    most ``MAX_AXES`` of them, the highest priority first."""
    allowed = wanted & splittable
    rank = np.argsort(-np.where(allowed, priority, -1.0), axis=1, kind="stable")[:, :MAX_AXES]
    pick = np.take_along_axis(allowed, rank, axis=1)
    bits = np.where(pick, np.left_shift(np.int64(1), rank), 0)
    return bits.sum(axis=1).astype(np.int64)
