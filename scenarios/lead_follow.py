"""``lead-follow`` (3-D): the SV follows a lead vehicle whose acceleration is the
scenario action. State ``(v0, v1, p10)``: SV speed [m/s], lead speed [m/s], bumper gap
from SV front to lead rear [m]."""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario
from scenarios.kinematics import advance, disturb
from scenarios.policies import BRAKE_ACCEL, SV_POLICIES
from scenarios.worst_case_rollout import safe_until_standstill


class LeadFollow(Scenario):
    name = "lead-follow"
    state_names = ("v0", "v1", "p10")
    lower = np.array([0.0, 0.0, 0.0])
    upper = np.array([20.0, 20.0, 70.0])
    failure_sides = {"p10": False}  # contact: p10 < 0
    action_names = ("u1",)
    action_lower = np.array([-5.0])
    action_upper = np.array([3.0])
    adversarial_actions = np.array([[-5.0]])  # maximal braking of the lead
    noise_width = 2
    sv_policies = SV_POLICIES
    units = {"v0": "m/s", "v1": "m/s", "p10": "m"}
    state_words = {"v0": "the SV's speed", "v1": "the lead's speed", "p10": "the gap from the SV's front to the lead's rear"}
    action_words = {"u1": "the lead vehicle's acceleration"}
    action_units = {"u1": "m/s^2"}
    failure_words = "collide"
    margin_through_contact = True  # gaps may go negative: the kinematics and the IDM (s <= 0) stay defined
    adversary_settle_steps = 400  # the lead stops within 4 s, any sane SV within 40 s
    # As vehicles on one lane (for simulator back ends): the SV, then one commanded
    # vehicle per action column; 5 m cars, positions are front bumpers.
    vehicle_roles = ("sv", "lead")
    sv_accel_bound = abs(BRAKE_ACCEL)  # [m/s^2] |SV acceleration| (brake, idm); a simulator SV may widen it
    vehicle_length = 5.0  # [m]

    def to_vehicles(self, states):
        """(B, n) -> front positions relative to the SV's front [m], speeds [m/s] (B, R)."""
        fronts = np.zeros((len(states), 2))
        fronts[:, 1] = states[:, 2] + self.vehicle_length  # p10 is the bumper gap
        return fronts, states[:, :2].copy()

    def from_vehicles(self, fronts, speeds):
        return np.column_stack([speeds[:, 0], speeds[:, 1], fronts[:, 1] - self.vehicle_length - fronts[:, 0]])

    def step(self, states, actions, noise):
        return self._step_via_into(states, actions, noise)

    def step_into(self, states, actions, noise, out):
        self._require_sv_policy()
        v0, v1, p10 = states[:, 0], states[:, 1], states[:, 2]
        a0 = self._policy(v0, v1, p10)
        a1 = actions[:, 0]
        if noise is not None:
            a0 = disturb(a0, noise[:, 0], self.disturbance)
            a1 = disturb(a1, noise[:, 1], self.disturbance)
        _, x0 = advance(v0, a0, self.dt, out=out[0])
        _, x1 = advance(v1, a1, self.dt, out=out[1])
        np.subtract(x1, x0, out=out[2])
        out[2] += p10

    def reference_safe(self, points):
        # Under the single adversarial action the system is deterministic: one rollout
        # per point until failure, truncation or standstill decides membership exactly.
        return None if self.external_sv else safe_until_standstill(self, points)

    def step_bound(self) -> float:
        a_max = max(self.sv_accel_bound, 5.0, 3.0) + self.disturbance
        v_max = float(self.upper[0])
        # speed change <= a_max*dt; gap change <= one vehicle's travel in a step
        return max(a_max * self.dt, v_max * self.dt + 0.5 * a_max * self.dt**2)

    def step_bounds(self) -> np.ndarray:
        a_max = max(self.sv_accel_bound, 5.0, 3.0) + self.disturbance
        speed = a_max * self.dt
        return np.array([speed, speed, self.step_bound()])  # v0, v1; p10: one vehicle's travel
