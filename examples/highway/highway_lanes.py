"""A lateral case: the SV may change lane (highway-env's IDM + MOBIL) to get away from a
braking lead, on a two-lane road. No vectorized back end has such a scenario; a per-run
simulator makes it one file.

The scenario (``TwoLaneFollow``) declares the state space; highway-env simulates it
(``HighwayMOBIL``). Quantify it:

    pip install -e '.[highway]'
    cd examples/highway
    scenario-farm quantify two_lane_highway.toml --out runs/two-lane

State ``(v0, v1, p10, y)``:
  v0   SV speed [m/s]                                  Sigma [0, 20]
  v1   lead speed [m/s]                                Sigma [0, 20]
  p10  longitudinal clearance [m]: the lead's rear      Sigma [0, 50]
       minus the SV's foremost point (its bumper gap when the SV is straight)
  y    the SV's lateral offset from the centre of the   Sigma [-1, 3.5]
       lead's lane (lane 0; lane 1 is at y = 4) [m]
Facets: p10 < 0 is a failure (the SV's front passed the lead's rear while within 3.5 m of
its lane: contact, or less than 3 cm lateral clearance at the steepest heading, counted
as contact: conservative). y > 3.5 truncates: the SV is beside the lead in lane 1 and can
no longer run into it (at any heading up to pi/4, its footprint clears the lead's). The
speed facets v > 20, p10 > 50 and y < -1 truncate as in lead-follow.
Action: the lead's acceleration u1 in [-5, 3] m/s^2 (Gamma* = {-5}), as in lead-follow.

What the state leaves out: the SV's heading and the lane it is heading for. A run starts
with the SV parallel to its lane and aiming for the lane it is in (MOBIL then decides
every step); a state visited in the middle of a lane change has the change's heading.
The set quantified is of start states with the SV parallel to its lane, and the farm's
screening treats a visited state as such a start (docs/custom_scenario.md says what
that means).
"""

import numpy as np
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle

from highway_idm import SpecIDM
from scenarios.base import Scenario, ScenarioError
from scenarios.per_run import RunSimulator

SV_X = 50.0  # [m] where each run places the SV's centre
LENGTH, WIDTH = Vehicle.LENGTH, Vehicle.WIDTH  # 5 m, 2 m
Y_CLEAR = 3.5  # [m] beyond this lateral offset the SV's footprint clears the lead's (heading <= pi/4)


class TwoLaneFollow(Scenario):
    """The state space of the lateral case (see the module docstring)."""

    name = "two-lane-follow"
    state_names = ("v0", "v1", "p10", "y")
    lower = np.array([0.0, 0.0, 0.0, -1.0])
    upper = np.array([20.0, 20.0, 50.0, Y_CLEAR])
    failure_sides = {"p10": False}
    action_names = ("u1",)
    action_lower = np.array([-5.0])
    action_upper = np.array([3.0])
    adversarial_actions = np.array([[-5.0]])
    dt = 0.1
    units = {"v0": "m/s", "v1": "m/s", "p10": "m", "y": "m"}
    action_words = {"u1": "the lead vehicle's acceleration"}
    action_units = {"u1": "m/s^2"}
    failure_words = "collide"

    def step(self, states, actions, noise):
        raise ScenarioError(f"scenario {self.name!r} has no vectorized model; it runs on its per-run simulator "
                            f"(scenario.backend = 'highway_lanes:HighwayMOBIL')")

    def step_bound(self):
        """sigma-bar: speeds change by at most 5 m/s^2 * dt; p10 and y by one step's travel
        at 20.5 m/s plus the change of the SV's foremost point as it turns (< 0.25 m)."""
        return 20.5 * self.dt + 0.25

    def views(self):
        from scenarios.base import View

        return [View("lane_0", "SV in the lead's lane (y = 0)", ("v0", "v1", "p10"), fixed=(("y", 0.0),))]


class MobilIDM(SpecIDM):
    """The lead-follow IDM (same parameters) with highway-env's MOBIL lane changes, which
    it considers every step (highway-env's default: once a second, on a timer the state
    would have to carry)."""

    LANE_CHANGE_DELAY = 0.05  # [s] < dt: MOBIL decides at every step


class HighwayMOBIL(RunSimulator):
    """Two lanes, the lead in lane 0, the SV behind it (IDM + MOBIL)."""

    sv_policy = "highway-env-idm-mobil"

    def __init__(self, scenario, options=None):
        super().__init__(scenario, options)
        if self.options:
            raise ValueError(f'scenario."highway_lanes:HighwayMOBIL": takes no options; got {sorted(self.options)}')
        self.dt = scenario.dt
        self.road = Road(RoadNetwork.straight_road_network(lanes=2, length=10_000.0, speed_limit=30.0))
        self.lane = self.road.network.get_lane(("0", "1", 0))

    def reset(self, state, key):
        v0, v1, p10, y = state
        self.road.np_random = key.generator()
        self.sv = MobilIDM(self.road, self.lane.position(SV_X, y), speed=v0, target_speed=30.0, timer=1e-3)
        self.lead = Vehicle(self.road, self.lane.position(SV_X + LENGTH + p10, 0.0), speed=v1)
        self.road.vehicles = [self.sv, self.lead]
        return self._read()

    def step(self, action):
        self.sv.act()
        self.lead.act({"acceleration": float(action[0]), "steering": 0.0})
        for vehicle in (self.sv, self.lead):
            vehicle.step(self.dt)
            if vehicle.speed < 0.0:  # a stopped vehicle stays stopped (highway-env would reverse it)
                vehicle.speed = 0.0
        return self._read()

    def _read(self):
        h = self.sv.heading
        front = self.sv.position[0] + LENGTH / 2 * abs(np.cos(h)) + WIDTH / 2 * abs(np.sin(h))
        rear_of_lead = self.lead.position[0] - LENGTH / 2
        return np.array([self.sv.speed, self.lead.speed, rear_of_lead - front, self.sv.position[1]])
