"""Your own scenario in one file: an automated vehicle approaching a stopped obstacle.

The controller under test brakes to stop STOP_MARGIN metres short of the obstacle; the
environment (the adversary) picks the road grip, i.e. which share of the commanded
braking the tyres deliver. Is there a set of (speed, distance) states from which the
controller never hits the obstacle, whatever the grip? Quantify it:

    cd examples/custom
    scenario-farm quantify approach.toml --out runs/approach

docs/custom_scenario.md walks through every line.
"""

import numpy as np

from scenarios.base import Scenario

STOP_MARGIN = 2.0  # [m] the controller aims to stop this far short
MAX_BRAKE = 8.0  # [m/s^2] the most it commands
CRUISE_SPEED, CRUISE_ACCEL = 15.0, 1.0  # [m/s], [m/s^2] below cruise speed it speeds up,
CRUISE_CLEARANCE = 20.0  # [m] ... unless the obstacle is nearer than this
V_MAX = 20.0  # [m/s] Sigma's speed bound


class Approach(Scenario):
    """State (v, d): ego speed and distance to the obstacle. Action: road grip in
    [0.5, 1] (the share of the commanded braking delivered). Failure: d < 0."""

    name = "approach"
    state_names = ("v", "d")
    lower = np.array([0.0, 0.0])
    upper = np.array([V_MAX, 100.0])
    failure_sides = {"d": False}  # failure when d falls below its lower bound (contact)
    action_names = ("grip",)
    action_lower = np.array([0.5])
    action_upper = np.array([1.0])
    adversarial_actions = np.array([[0.5]])  # Gamma*: the worst grip, every step
    dt = 0.1
    units = {"v": "m/s", "d": "m"}
    action_words = {"grip": "the road grip"}
    failure_words = "hit the obstacle"

    def step(self, states, actions, noise):
        """(B, 2) states, (B, 1) actions -> (B, 2) next states, vectorized over the batch."""
        v, d = states[:, 0], states[:, 1]
        need = v * v / (2 * np.maximum(d - STOP_MARGIN, 1e-3))  # deceleration that stops at the margin
        # twice what is needed (half grip still stops), capped: too fast and too close fails
        brake = np.minimum(np.where(need > 0.5, 2.2 * need, 0.0), MAX_BRAKE)
        cruise = CRUISE_ACCEL * ((v < CRUISE_SPEED) & (d > CRUISE_CLEARANCE))
        accel = np.where(brake > 0, -brake * actions[:, 0], cruise)
        v_next = np.maximum(v + accel * self.dt, 0.0)
        d_next = d - 0.5 * (v + v_next) * self.dt
        return np.column_stack([v_next, d_next])

    def step_bound(self):
        """sigma-bar (Assumption 1): no step changes v by more than MAX_BRAKE*dt, or d by
        more than one step's travel at the top speed."""
        return max(MAX_BRAKE * self.dt, (V_MAX + CRUISE_ACCEL * self.dt / 2) * self.dt)
