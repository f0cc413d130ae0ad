"""Longitudinal vehicle kinematics over one step (shared/spec/scenarios.md).

Acceleration is held constant within the step and vehicles never reverse: a vehicle
that would reach negative speed stops inside the step.
"""

from __future__ import annotations

import numpy as np


def advance(speed: np.ndarray, accel: np.ndarray, dt: float,
            out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One step for a batch of vehicles: speed [m/s], accel [m/s^2] -> (new speed,
    distance travelled [m]). If ``v + a*dt >= 0``: ``v' = v + a*dt``, ``x = v*dt +
    a*dt^2/2`` (= (v + v') dt / 2); else the vehicle stops inside the step: ``v' = 0``,
    ``x = v^2/(2|a|)``. ``out`` receives the new speed (a row of the next state)."""
    new_speed = np.multiply(accel, dt, out=out)
    new_speed += speed
    distance = speed + new_speed
    distance *= 0.5 * dt
    stops = np.flatnonzero(new_speed < 0.0)  # one scan; the few stopped rows by index
    if len(stops):
        v, a = speed[stops], np.broadcast_to(accel, speed.shape)[stops]
        distance[stops] = v * v / (2.0 * np.abs(a))
        new_speed[stops] = 0.0
    return new_speed, distance


def disturb(accel: np.ndarray, noise: np.ndarray | None, bound: float) -> np.ndarray:
    """Add the bounded disturbance: an independent U[-w, w] draw per vehicle and step
    (noise holds U[0,1) draws of the same shape), after any policy clipping."""
    if noise is None or bound == 0.0:
        return accel
    return accel + bound * (2.0 * noise - 1.0)
