"""``lead-follow-params`` (5-D): lead-follow over a domain of two parameters, the SV's
IDM time headway T and the road's friction coefficient mu. Parameters are state axes
that never change during a run (``Scenario.parameter_names``, step bound 0), so one
campaign quantifies the safe set over states and parameters together.

State ``sigma = (v0, v1, p10, T, mu)``: SV speed [m/s], lead speed [m/s], bumper gap from
SV front to lead rear [m], IDM time headway [s], friction coefficient [-].

- Sigma: ``v0, v1 in [0, 20]``, ``p10 in [0, 70]``, ``T in [0.8, 2.0]``, ``mu in [0.4, 1.0]``.
- Failure facet: ``p10 < 0`` (contact). Truncating facets: ``v0 > 20``, ``v1 > 20``,
  ``p10 > 70``. T and mu never change, so a run never leaves through their facets.
- Scenario action: the lead's commanded acceleration ``u in Gamma = [-5, 3]`` [m/s^2],
  Gamma* = {-5}. Friction scales every braking limit: the lead applies
  ``a1 = u`` for ``u >= 0`` and ``a1 = mu * u`` for ``u < 0``, so u is the braking asked
  for as a share of the dry road's and Gamma* = -5 still means "brake as hard as the
  road allows" (``-5 mu``). Accelerating (at most 3 m/s^2 < 0.4 g) is not limited.
- SV policies (see ``lead-follow``), their braking limits scaled by mu:
  - ``brake``: ``a0 = -10 mu``.
  - ``idm``: the SV IDM (a = 0.73, b = 1.67, v_des = 30, s0 = 2, exponent 4) with the
    row's own time headway T: ``s* = s0 + max(0, v0 T + v0 (v0 - v1) / (2 sqrt(a b)))``,
    ``a0 = a (1 - (v0/v_des)^4 - (s*/s)^2)`` with ``s = p10``, clipped to
    ``[-4.67 mu, 0.73]``; ``s <= 0`` gives ``-4.67 mu``. (b, the comfortable
    deceleration, is the driver's wish, not a road limit: it is not scaled.)
- Disturbance w (default 0): a U[-w, w] draw added to a0 and to a1 after the above, as
  in every scenario. Kinematics: scenarios/kinematics.py (vehicles never reverse).

At T = 1.5 s and mu = 1 this is lead-follow exactly (bit for bit).
"""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario, Slices, View
from scenarios.kinematics import advance, disturb
from scenarios.policies import BRAKE_ACCEL, IDM_MIN, SV_IDM, idm_accel
from scenarios.worst_case_rollout import safe_until_standstill


def idm_on_road(v0, v1, gap, headway, friction):
    """The SV IDM with time headway ``headway`` [s] (B,), its braking limited to
    -4.67 ``friction`` [m/s^2]."""
    return idm_accel(v0, v1, gap, SV_IDM, headway=headway, min_accel=friction * IDM_MIN)


def brake_on_road(v0, v1, gap, headway, friction):
    """Brake to stop as hard as the road allows: -10 ``friction`` [m/s^2]."""
    return friction * BRAKE_ACCEL


class LeadFollowParams(Scenario):
    name = "lead-follow-params"
    state_names = ("v0", "v1", "p10", "T", "mu")
    parameter_names = ("T", "mu")
    lower = np.array([0.0, 0.0, 0.0, 0.8, 0.4])
    upper = np.array([20.0, 20.0, 70.0, 2.0, 1.0])
    failure_sides = {"p10": False}  # contact: p10 < 0
    action_names = ("u1",)
    action_lower = np.array([-5.0])
    action_upper = np.array([3.0])
    adversarial_actions = np.array([[-5.0]])  # the lead brakes as hard as the road allows
    noise_width = 2
    # SV policies here see the parameters too: (v0, v1, gap, headway, friction) -> accel
    sv_policies = {"idm": idm_on_road, "brake": brake_on_road}
    units = {"v0": "m/s", "v1": "m/s", "p10": "m", "T": "s"}  # mu is a ratio
    state_words = {"v0": "the SV's speed", "v1": "the lead's speed", "p10": "the gap from the SV's front to the lead's rear",
                   "T": "the SV's IDM time headway", "mu": "the road's friction (scales every braking limit)"}
    action_words = {"u1": "the lead vehicle's commanded acceleration (braking scaled by the road's friction)"}
    action_units = {"u1": "m/s^2"}
    failure_words = "collide"
    margin_through_contact = True  # gaps may go negative: the kinematics and the IDM (s <= 0) stay defined
    adversary_settle_steps = 400  # as lead-follow: slower braking on a slippery road still ends within 40 s
    sv_accel_bound = abs(BRAKE_ACCEL)  # [m/s^2] |SV acceleration| on the driest road (mu = 1)

    def step(self, states, actions, noise):
        return self._step_via_into(states, actions, noise)

    def step_into(self, states, actions, noise, out):
        self._require_sv_policy()
        v0, v1, p10, headway, friction = (states[:, i] for i in range(5))
        a0 = self._policy(v0, v1, p10, headway, friction)
        u = actions[:, 0]
        a1 = np.where(u < 0.0, u * friction, u)  # only braking is limited by the road
        if noise is not None:
            a0 = disturb(a0, noise[:, 0], self.disturbance)
            a1 = disturb(a1, noise[:, 1], self.disturbance)
        _, x0 = advance(v0, a0, self.dt, out=out[0])
        _, x1 = advance(v1, a1, self.dt, out=out[1])
        np.subtract(x1, x0, out=out[2])
        out[2] += p10
        self.hold_parameters(states, out)

    def reference_safe(self, points):
        return None if self.external_sv else safe_until_standstill(self, points)

    def _accel_max(self) -> float:
        # mu <= 1 only shrinks the braking limits: lead-follow's bound holds
        return max(self.sv_accel_bound, 5.0, 3.0) + self.disturbance

    def step_bound(self) -> float:
        a_max = self._accel_max()
        return max(a_max * self.dt, float(self.upper[0]) * self.dt + 0.5 * a_max * self.dt**2)

    def step_bounds(self) -> np.ndarray:
        a_max = self._accel_max()
        travel = float(self.upper[0]) * self.dt + 0.5 * a_max * self.dt**2
        return np.array([a_max * self.dt, a_max * self.dt, travel, 0.0, 0.0])  # T, mu: parameters

    def views(self):
        nominal = (("T", 1.5), ("mu", 1.0))
        return [View("dry_road", "dry road, T = 1.5 s", ("v0", "v1", "p10"), fixed=nominal),
                View("wet_road", "mu = 0.4, T = 1.5 s", ("v0", "v1", "p10"), fixed=(("T", 1.5), ("mu", 0.4))),
                View("parameters", "gap needed over the parameters", ("T", "mu", "p10"),
                     fixed=(("v0", 15.0), ("v1", 5.0)))]

    def slices(self):
        return [Slices("v0", "p10", "mu"), Slices("v0", "p10", "T")]
