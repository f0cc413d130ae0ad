"""``lead-follow`` (3-D): the SV follows a lead vehicle whose acceleration is the
scenario action. State ``(v0, v1, p10)``: SV speed [m/s], lead speed [m/s], bumper gap
from SV front to lead rear [m]."""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario
from scenarios.kinematics import advance, disturb
from scenarios.policies import BRAKE_ACCEL, sv_policy as lookup_sv_policy


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
    units = {"v0": "m/s", "v1": "m/s", "p10": "m"}

    def __init__(self, sv_policy: str = "idm", failure_facets=None, disturbance: float = 0.0):
        super().__init__(failure_facets, disturbance)
        self.sv_policy_name = sv_policy
        self._policy = lookup_sv_policy(sv_policy)

    def step(self, states, actions, noise):
        return self._step_via_into(states, actions, noise)

    def step_into(self, states, actions, noise, out):
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

    def step_bound(self) -> float:
        a_max = max(abs(BRAKE_ACCEL), 5.0, 3.0) + self.disturbance
        v_max = float(self.upper[0])
        # speed change <= a_max*dt; gap change <= one vehicle's travel in a step
        return max(a_max * self.dt, v_max * self.dt + 0.5 * a_max * self.dt**2)
