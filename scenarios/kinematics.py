"""Longitudinal vehicle kinematics over one step (shared/spec/scenarios.md).

Acceleration is held constant within the step and vehicles never reverse: a vehicle
that would reach negative speed stops inside the step.
"""

from __future__ import annotations

import numpy as np
from numpy._core.umath import clip as _clip  # the ufunc: np.clip's Python wrapper costs ~3 us a call


def advance(speed: np.ndarray, accel: np.ndarray, dt: float,
            out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One step for a batch of vehicles: speed [m/s], accel [m/s^2] -> (new speed,
    distance travelled [m]). If ``v + a*dt >= 0``: ``v' = v + a*dt``, ``x = v*dt +
    a*dt^2/2`` (= (v + v') dt / 2); else the vehicle stops inside the step: ``v' = 0``,
    ``x = v^2/(2|a|)``. ``out`` receives the new speed (a row of the next state).

    Branch-free, so that a row's result never depends on its batch-mates: with
    ``v' = max(v + a*dt, 0)``, ``x = min((v + v') dt/2, v^2 / (2 max(-a, 0)))``. The
    second term is the distance to standstill, which is the smaller exactly when the
    vehicle stops inside the step (the braking parabola peaks before ``dt``) and is
    +inf or NaN (ignored by ``fmin``) for a vehicle that does not brake. (Only a braking
    acceleration below ~1e-150 m/s^2 with a speed below ~1e-154 m/s, where v^2
    underflows, would pick the wrong term; accelerations here are differences of O(1)
    numbers, never that small unless exactly 0.)"""
    new_speed = np.multiply(accel, dt, out=out)
    new_speed += speed
    # clip with both bounds: numpy's maximum against a scalar is slower on large batches
    _clip(new_speed, 0.0, np.inf, out=new_speed)
    distance = speed + new_speed
    distance *= 0.5 * dt
    to_standstill = speed * speed
    twice_decel = _clip(accel, -np.inf, 0.0)
    np.abs(twice_decel, out=twice_decel)  # max(-a, 0) as +0.0, never -0.0 (x/-0 = -inf)
    twice_decel *= 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        to_standstill /= twice_decel
    np.fmin(distance, to_standstill, out=distance)
    return new_speed, distance


def disturb(accel: np.ndarray, noise: np.ndarray | None, bound: float) -> np.ndarray:
    """Add the bounded disturbance: an independent U[-w, w] draw per vehicle and step
    (noise holds U[0,1) draws of the same shape), after any policy clipping."""
    if noise is None or bound == 0.0:
        return accel
    return accel + bound * (2.0 * noise - 1.0)
