"""A scenario's states as vehicles on the exported road.

A scenario that lays its state out as vehicles on one lane (``vehicle_roles``,
``to_vehicles``: lead-follow, fleet3; the SUMO back end uses the same) gives each
vehicle's front bumper relative to the SV's front and its speed. On the road, the SV's
front starts at ``sv_front`` (the same for every start state of the scenario, so the
rearmost vehicle Sigma allows still starts ``BACK_MARGIN`` from the road's start), and
an OpenSCENARIO position is a vehicle's reference point: its rear axle,
``REF_TO_FRONT`` behind the front bumper (the bounding box says so to every tool).
"""

from __future__ import annotations

import itertools
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
        corners = np.array(list(itertools.product(*zip(sc.lower, sc.upper))), dtype=float)
        s, v = self.place(corners)
        travel = (float(np.max(v, initial=0.0)) + SPEED_MARGIN) * self.dt * max(horizon_states - 1, 1)
        return float(np.ceil((float(s.max()) + self.length + travel + FRONT_MARGIN) / 10.0) * 10.0)


def layout_of(scenario) -> Layout:
    for attr in ("vehicle_roles", "to_vehicles", "vehicle_length"):
        if not hasattr(scenario, attr):
            raise NotALaneScenario(f"export --xosc: scenario {scenario.name!r} does not lay its state out as "
                                   f"vehicles on one lane (no {attr}); OpenSCENARIO export supports lane scenarios "
                                   f"such as lead-follow and fleet3")
    bad = [name for name in scenario.state_names if not PARAMETER_NAME.match(name)]
    if bad:
        raise NotALaneScenario(f"export --xosc: state variable {bad[0]!r} is not an OpenSCENARIO parameter name "
                               f"([A-Za-z_][A-Za-z0-9_]*)")
    length = float(scenario.vehicle_length)
    corners = np.array(list(itertools.product(*zip(scenario.lower, scenario.upper))), dtype=float)
    fronts, _ = scenario.to_vehicles(corners)
    sv_front = BACK_MARGIN + length - float(fronts.min())  # the rearmost rear bumper at BACK_MARGIN
    return Layout(scenario, tuple(scenario.vehicle_roles), length, sv_front, float(scenario.dt))
