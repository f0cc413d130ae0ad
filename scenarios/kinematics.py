"""Longitudinal vehicle kinematics over one step (shared/spec/scenarios.md).

Acceleration is held constant within the step and vehicles never reverse: a vehicle
that would reach negative speed stops inside the step.
"""

from __future__ import annotations

import numpy as np


def advance(speed: np.ndarray, accel: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One step for a batch of vehicles: speed [m/s], accel [m/s^2] -> (new speed,
    distance travelled [m]). If ``v + a*dt >= 0``: ``v' = v + a*dt``, ``x = v*dt +
    a*dt^2/2``; else the vehicle stops inside the step: ``v' = 0``, ``x = v^2/(2|a|)``."""
    new_speed = speed + accel * dt
    distance = speed * dt + 0.5 * accel * dt * dt
    stops = new_speed < 0.0
    if stops.any():
        v, a = speed[stops], accel[stops]
        distance[stops] = v * v / (2.0 * np.abs(a))
        new_speed[stops] = 0.0
    return new_speed, distance


def disturb(accel: np.ndarray, noise: np.ndarray | None, bound: float) -> np.ndarray:
    """Add the bounded disturbance: an independent U[-w, w] draw per vehicle and step
    (noise holds U[0,1) draws of the same shape), after any policy clipping."""
    if noise is None or bound == 0.0:
        return accel
    return accel + bound * (2.0 * noise - 1.0)
