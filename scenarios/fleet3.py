"""``fleet3`` (5-D): lead (1), SV (0) in the middle, follower (2), one lane, 5 m cars.
State ``(v0, v1, v2, p10, p20)``: speeds [m/s]; p10 = lead minus SV position, p20 =
follower minus SV position, front to front [m]. Bumper gaps: p10 - 5 and -p20 - 5."""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario, Slices, View
from scenarios.kinematics import advance, disturb
from scenarios.policies import BRAKE_ACCEL, SV_POLICIES
from scenarios.worst_case_rollout import safe_until_standstill

VEHICLE_LENGTH = 5.0  # [m]


class Fleet3(Scenario):
    name = "fleet3"
    state_names = ("v0", "v1", "v2", "p10", "p20")
    lower = np.array([0.0, 0.0, 0.0, 5.0, -25.0])
    upper = np.array([6.0, 6.0, 6.0, 25.0, -5.0])
    failure_sides = {"p10": False, "p20": True}  # p10 < 5 (lead contact), p20 > -5 (follower)
    action_names = ("u1", "u2")
    action_lower = np.array([-5.0, -7.0])
    action_upper = np.array([3.0, -3.0])  # the follower never accelerates
    adversarial_actions = np.array([[-5.0, -3.0]])  # lead brakes hardest, follower least
    noise_width = 3
    units = {"v0": "m/s", "v1": "m/s", "v2": "m/s", "p10": "m", "p20": "m"}
    state_words = {"v0": "the SV's speed", "v1": "the lead's speed", "v2": "the follower's speed",
                   "p10": "lead minus SV position", "p20": "follower minus SV position (front to front)"}
    action_words = {"u1": "the lead vehicle's acceleration", "u2": "the following vehicle's acceleration"}
    action_units = {"u1": "m/s^2", "u2": "m/s^2"}
    failure_words = "collide"
    margin_through_contact = True  # gaps may go negative: the kinematics and the IDM (s <= 0) stay defined
    sides = {"lead": ("p10",), "rear": ("p20",)}  # the paper's Fig. 4 / Table 2 measures
    sv_policies = SV_POLICIES
    adversary_settle_steps = 400
    vehicle_roles = ("sv", "lead", "follower")  # as vehicles on one lane (see LeadFollow)
    sv_accel_bound = abs(BRAKE_ACCEL)  # [m/s^2] |SV acceleration| (brake, idm); a simulator SV may widen it
    vehicle_length = VEHICLE_LENGTH

    def to_vehicles(self, states):
        fronts = np.zeros((len(states), 3))
        fronts[:, 1] = states[:, 3]  # p10, p20 are front-to-front offsets from the SV
        fronts[:, 2] = states[:, 4]
        return fronts, states[:, :3].copy()

    def from_vehicles(self, fronts, speeds):
        return np.column_stack([speeds[:, 0], speeds[:, 1], speeds[:, 2], fronts[:, 1] - fronts[:, 0],
                                fronts[:, 2] - fronts[:, 0]])

    def step(self, states, actions, noise):
        return self._step_via_into(states, actions, noise)

    def step_into(self, states, actions, noise, out):
        self._require_sv_policy()
        v0, v1, v2 = states[:, 0], states[:, 1], states[:, 2]
        p10, p20 = states[:, 3], states[:, 4]
        a0 = self._policy(v0, v1, p10 - VEHICLE_LENGTH)  # the SV sees the lead only
        a1, a2 = actions[:, 0], actions[:, 1]
        if noise is not None:
            a0 = disturb(a0, noise[:, 0], self.disturbance)
            a1 = disturb(a1, noise[:, 1], self.disturbance)
            a2 = disturb(a2, noise[:, 2], self.disturbance)
        _, x0 = advance(v0, a0, self.dt, out=out[0])
        _, x1 = advance(v1, a1, self.dt, out=out[1])
        _, x2 = advance(v2, a2, self.dt, out=out[2])
        np.subtract(x1, x0, out=out[3])
        out[3] += p10
        np.subtract(x2, x0, out=out[4])
        out[4] += p20

    def reference_safe(self, points):
        return None if self.external_sv else safe_until_standstill(self, points)

    def views(self):
        # the paper's Fig. 4: the lead side (gap to the lead must be large enough) and the
        # rear side (the follower must stay far enough behind: p20 small enough)
        return [View("lead_side", "lead side", ("v0", "v1", "p10"), safe_above=True),
                View("rear_side", "rear side", ("v0", "v2", "p20"), safe_above=False)]

    def slices(self):
        return [Slices("v0", "p10", "v1"), Slices("v0", "p20", "v2")]

    def step_bound(self) -> float:
        a_max = max(self.sv_accel_bound, 7.0) + self.disturbance
        v_max = float(self.upper[0])
        return max(a_max * self.dt, v_max * self.dt + 0.5 * a_max * self.dt**2)

    def step_bounds(self) -> np.ndarray:
        a_max = max(self.sv_accel_bound, 7.0) + self.disturbance
        speed = a_max * self.dt
        return np.array([speed, speed, speed, self.step_bound(), self.step_bound()])  # v0, v1, v2; p10, p20
