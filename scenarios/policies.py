"""SV policies: the black box under test, and the IDM that drives traffic around it.
Policies see the SV speed, the lead speed and the bumper gap to the lead, never the
lead's action."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy._core.umath import clip as _clip  # the ufunc: np.clip's Python wrapper costs ~3 us a call

# IDM parameters of the SV (shared/spec/scenarios.md).
IDM_A = 0.73  # max acceleration [m/s^2]
IDM_B = 1.67  # comfortable deceleration [m/s^2]
IDM_V_DES = 30.0  # desired speed [m/s]
IDM_T = 1.5  # time headway [s]
IDM_S0 = 2.0  # jam distance [m]
IDM_DELTA = 4  # acceleration exponent
IDM_MIN, IDM_MAX = -4.67, 0.73  # clipping [m/s^2]
BRAKE_ACCEL = -10.0  # brake-to-stop [m/s^2]
# Gaps are floored here: with s* <= ~230 m in any state the scenarios reach, (s*/s)^2
# stays finite (< 1e205) and still saturates the lower clip for every s <= 1e-100, as
# the exact formula (or +inf at s <= 0) does: the same result, without overflow.
_GAP_FLOOR = 1e-100
assert IDM_DELTA == 4  # idm_accel() squares twice


@dataclass(frozen=True)
class IDMParameters:
    """One Intelligent Driver Model: its constants and its clipping range."""

    accel: float  # a [m/s^2]
    decel: float  # b [m/s^2]
    desired_speed: float  # v_des [m/s]
    headway: float  # T [s]
    jam_distance: float  # s0 [m]
    min_accel: float  # lower clip [m/s^2]; also the acceleration at a gap s <= 0
    max_accel: float  # upper clip [m/s^2]
    inv_2sqrt_ab: float = field(init=False, repr=False)  # 1 / (2 sqrt(a b)) [s^2/m], once

    def __post_init__(self):
        object.__setattr__(self, "inv_2sqrt_ab", 1.0 / (2.0 * np.sqrt(self.accel * self.decel)))


SV_IDM = IDMParameters(IDM_A, IDM_B, IDM_V_DES, IDM_T, IDM_S0, IDM_MIN, IDM_MAX)
# The cars between the SV and the scenario's commanded vehicles (platoon).
TRAFFIC_IDM = IDMParameters(accel=1.0, decel=2.0, desired_speed=30.0, headway=1.0, jam_distance=2.0,
                            min_accel=-6.0, max_accel=1.0)


def idm_accel(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray, params: IDMParameters,
              headway: np.ndarray | float | None = None, min_accel: np.ndarray | float | None = None) -> np.ndarray:
    """IDM acceleration [m/s^2] of a car at speed ``v0`` behind a car at ``v1`` with the
    bumper gap ``gap`` [m], all (B,):
    ``s* = s0 + max(0, v0 T + v0 (v0 - v1) / (2 sqrt(a b)))``,
    ``a0 = a (1 - (v0/v_des)^4 - (s*/s)^2)`` clipped to [min_accel, max_accel]; a gap
    s <= 0 gets min_accel (never divides by zero). ``headway`` [s] and ``min_accel``
    [m/s^2] replace the parameters' own, per row when arrays (B,).

    Branch-free: the gap is floored at 1e-100, so for s <= 0 the term (s*/s)^2 (s* >= s0
    > 0) is ~1e200 and the clip yields exactly min_accel."""
    headway = params.headway if headway is None else headway
    min_accel = params.min_accel if min_accel is None else min_accel
    # Written with in-place operations: this runs once per step on 1e5-row batches.
    s_star = v0 - v1
    s_star *= params.inv_2sqrt_ab
    s_star += headway
    s_star *= v0
    _clip(s_star, 0.0, np.inf, out=s_star)  # = max(0, .); numpy's scalar maximum is slower
    s_star += params.jam_distance
    positive_gap = _clip(gap, _GAP_FLOOR, np.inf)
    ratio_gap = np.divide(s_star, positive_gap, out=s_star)
    ratio_gap *= ratio_gap
    speed_term = v0 * (1.0 / params.desired_speed)
    speed_term *= speed_term
    speed_term *= speed_term  # exponent 4
    accel = np.subtract(1.0, speed_term, out=speed_term)
    accel -= ratio_gap
    accel *= params.accel
    _clip(accel, min_accel, params.max_accel, out=accel)
    return accel


def brake(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Brake to stop at -10 m/s^2, whatever happens."""
    return np.full_like(v0, BRAKE_ACCEL)


def idm(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """The SV's Intelligent Driver Model on the bumper gap ``gap`` [m], clipped to
    [-4.67, 0.73]; a non-positive gap gets the maximal braking."""
    return idm_accel(v0, v1, gap, SV_IDM)


def traffic_idm(v0: np.ndarray, v1: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """The traffic cars' IDM (a = 1, b = 2, T = 1 s, clipped to [-6, 1])."""
    return idm_accel(v0, v1, gap, TRAFFIC_IDM)


SV_POLICIES = {"idm": idm, "brake": brake}  # the first is the default
