"""The SUMO back end: the SV is a real SUMO vehicle driven by SUMO's own car-following
model, a true black box (shared/spec/scenarios.md, section "sumo back end").

It implements the four calls of ``scenarios.backend.Backend`` for any scenario that can
be laid out as vehicles on one lane (``vehicle_roles``, ``to_vehicles``,
``from_vehicles``: lead-follow and fleet3). All runs of a batch share one simulation,
each on its own road (see network.py), so one ``simulationStep`` advances all of them.
Per step the commanded vehicles (lead, follower) get their new speeds (speed mode 0:
obeyed exactly), SUMO moves everything, and the state is read back from SUMO's
positions and speeds; the rollout core classifies it.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import Scenario
from scenarios.errors import ConfigError
from scenarios.sumo import network
from scenarios.sumo.config import parse_config

BACK_MARGIN = 5.0  # [m] road before the rearmost vehicle's back bumper
FRONT_MARGIN = 100.0  # [m] road left after the furthest possible travel
MAX_SLOTS = 1024  # runs per simulation; the rollout core runs larger batches in pieces
_SUMO_DEFAULT_ACCEL_BOUND = 9.0  # [m/s^2] SUMO's passenger emergencyDecel (accel 2.6, decel 4.5 are smaller)


class SumoBackend:
    name = "sumo"
    external_sv = "sumo"  # the config's sv_policy: the SV is SUMO's own model
    max_batch = MAX_SLOTS

    def __init__(self, scenario: Scenario, options: dict | None = None):
        for attr in ("vehicle_roles", "to_vehicles", "from_vehicles"):
            if not hasattr(scenario, attr):
                raise ConfigError(f"scenario.backend: the sumo back end simulates vehicles on one lane; scenario "
                                  f"{scenario.name!r} does not say how (no {attr})")
        traffic = scenario.traffic_roles
        if traffic:
            raise ConfigError(f"scenario.backend: the sumo back end commands every vehicle but the SV by an action "
                              f"column; in scenario {scenario.name!r} its own traffic model drives "
                              f"{', '.join(traffic)} (use the numpy back end)")
        if scenario.disturbance != 0.0:
            raise ConfigError("scenario.disturbance: the sumo back end supports only 0")
        self.scenario = scenario
        self.config = parse_config(options)
        self.deterministic = not self.config.allow_nondeterministic
        try:
            from scenarios.sumo.simulation import world  # imports libsumo: only now
        except ImportError as exc:
            raise ConfigError(f"scenario.backend: 'sumo' needs libsumo, which does not import here ({exc}); "
                              f"install it with pip install 'scenario-farm[sumo]'") from None

        world().ensure(1, 0.0, self.config.vtype_id, self.config.vtype_attributes())  # SUMO's own vType check
        self._ids: list[list[str]] = []
        # sigma-bar: SUMO never brakes harder than max(decel, emergencyDecel)
        params = self.config.params
        scenario.sv_accel_bound = max([scenario.sv_accel_bound, _SUMO_DEFAULT_ACCEL_BOUND] + [
            float(params[k]) for k in ("accel", "decel", "emergencyDecel") if k in params])

    # -- the Backend calls -------------------------------------------------------------
    def insert(self, starts: np.ndarray, horizon: int, streams=None) -> np.ndarray:
        import libsumo

        from scenarios.sumo.simulation import world

        fronts, speeds = self.scenario.to_vehicles(starts)
        # Each road starts just behind its rearmost vehicle; it must outlast the fastest
        # possible travel (speeds beyond Sigma end a run within a step).
        shift = BACK_MARGIN + np.maximum(0.0, self.scenario.vehicle_length - fronts.min(axis=1))
        fronts = fronts + shift[:, None]
        v_cap = float(np.max(speeds, initial=0.0)) + float(np.max(self.scenario.upper)) + 50.0
        road = float(fronts.max()) + v_cap * self.scenario.dt * (horizon - 1) + FRONT_MARGIN
        w = world()
        w.ensure(len(starts), road, self.config.vtype_id, self.config.vtype_attributes())
        w.clear()
        veh = libsumo.vehicle
        roles = self.scenario.vehicle_roles
        tag = w.batches
        self._ids = [[f"{role}{tag}.{i}" for i in range(len(starts))] for role in roles]
        self._slots = list(range(len(starts)))
        types = [self.config.vtype_id] + [network.COMMANDED_VTYPE_ID] * (len(roles) - 1)
        for r, role_ids in enumerate(self._ids):
            for i, (vid, pos, speed) in enumerate(zip(role_ids, fronts[:, r].tolist(), speeds[:, r].tolist())):
                veh.add(vid, network.route_id(i), typeID=types[r], depart="now", departLane="0",
                        departPos=repr(pos), departSpeed=repr(speed))
        libsumo.simulation.step()  # vehicles do not move in their insertion step
        for role_ids in self._ids[1:]:
            for vid in role_ids:
                veh.setSpeedMode(vid, 0)  # obey setSpeed exactly: no safety, accel or decel limits
        self._x, self._v = self._read()
        return self.scenario.from_vehicles(self._x, self._v)  # differences of positions only

    def step(self, states, actions, noise, out) -> None:
        import libsumo

        v_cmd = self._v[:, 1:]
        target = v_cmd + actions * self.scenario.dt
        stops = target < 0.0
        target[stops] = 0.0
        set_speed = libsumo.vehicle.setSpeed
        for r, role_ids in enumerate(self._ids[1:]):
            for vid, speed in zip(role_ids, target[:, r].tolist()):
                set_speed(vid, speed)
        libsumo.simulation.step()
        stopping = stops & (v_cmd > 0.0)
        if stopping.any():
            self._stop_exactly(v_cmd, actions, stopping)
        self._x, self._v = self._read()
        out[...] = self.scenario.from_vehicles(self._x, self._v).T

    def keep(self, rows: np.ndarray) -> None:
        import libsumo

        remove = libsumo.vehicle.remove
        for role_ids in self._ids:
            for i in np.nonzero(~rows)[0]:
                remove(role_ids[i])  # SUMO would keep simulating them otherwise
        kept = np.nonzero(rows)[0].tolist()
        self._ids = [[role_ids[i] for i in kept] for role_ids in self._ids]
        self._slots = [self._slots[i] for i in kept]
        self._x, self._v = self._x[rows], self._v[rows]

    def clear(self) -> None:
        from scenarios.sumo.simulation import world

        world().clear()
        self._ids = []

    # -- helpers -------------------------------------------------------------------------
    def _read(self) -> tuple[np.ndarray, np.ndarray]:
        """Front positions and speeds (B, R) of the vehicles, read back from SUMO."""
        import libsumo

        pos, speed = libsumo.vehicle.getLanePosition, libsumo.vehicle.getSpeed
        x = np.array([[pos(vid) for vid in role] for role in self._ids]).T
        v = np.array([[speed(vid) for vid in role] for role in self._ids]).T
        return x.reshape(-1, len(self._ids)), v.reshape(-1, len(self._ids))

    def _stop_exactly(self, v_prev, actions, stopping) -> None:
        """A commanded vehicle that stops inside the step travels v^2 / (2|u|) in the
        spec; SUMO's ballistic update of a speed command v -> 0 assumes the deceleration
        v/dt instead (distance v*dt/2, up to |u|*dt^2/8 = 6 mm more). Put it where the
        spec says."""
        import libsumo

        for row, col in zip(*np.nonzero(stopping)):
            vel, acc = float(v_prev[row, col]), float(actions[row, col])
            target = float(self._x[row, col + 1]) + vel * vel / (2.0 * abs(acc))
            libsumo.vehicle.moveTo(self._ids[col + 1][row], network.lane_id(self._slots[row]), target)
