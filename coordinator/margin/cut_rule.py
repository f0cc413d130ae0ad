"""Where the boundary crosses a box, from its margins: the cut of margin refinement's last
round (coordinator/margin/refinement.py).

Bisection places the boundary to within a box, and halving that box costs four runs
(two axes) on each side of the boundary, wave after wave. A margin places it better: to
first order the margin is ``m + g . (x - c)`` over the box (``g`` from the face
neighbours' margins, coordinator/margin/split_rule.py), so it is zero on the plane
``x_a = c_a - m / g_a`` along the axis ``a`` that carries most of its change
(``|g_a| h_a``). Across the box that crossing moves by up to ``V / |g_a|``, where
``V = sum_{b != a} |g_b| h_b`` is the change along the other axes. A box is cut along
``a`` at the crossing moved ``CUT_SHIFT V / |g_a|`` to its safe side (the side the margin
grows to): two children, each run from its centre, and the safe side's is claimed by
the claim's own test (``m > KAPPA R``) on its own run and neighbours.

The boxes cut: the safe ones the claim leaves out (``m <= KAPPA R``: the boundary may
cross them) and the failing ones whose margin the change across the box can bring to
zero (``-m <= R``: a safe part may lie in them). A cut that would leave either child
less than ``CUT_MIN_SHARE`` of the box's width along ``a`` is not made: the box is
within that of being all on one side. ``CUT_PASSES`` passes of cuts end the refinement;
each pass looks at the partition the last one left.
"""

from __future__ import annotations

import numpy as np

from coordinator.margin.split_rule import KAPPA, Neighbourhood, gradient

CUT_PASSES = 3  # each pass finds fewer boxes to cut (docs/margin_refinement.md measures 1 to 3)
CUT_SHIFT = 0.5  # of the crossing's movement across the box, toward the safe side
CUT_MIN_SHARE = 0.15  # of the box's width along the cut axis, each side at least


def cuts(hood: Neighbourhood, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For boxes (B) with their neighbourhoods and bounds ``lo`` / ``hi`` (B, n): ->
    ((B,) bool: the box is cut, (B,) int: along which axis, (B, n): the cut point (the
    centre but along that axis))."""
    g = gradient(hood)
    change = np.abs(g) * hood.half_width
    axis = np.argmax(change, axis=1)
    rows = np.arange(len(axis))
    g_a = g[rows, axis]
    spread = change.sum(axis=1)
    other = spread - change[rows, axis]
    m = hood.margin
    crossed = np.where(hood.safe, m <= KAPPA * spread, -m <= spread) & (g_a != 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        plane = hood.centre[rows, axis] - m / g_a + np.sign(g_a) * CUT_SHIFT * other / np.abs(g_a)
    lo_a, hi_a = lo[rows, axis], hi[rows, axis]
    room = CUT_MIN_SHARE * (hi_a - lo_a)
    cut = crossed & np.isfinite(plane) & (plane >= lo_a + room) & (plane <= hi_a - room)
    at = hood.centre.copy()
    at[rows, axis] = np.where(cut, plane, at[rows, axis])
    return cut, axis, at
