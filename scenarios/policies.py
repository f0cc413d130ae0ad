"""SV policies: the black box under test. They see the SV speed, the lead speed and the
bumper gap to the lead, never the lead's action."""

from __future__ import annotations

import numpy as np
from numpy._core.umath import clip as _clip  # the ufunc: np.clip's Python wrapper costs ~3 us a call

# IDM parameters of the spec (shared/spec/scenarios.md).
IDM_A = 0.73  # max acceleration [m/s^2]
IDM_B = 1.67  # comfortable deceleration [m/s^2]
IDM_V_DES = 30.0  # desired speed [m/s]
IDM_T = 1.5  # time headway [s]
IDM_S0 = 2.0  # jam distance [m]
IDM_DELTA = 4  # acceleration exponent
IDM_MIN, IDM_MAX = -4.67, 0.73  # clipping [m/s^2]
BRAKE_ACCEL = -10.0  # brake-to-stop [m/s^2]
_INV_2SQRT_AB = 1.0 / (2.0 * np.sqrt(IDM_A * IDM_B))
# Gaps are floored here: with s* <= ~230 m in any state the scenarios reach, (s*/s)^2
# stays finite (< 1e205) and still saturates the clip at -4.67 for every s <= 1e-100, as
# the exact formula (or +inf at s <= 0) does: the same result, without overflow.
_GAP_FLOOR = 1e-100
assert IDM_DELTA == 4  # idm() squares twice


def brake(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Brake to stop at -10 m/s^2, whatever happens."""
    return np.full_like(v0, BRAKE_ACCEL)


def idm(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Intelligent Driver Model on the bumper gap ``gap`` [m], clipped to [-4.67, 0.73];
    a non-positive gap gets the maximal braking (never divides by zero).

    Branch-free: the gap is floored at 1e-100, so for s <= 0 the term (s*/s)^2 (s* >= s0
    > 0) is ~1e200 and the clip yields exactly -4.67."""
    # Written with in-place operations: this runs once per step on 1e5-row batches.
    s_star = v0 - v1
    s_star *= _INV_2SQRT_AB
    s_star += IDM_T
    s_star *= v0
    _clip(s_star, 0.0, np.inf, out=s_star)  # = max(0, .); numpy's scalar maximum is slower
    s_star += IDM_S0
    positive_gap = _clip(gap, _GAP_FLOOR, np.inf)
    ratio_gap = np.divide(s_star, positive_gap, out=s_star)
    ratio_gap *= ratio_gap
    speed_term = v0 * (1.0 / IDM_V_DES)
    speed_term *= speed_term
    speed_term *= speed_term  # exponent 4
    accel = np.subtract(1.0, speed_term, out=speed_term)
    accel -= ratio_gap
    accel *= IDM_A
    _clip(accel, IDM_MIN, IDM_MAX, out=accel)
    return accel


SV_POLICIES = {"idm": idm, "brake": brake}  # the first is the default
