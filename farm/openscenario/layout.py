"""A scenario's states as vehicles on the exported road.

A scenario that lays its state out as vehicles on one lane (``vehicle_roles``,
``to_vehicles``: lead-follow, fleet3, platoon; the SUMO back end uses the same) gives each
vehicle's front bumper relative to the SV's front and its speed. On the road, the SV's
front starts at ``sv_front`` (the same for every start state of the scenario, so the
rearmost vehicle Sigma allows still starts ``BACK_MARGIN`` from the road's start), and
an OpenSCENARIO position is a vehicle's reference point: its rear axle,
``REF_TO_FRONT`` behind the front bumper (the bounding box says so to every tool).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from scenarios.errors import ConfigError

BACK_MARGIN = 10.0  # [m] road behind the rearmost vehicle's rear bumper
FRONT_MARGIN = 100.0  # [m] road left after the fastest travel a run could make
SPEED_MARGIN = 10.0  # [m/s] an SV under test may drive faster than Sigma's speeds
REAR_OVERHANG = 1.0  # [m] rear bumper to rear axle (the reference point)
FRONT_OVERHANG = 1.0  # [m] front axle to front bumper
WIDTH, HEIGHT = 1.8, 1.5  # [m]
PARAMETER_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")  # OpenSCENARIO's parameter names


class NotALaneScenario(ConfigError):
    """The scenario does not lay its state out as vehicles on one lane (the request does
    not fit the user's scenario: exit 2)."""


@dataclass(frozen=True)
class Layout:
    scenario: object
    roles: tuple[str, ...]  # "sv" first, then one commanded vehicle per action column
    length: float  # [m] each vehicle's
    sv_front: float  # [m] s of the SV's front bumper at the start
    dt: float

    @property
    def ref_to_front(self) -> float:
        return self.length - REAR_OVERHANG

    def place(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, n) states -> reference-point positions s [m] (T, R) at the start of the
        road, and speeds [m/s] (T, R)."""
        fronts, speeds = self.scenario.to_vehicles(np.atleast_2d(states))
        return self.sv_front + fronts - self.ref_to_front, speeds

    def affine(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``place`` as s = A sigma + a, v = B sigma + b ((R, n), (R,) each), for
        positions written as expressions of the state parameters; ``NotALaneScenario``
        if ``to_vehicles`` is not affine."""
        sc = self.scenario
        mid = (sc.lower + sc.upper) / 2
        s0, v0 = (x[0] for x in self.place(mid[None]))
        unit = np.eye(sc.n)
        s1, v1 = self.place(mid + unit)
        # rounded: unit differences of positions in metres are exact to far below a nanometre
        A, B = np.round((s1 - s0).T, 9), np.round((v1 - v0).T, 9)
        a, b = np.round(s0 - A @ mid, 9), np.round(v0 - B @ mid, 9)
        probe = np.random.default_rng(0).uniform(sc.lower, sc.upper, (16, sc.n))
        s, v = self.place(probe)
        if not (np.allclose(s, probe @ A.T + a, atol=1e-9) and np.allclose(v, probe @ B.T + b, atol=1e-9)):
            raise NotALaneScenario(f"scenario {sc.name!r}: its to_vehicles is not affine in the state; positions "
                                   f"cannot be written as OpenSCENARIO expressions of the state parameters")
        return A, a, B, b

    def road_length(self, horizon_states: int) -> float:
        """Long enough for any start state in Sigma and the fastest travel in the horizon."""
        sc = self.scenario
        (_, s_max), (_, v_max) = (affine_range(lambda x, k=k: self.place(x)[k], sc.lower, sc.upper) for k in (0, 1))
        travel = (max(float(v_max.max()), 0.0) + SPEED_MARGIN) * self.dt * max(horizon_states - 1, 1)
        return float(np.ceil((float(s_max.max()) + self.length + travel + FRONT_MARGIN) / 10.0) * 10.0)


def affine_range(f, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest value of each column of ``f`` ((T, n) -> (T, R), affine in
    the state, as ``Layout.affine`` checks before anything is written) over the box
    [lower, upper]: from n + 1 evaluations, not the box's 2^n corners."""
    mid, half = (lower + upper) / 2, (upper - lower) / 2
    f0 = f(mid[None])[0]
    slopes = f(mid + np.eye(len(mid))) - f0  # (n, R): column j's change per unit of axis i
    reach = np.abs(slopes).T @ half
    return f0 - reach, f0 + reach


def layout_of(scenario) -> Layout:
    for attr in ("vehicle_roles", "to_vehicles", "vehicle_length"):
        if not hasattr(scenario, attr):
            raise NotALaneScenario(f"export --xosc: scenario {scenario.name!r} does not lay its state out as "
                                   f"vehicles on one lane (no {attr}); OpenSCENARIO export supports lane scenarios "
                                   f"such as lead-follow, fleet3 and platoon")
    bad = [name for name in scenario.state_names if not PARAMETER_NAME.match(name)]
    if bad:
        raise NotALaneScenario(f"export --xosc: state variable {bad[0]!r} is not an OpenSCENARIO parameter name "
                               f"([A-Za-z_][A-Za-z0-9_]*)")
    length = float(scenario.vehicle_length)
    front_min, _ = affine_range(lambda x: scenario.to_vehicles(x)[0], scenario.lower, scenario.upper)
    sv_front = BACK_MARGIN + length - float(front_min.min())  # the rearmost rear bumper at BACK_MARGIN
    return Layout(scenario, tuple(scenario.vehicle_roles), length, sv_front, float(scenario.dt))
