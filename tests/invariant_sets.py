"""Domains known to be forward invariant, as predicates for validation tests."""

import numpy as np

from scenarios.lead_follow import LeadFollow


def min_future_gap_brake(states: np.ndarray) -> np.ndarray:
    """Smallest future bumper gap of lead-follow/brake under the adversarial action
    (lead brakes at -5): since the brake SV ignores the lead, maximal lead braking
    minimises the gap at every future time, so this is the worst case over Gamma."""
    sc = LeadFollow(sv_policy="brake")
    s = np.array(states, dtype=float)
    gap = s[:, 2].copy()
    u = np.full((len(s), 1), -5.0)
    for _ in range(60):  # both vehicles stop within 40 steps from 20 m/s
        s = sc.step(s, u, None)
        gap = np.minimum(gap, s[:, 2])
    return gap


def brake_superlevel_5(states: np.ndarray) -> np.ndarray:
    """{sigma : min future gap under Gamma* >= 5 m}: forward invariant for the brake SV."""
    return min_future_gap_brake(states) >= 5.0
