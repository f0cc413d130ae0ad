"""``toy`` (2-D): two disjoint invariant sets known in closed form.

State ``(x, y)`` in Sigma = [0, 10]^2; failure facet ``y < 0``. Inside a well
``W1 = [1, 4]`` or ``W2 = [6, 9]`` (in x), both coordinates contract towards the well
centre and the action pushes them: ``x' = c + 0.8 (x - c) + ux``, ``|ux| <= 0.3``, and
``y' = 5 + 0.8 (y - 5) + uy``, ``|uy| <= 1``; since ``0.8*1.5 + 0.3 = 1.5`` and
``0.8*5 + 1 = 5``, each ``Wi x [0, 10]`` is robustly invariant, and its trajectories
fill it. Outside the wells x is frozen and y falls by 3 per step: failure within 4 steps.
So the maximal safe set is exactly ``(W1 u W2) x [0, 10]``: the union of two disjoint
invariant sets, the situation of the paper's Theorems 8 and 9.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario

WELLS = ((1.0, 4.0), (6.0, 9.0))
CONTRACTION = 0.8
FALL = 3.0  # [units per step] outside the wells


class Toy(Scenario):
    name = "toy"
    state_names = ("x", "y")
    lower = np.array([0.0, 0.0])
    upper = np.array([10.0, 10.0])
    failure_sides = {"y": False}
    action_names = ("ux", "uy")
    action_lower = np.array([-0.3, -1.0])
    action_upper = np.array([0.3, 1.0])
    adversarial_actions = np.array([[-0.3, -1.0], [-0.3, 1.0], [0.3, -1.0], [0.3, 1.0]])

    @staticmethod
    def safe(states: np.ndarray) -> np.ndarray:
        """Closed-form membership of the maximal safe set, (B, 2) -> (B,) bool."""
        x = states[:, 0]
        in_wells = np.zeros(len(states), dtype=bool)
        for lo, hi in WELLS:
            in_wells |= (x >= lo) & (x <= hi)
        inside = (states >= 0.0).all(axis=1) & (states <= 10.0).all(axis=1)
        return in_wells & inside

    def reference_safe(self, points):
        return self.safe(points)

    def step(self, states, actions, noise):
        x, y = states[:, 0], states[:, 1]
        centre = np.where(x < 5.0, 2.5, 7.5)
        in_well = np.abs(x - centre) <= 1.5
        x_next = np.where(in_well, centre + CONTRACTION * (x - centre) + actions[:, 0], x)
        y_next = np.where(in_well, 5.0 + CONTRACTION * (y - 5.0) + actions[:, 1], y - FALL)
        return np.stack([x_next, y_next]).T

    def step_bound(self) -> float:
        return max(FALL, 2.0)  # outside: y falls by 3; inside: |dy| <= 0.2*5 + 1
