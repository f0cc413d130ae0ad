"""A user scenario that raises for some states (the error path of the farm)."""

import numpy as np

from scenarios.base import Scenario


class Raising(Scenario):
    name = "raising"
    state_names = ("a", "b")
    lower = np.array([0.0, 0.0])
    upper = np.array([1.0, 1.0])
    failure_sides = {"a": False}
    action_names = ("u",)
    action_lower = np.array([0.0])
    action_upper = np.array([0.0])
    adversarial_actions = np.array([[0.0]])

    def __init__(self, sv_policy="none", failure_facets=None, disturbance=0.0):
        super().__init__(failure_facets, disturbance)

    def step(self, states, actions, noise):
        if (states[:, 0] > 0.5).any():
            raise ValueError("boom")
        return states
