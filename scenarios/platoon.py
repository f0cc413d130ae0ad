"""``platoon`` (2k - 1 dimensions): k cars of 5 m on one lane, m leads ahead of the SV
and r followers behind it (m, r >= 1, m + 1 + r = k). The front-most lead and the
rear-most follower are commanded by the scenario actions; every car between them other
than the SV drives the traffic IDM (scenarios/policies.py ``TRAFFIC_IDM``) on the car
directly ahead. The SV reacts to lead 1 only. k = 3 is fleet3's dynamics.

Cars are numbered 0 (SV), 1 .. m (leads, 1 nearest), m+1 .. k-1 (followers, m+1
nearest). State: the speeds v0 .. v{k-1} [m/s], then one gap per car i >= 1 to its
*partner*, front to front [m]: a lead's partner is the car behind it (``p10, p21, ...``,
positive), a follower's the car ahead of it (``p(m+1)0, p(m+2)(m+1), ...``, negative).
Bumper gaps are ``p - 5`` ahead and ``-p - 5`` behind.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario, Slices, View
from scenarios.errors import ConfigError
from scenarios.kinematics import advance, disturb
from scenarios.policies import BRAKE_ACCEL, SV_POLICIES, TRAFFIC_IDM, traffic_idm
from scenarios.worst_case_rollout import safe_until_standstill

VEHICLE_LENGTH = 5.0  # [m]
MIN_VEHICLES, MAX_VEHICLES = 3, 8
SPEED_MAX = 6.0  # [m/s]
GAP_MIN, GAP_MAX = 5.0, 25.0  # [m] |front-to-front gap| of neighbours
LEAD_ACTION = (-5.0, 3.0)  # [m/s^2] the front-most lead's acceleration
REAR_ACTION = (-7.0, -3.0)  # [m/s^2] the rear-most follower's: it never accelerates


def _car(i: int, leads: int) -> str:
    """Car i in words: the SV, lead 1 .. m (1 nearest), follower 1 .. r (1 nearest)."""
    return "the SV" if i == 0 else (f"lead {i}" if i <= leads else f"follower {i - leads}")


def _layout(vehicles: int, followers: int) -> dict:
    """The declarations that depend on k and r, as class attributes would hold them."""
    leads = vehicles - 1 - followers
    partner = [0] + [i - 1 for i in range(1, leads + 1)] + [0] + list(range(leads + 1, vehicles - 1))
    speeds = tuple(f"v{i}" for i in range(vehicles))
    gaps = tuple(f"p{i}{partner[i]}" for i in range(1, vehicles))
    rear = gaps[leads]  # p(m+1)0: follower 1 to the SV
    is_lead = np.arange(1, vehicles) <= leads
    roles = ("sv",) + tuple(f"lead{i}" for i in range(1, leads + 1)) + tuple(f"follower{j}"
                                                                            for j in range(1, followers + 1))
    return {
        "leads": leads, "partner": tuple(partner), "rear_facet": rear,
        # cars in index order; the action columns command lead m and follower r, the cars
        # between them and the SV drive the traffic IDM
        "vehicle_roles": roles, "traffic_roles": roles[1:leads] + roles[leads + 1 : vehicles - 1],
        "state_names": speeds + gaps,
        "lower": np.concatenate([np.zeros(vehicles), np.where(is_lead, GAP_MIN, -GAP_MAX)]),
        "upper": np.concatenate([np.full(vehicles, SPEED_MAX), np.where(is_lead, GAP_MAX, -GAP_MIN)]),
        "failure_sides": {"p10": False, rear: True},  # p10 < 5 (lead 1), p(m+1)0 > -5 (follower 1)
        "noise_width": vehicles,  # one disturbance draw per car and step
        "units": {**{v: "m/s" for v in speeds}, **{p: "m" for p in gaps}},
        "state_words": {**{v: f"{_car(i, leads)}'s speed" for i, v in enumerate(speeds)},
                        **{p: f"{_car(i + 1, leads)}'s minus {_car(partner[i + 1], leads)}'s position"
                           for i, p in enumerate(gaps)}},
        "sides": {"lead": ("p10",), "rear": (rear,)},
    }


class Platoon(Scenario):
    name = "platoon"
    config_options = ("vehicles", "followers")
    action_names = ("uL", "uF")
    action_lower = np.array([LEAD_ACTION[0], REAR_ACTION[0]])
    action_upper = np.array([LEAD_ACTION[1], REAR_ACTION[1]])
    adversarial_actions = np.array([[-5.0, -3.0]])  # the front lead brakes hardest, the rear follower least
    action_words = {"uL": "the front-most lead vehicle's acceleration",
                    "uF": "the rear-most following vehicle's acceleration"}
    action_units = {"uL": "m/s^2", "uF": "m/s^2"}
    failure_words = "collide"
    margin_through_contact = True  # gaps may go negative: the kinematics and the IDM (s <= 0) stay defined
    sv_policies = SV_POLICIES
    adversary_settle_steps = 400  # as fleet3: adversarial rollouts from Sigma end within ~200 steps (k <= 8)
    sv_accel_bound = abs(BRAKE_ACCEL)  # [m/s^2] |SV acceleration| (brake, idm)
    vehicle_length = VEHICLE_LENGTH
    # Sigma, the facets, the state names, units, sides and the cars on the lane
    # (``vehicle_roles``, ``traffic_roles``) depend on k and r: the constructor sets them
    # (``_layout``).

    def __init__(self, sv_policy: str | None = None, failure_facets: tuple[str, ...] | None = None,
                 disturbance: float = 0.0, vehicles: int = 4, followers: int = 1):
        """``vehicles`` k in [3, 8], ``followers`` r in [1, k - 2] (at least one lead)."""
        if isinstance(vehicles, bool) or not isinstance(vehicles, int) or not MIN_VEHICLES <= vehicles <= MAX_VEHICLES:
            raise ConfigError(f"scenario.vehicles: {vehicles!r} is out of range; allowed [{MIN_VEHICLES}, "
                              f"{MAX_VEHICLES}]")
        if isinstance(followers, bool) or not isinstance(followers, int) or not 1 <= followers <= vehicles - 2:
            raise ConfigError(f"scenario.followers: {followers!r} is out of range; allowed [1, {vehicles - 2}] "
                              f"with {vehicles} vehicles (at least one lead)")
        self.vehicles, self.followers = vehicles, followers
        for attr, value in _layout(vehicles, followers).items():
            setattr(self, attr, value)
        super().__init__(sv_policy, failure_facets, disturbance)

    def step(self, states, actions, noise):
        return self._step_via_into(states, actions, noise)

    def step_into(self, states, actions, noise, out):
        self._require_sv_policy()
        k, m, partner = self.vehicles, self.leads, self.partner
        speed = [states[:, i] for i in range(k)]
        gap = [None] + [states[:, k - 1 + i] for i in range(1, k)]  # gap[i]: car i to its partner
        # every acceleration from the state at the start of the step (simultaneous update)
        accel = [self._policy(speed[0], speed[1], gap[1] - VEHICLE_LENGTH)]  # the SV sees lead 1 only
        for i in range(1, k):
            if i == m:
                accel.append(actions[:, 0])
            elif i == k - 1:
                accel.append(actions[:, 1])
            elif i < m:  # a lead between the SV and the front lead: its car ahead is i + 1
                accel.append(traffic_idm(speed[i], speed[i + 1], gap[i + 1] - VEHICLE_LENGTH))
            else:  # a follower between the SV and the rear follower: its car ahead is its partner
                accel.append(traffic_idm(speed[i], speed[partner[i]], -gap[i] - VEHICLE_LENGTH))
        if noise is not None:
            accel = [disturb(a, noise[:, i], self.disturbance) for i, a in enumerate(accel)]
        travel = [advance(speed[i], accel[i], self.dt, out=out[i])[1] for i in range(k)]
        for i in range(1, k):  # gaps change by the difference of the distances travelled
            row = out[k - 1 + i]
            np.subtract(travel[i], travel[partner[i]], out=row)
            row += gap[i]

    def reference_safe(self, points):
        return None if self.external_sv else safe_until_standstill(self, points)

    # -- geometry ----------------------------------------------------------------------------
    def to_vehicles(self, states):
        """(B, n) -> front positions relative to the SV's front [m], speeds [m/s] (B, k),
        cars in index order (SV, leads, followers)."""
        k = self.vehicles
        fronts = np.zeros((len(states), k))
        for i in range(1, k):  # a partner has a smaller index: its position is known
            fronts[:, i] = fronts[:, self.partner[i]] + states[:, k - 1 + i]
        return fronts, states[:, :k].copy()

    def from_vehicles(self, fronts, speeds):
        gaps = [fronts[:, i] - fronts[:, self.partner[i]] for i in range(1, self.vehicles)]
        return np.column_stack([speeds[:, : self.vehicles], *gaps])

    def views(self):
        # as fleet3's: the lead side (the gap to lead 1 large enough) and the rear side
        # (follower 1 far enough behind: its negative gap small enough)
        rear_speed = f"v{self.leads + 1}"
        return [View("lead_side", "lead side", ("v0", "v1", "p10"), safe_above=True),
                View("rear_side", "rear side", ("v0", rear_speed, self.rear_facet), safe_above=False)]

    def slices(self):
        return [Slices("v0", "p10", "v1"), Slices("v0", self.rear_facet, f"v{self.leads + 1}")]

    def _accel_max(self) -> float:
        """[m/s^2] the largest |acceleration| of any car: SV, actions, traffic IDM, plus w."""
        commanded = max(abs(b) for b in (*LEAD_ACTION, *REAR_ACTION))
        traffic = max(abs(TRAFFIC_IDM.min_accel), abs(TRAFFIC_IDM.max_accel))
        return max(self.sv_accel_bound, commanded, traffic) + self.disturbance

    def step_bound(self) -> float:
        a_max = self._accel_max()
        # speed change <= a_max dt; a gap changes by the difference of two travels in
        # [0, v_max dt + a_max dt^2 / 2] (cars never reverse), so by at most one of them
        return max(a_max * self.dt, SPEED_MAX * self.dt + 0.5 * a_max * self.dt**2)

    def step_bounds(self) -> np.ndarray:
        a_max = self._accel_max()
        travel = SPEED_MAX * self.dt + 0.5 * a_max * self.dt**2
        return np.concatenate([np.full(self.vehicles, a_max * self.dt), np.full(self.vehicles - 1, travel)])
