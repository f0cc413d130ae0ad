"""``lead-follow`` and ``fleet3`` with a SUMO vehicle as the SV.

Subclasses of the numpy scenarios, so the state names, the box Sigma, the facets, the
action space, Gamma* and ``classify`` are the same objects; only the dynamics differ.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario
from scenarios.fleet3 import Fleet3
from scenarios.lead_follow import LeadFollow
from scenarios.sumo.config import SumoConfig
from scenarios.sumo.network import VEHICLE_LENGTH
from scenarios.sumo.rollout import SumoRollout

# SUMO's passenger-car defaults [m/s^2], for attributes the config leaves unset.
_SUMO_DEFAULT_ACCEL_BOUND = 9.0  # emergencyDecel (accel 2.6, decel 4.5 are smaller)


class _SumoScenario(SumoRollout):
    sv_policy_name = "sumo"

    def _init_sumo(self, config: SumoConfig, failure_facets) -> None:
        Scenario.__init__(self, failure_facets, 0.0)  # the numpy __init__ would look up a numpy SV policy
        self.sumo_config = config
        self._policy = None

    def step_bound(self) -> float:
        """The numpy bound, widened if the SV may brake or accelerate harder than the
        numpy SVs (SUMO never brakes harder than max(decel, emergencyDecel))."""
        params = self.sumo_config.params
        sv = max([_SUMO_DEFAULT_ACCEL_BOUND] + [float(params[k]) for k in ("accel", "decel", "emergencyDecel")
                                                if k in params])
        return max(super().step_bound(), sv * self.dt)

    def describe(self) -> dict:
        out = super().describe()
        out["backend"] = "sumo"
        out["sumo"] = {"car_follow_model": self.sumo_config.car_follow_model, "params": dict(self.sumo_config.params),
                      "allow_nondeterministic": self.sumo_config.allow_nondeterministic}
        return out


class SumoLeadFollow(_SumoScenario, LeadFollow):
    roles = ("sv", "lead")

    def __init__(self, config: SumoConfig, failure_facets=None):
        self._init_sumo(config, failure_facets)

    def _layout(self, states):
        # p10 is the bumper gap: lead front = SV front + p10 + lead length.
        fronts = np.zeros((len(states), 2))
        fronts[:, 1] = states[:, 2] + VEHICLE_LENGTH
        return fronts, states[:, :2].copy()

    def _state(self, x, v):
        return np.column_stack([v[:, 0], v[:, 1], x[:, 1] - VEHICLE_LENGTH - x[:, 0]])


class SumoFleet3(_SumoScenario, Fleet3):
    roles = ("sv", "lead", "follower")

    def __init__(self, config: SumoConfig, failure_facets=None):
        self._init_sumo(config, failure_facets)

    def _layout(self, states):
        # p10, p20 are front-to-front offsets from the SV (5 m cars).
        fronts = np.zeros((len(states), 3))
        fronts[:, 1] = states[:, 3]
        fronts[:, 2] = states[:, 4]
        return fronts, states[:, :3].copy()

    def _state(self, x, v):
        return np.column_stack([v[:, 0], v[:, 1], v[:, 2], x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]])
