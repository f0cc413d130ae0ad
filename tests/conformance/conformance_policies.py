"""Feedback policies (states (B, n) -> actions (B, m)) for the action-policy conformance
test: simple, deterministic, and inside Gamma after the farm's clipping."""

import numpy as np


def lead_follow(states):
    return np.where(states[:, 2:3] < 20.0, -5.0, 1.0)  # brake when close


def fleet3(states):
    return np.column_stack([np.full(len(states), -1.0), np.full(len(states), -5.0)])


def toy(states):
    return -np.clip(states, -0.3, 0.3)
