"""highway-env's IDM vehicle as the SV of lead-follow, through the per-run contract.

highway-env (PyPI ``highway-env``) simulates one scene at a time: Python objects for
the road and each vehicle, advanced by ``act()`` and ``step(dt)``. This file is all a
user writes to quantify its IDM vehicle as the subject vehicle (SV) of the shipped
``lead-follow`` scenario (state ``(v0, v1, p10)``, the lead's acceleration as the
action): place the scene at a start state, advance it one step under an action, read
the state back.

    pip install -e '.[highway]'
    cd examples/highway
    scenario-farm quantify lead_follow_highway.toml --out runs/highway-idm

docs/custom_scenario.md ("A simulator that runs one scene at a time") walks through it.
"""

import numpy as np
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.kinematics import Vehicle

from scenarios.per_run import RunSimulator

SV_X = 50.0  # [m] where each run places the SV's centre on a 10 km straight lane


class SpecIDM(IDMVehicle):
    """highway-env's IDMVehicle with the parameters of the numpy ``idm`` SV
    (shared/spec/scenarios.md), so that the two safe sets can be compared. What stays
    highway-env's own: the gap it sees is centre to centre (bumper gap + 5 m; the jam
    distance is set to match at standstill), and it integrates speed and position with
    explicit Euler steps."""

    COMFORT_ACC_MAX = 0.73  # a [m/s^2]
    COMFORT_ACC_MIN = -1.67  # -b [m/s^2]
    DISTANCE_WANTED = 2.0 + IDMVehicle.LENGTH  # s0 = 2 m bumper to bumper
    TIME_WANTED = 1.5  # T [s]
    DELTA = 4.0
    ACC_MAX = 4.67  # the spec's clip at -4.67 (IDM never asks for more than +a)


class HighwayIDM(RunSimulator):
    """lead-follow with highway-env's IDM vehicle as the SV.

    Both vehicles are highway-env's: the SV decides with its IDM, the lead is commanded
    with the action as its acceleration, and highway-env moves both.

    Options (``[scenario."highway_idm:HighwayIDM"]``):
      clamp_reverse  (default true) a vehicle that brakes to a stop stays at speed 0, as
                     the spec's vehicles do. highway-env lets a vehicle's speed go below 0
                     (it reverses, down to -40 m/s): the braking lead then leaves Sigma
                     through v1 < 0, which truncates the run (counted safe) while the SV
                     is still closing in, before the contact. false: highway-env as it
                     comes (docs/custom_scenario.md shows what that hides).
    """

    sv_policy = "highway-env-idm"

    def __init__(self, scenario, options=None):
        super().__init__(scenario, options)
        unknown = set(self.options) - {"clamp_reverse"}
        if unknown:
            raise ValueError(f'scenario."highway_idm:HighwayIDM": unknown option {sorted(unknown)[0]!r}; '
                             f'allowed: clamp_reverse')
        self.clamp_reverse = bool(self.options.get("clamp_reverse", True))
        self.dt = scenario.dt
        self.road = Road(RoadNetwork.straight_road_network(lanes=1, length=10_000.0, speed_limit=30.0))
        self.lane = self.road.network.get_lane(("0", "1", 0))

    def reset(self, state, key):
        v0, v1, p10 = state
        self.road.np_random = key.generator()  # highway-env's own randomness, keyed by the run
        self.sv = SpecIDM(self.road, self.lane.position(SV_X, 0.0), speed=v0, target_speed=30.0,
                          enable_lane_change=False)
        self.lead = Vehicle(self.road, self.lane.position(SV_X + Vehicle.LENGTH + p10, 0.0), speed=v1)
        self.road.vehicles = [self.sv, self.lead]
        return self._read()

    def step(self, action):
        self.sv.act()  # IDM decides from the scene at the start of the step
        self.lead.act({"acceleration": float(action[0]), "steering": 0.0})
        for vehicle in (self.sv, self.lead):
            vehicle.step(self.dt)
            if self.clamp_reverse and vehicle.speed < 0.0:
                vehicle.speed = 0.0
        return self._read()

    def _read(self):
        """(v0, v1, p10): the speeds and the bumper gap, from the vehicles' centres."""
        gap = self.lead.position[0] - self.sv.position[0] - Vehicle.LENGTH
        return np.array([self.sv.speed, self.lead.speed, gap])
