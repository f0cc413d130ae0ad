"""``rollout``: ``run_scenario`` (paper Alg. 1) for a scenario whose SV lives in SUMO.

SUMO's SV keeps internal state (its car-following model, its own position), so the
back end cannot offer a functional ``step(states, actions)``; it runs whole batches
instead, with exactly ``run_scenario``'s semantics and return type. All runs of a batch
share one simulation, each on its own road (see network.py), so one
``simulationStep`` advances all of them.

Per step: the policy gives the scenario actions from the current states (same call as
``run_scenario``, so the same (seed, index) streams give the same action sequences),
the commanded vehicles get their new speeds (speed mode 0: the command is obeyed
exactly), SUMO moves everything, and the state is read back from SUMO's positions and
speeds, then classified.
"""

from __future__ import annotations

import libsumo
import numpy as np

from scenarios.base import CONTINUE, HORIZON
from scenarios.run import RunBatch, ScenarioError
from scenarios.sumo import network
from scenarios.sumo.simulation import STEP_LENGTH, world

MAX_SLOTS = 1024  # runs per simulation batch; larger batches run as consecutive chunks
BACK_MARGIN = 5.0  # [m] road before the rearmost vehicle's back bumper
FRONT_MARGIN = 100.0  # [m] road left after the furthest possible travel
START_TOLERANCE = 1e-9  # read-back start state vs requested (SUMO stores doubles: exact in practice)


class SumoRollout:
    """Mixin for a Scenario subclass. The subclass provides:

    roles                  vehicle roles, SV first, then one commanded vehicle per action column
    _layout(states)        -> (fronts (B, R) relative to the SV's front [m], speeds (B, R))
    _state(fronts, speeds) -> (B, n) scenario states from read-back positions and speeds
    sumo_config            the checked ``SumoConfig``
    """

    roles: tuple[str, ...] = ()

    def step(self, states, actions, noise):
        raise NotImplementedError("the sumo back end runs whole batches: use rollout() (run_scenario does)")

    def rollout(self, starts, horizon, policy, streams) -> RunBatch:
        starts = np.asarray(starts, dtype=float)
        if horizon < 2:
            raise ValueError(f"horizon: K must be >= 2, got {horizon}")
        if starts.ndim != 2 or starts.shape[1] != self.n:
            raise ScenarioError(f"start states have shape {starts.shape}, scenario {self.name!r} needs (B, {self.n})")
        if len(streams) != len(starts):
            raise ScenarioError(f"{len(starts)} start states but {len(streams)} run streams")
        batch = len(starts)
        store = np.empty((horizon, batch, self.n))
        store[0] = starts
        lengths = np.full(batch, horizon, dtype=np.int32)
        outcomes = np.full(batch, HORIZON, dtype=np.int8)
        for lo in range(0, batch, MAX_SLOTS):
            hi = min(batch, lo + MAX_SLOTS)
            chunk_streams = streams if (lo, hi) == (0, batch) else streams.subset(np.arange(lo, hi))
            self._run_chunk(starts[lo:hi], horizon, policy, chunk_streams,
                            store[:, lo:hi], lengths[lo:hi], outcomes[lo:hi])
        return RunBatch(streams.indices, store, lengths, outcomes)

    # -- one simulation batch --------------------------------------------------------------
    def _run_chunk(self, starts, horizon, policy, streams, store, lengths, outcomes):
        try:
            fronts, speeds = self._place(starts, horizon)
        except ScenarioError as exc:
            raise ScenarioError(f"{exc} (sample indices {int(streams.indices[0])}...)") from None
        w = world()
        try:
            self._simulate(w, starts, fronts, speeds, horizon, policy, streams, store, lengths, outcomes)
        finally:
            w.clear()  # also after an error: the next batch must find empty roads

    def inserted_states(self, starts) -> np.ndarray:
        """Insert runs at ``starts`` and return the states read back from SUMO before any
        step (for checking that insertion is exact), then remove them."""
        starts = np.asarray(starts, dtype=float)
        fronts, speeds = self._place(starts, horizon=2)
        w = world()
        try:
            ids = self._insert(w, fronts, speeds)
            x, v = _read(ids)
            return self._state(x, v)
        finally:
            w.clear()

    def _place(self, starts, horizon):
        """Absolute front positions and speeds (B, R) of a chunk; loads the simulation."""
        fronts, speeds = self._layout(starts)
        if not (np.isfinite(fronts).all() and np.isfinite(speeds).all()) or (speeds < 0).any():
            row = int(np.nonzero(~np.isfinite(starts).all(axis=1) | (speeds < 0).any(axis=1))[0][0])
            raise ScenarioError(f"start state {starts[row].tolist()}: speeds and positions must be finite, "
                                "speeds >= 0")
        # Each road starts just behind its rearmost vehicle; the road must outlast the
        # fastest possible travel (speeds beyond Sigma end a run within a step).
        shift = BACK_MARGIN + np.maximum(0.0, network.VEHICLE_LENGTH - fronts.min(axis=1))
        fronts = fronts + shift[:, None]
        v_cap = float(np.max(speeds, initial=0.0)) + float(np.max(self.upper)) + 50.0
        road = float(fronts.max()) + v_cap * STEP_LENGTH * (horizon - 1) + FRONT_MARGIN
        config = self.sumo_config
        w = world()
        w.ensure(len(starts), road, config.vtype_id, config.vtype_attributes())
        w.clear()
        return fronts, speeds

    def _insert(self, w, fronts, speeds) -> list[list[str]]:
        """Add one vehicle per role and run on road i = row i; one step inserts them
        (vehicles do not move in their insertion step). Returns the ids per role."""
        veh = libsumo.vehicle
        batch, n_roles = fronts.shape
        tag = w.batches
        ids = [[f"{role}{tag}.{i}" for i in range(batch)] for role in self.roles]
        types = [self.sumo_config.vtype_id] + [network.COMMANDED_VTYPE_ID] * (n_roles - 1)
        add = veh.add
        for r in range(n_roles):
            for i, (vid, pos, speed) in enumerate(zip(ids[r], fronts[:, r].tolist(), speeds[:, r].tolist())):
                add(vid, network.route_id(i), typeID=types[r], depart="now", departLane="0",
                    departPos=repr(pos), departSpeed=repr(speed))
        libsumo.simulation.step()
        for r in range(1, n_roles):
            for vid in ids[r]:
                veh.setSpeedMode(vid, 0)  # obey setSpeed exactly: no safety, accel or decel limits
        return ids

    def _simulate(self, w, starts, fronts, speeds, horizon, policy, streams, store, lengths, outcomes):
        veh = libsumo.vehicle
        n_roles = fronts.shape[1]
        batch = len(starts)
        ids = self._insert(w, fronts, speeds)
        x, v = _read(ids)
        bad = (np.abs(x - fronts) > START_TOLERANCE) | (np.abs(v - speeds) > START_TOLERANCE)
        if bad.any():
            row = int(np.nonzero(bad.any(axis=1))[0][0])
            raise ScenarioError(f"SUMO did not insert sample index {int(streams.indices[row])} at its start state "
                                f"{starts[row].tolist()}: fronts {x[row].tolist()} speeds {v[row].tolist()}, "
                                f"requested {fronts[row].tolist()} {speeds[row].tolist()}")

        dt = STEP_LENGTH
        rows = np.arange(batch)  # chunk rows still running
        slots = list(range(batch))
        row_streams = streams
        states = starts
        set_speed = veh.setSpeed
        for t in range(1, horizon):
            actions = np.asarray(policy(self, states, t, row_streams), dtype=float).reshape(len(rows), self.m)
            v_cmd = v[:, 1:]
            target = v_cmd + actions * dt
            stops = target < 0.0
            target[stops] = 0.0
            for r in range(1, n_roles):
                for vid, speed in zip(ids[r], target[:, r - 1].tolist()):
                    set_speed(vid, speed)
            libsumo.simulation.step()
            stopping = stops & (v_cmd > 0.0)
            if stopping.any():
                _stop_exactly(ids, slots, x, v_cmd, actions, stopping)
            x, v = _read(ids)
            nxt = self._state(x, v)
            status = self.classify(nxt)
            store[t, rows] = nxt
            ended = status != CONTINUE
            if not np.isfinite(nxt).all():
                row = int(np.nonzero(~np.isfinite(nxt).all(axis=1))[0][0])
                raise ScenarioError(f"SUMO produced a non-finite state at step {t} of sample index "
                                    f"{int(row_streams.indices[row])}: {nxt[row].tolist()}")
            if ended.any():
                done = rows[ended]
                outcomes[done] = status[ended]
                lengths[done] = t + 1
                keep = ~ended
                remove = veh.remove
                for r in range(n_roles):
                    for vid in (ids[r][i] for i in np.nonzero(ended)[0]):
                        remove(vid)  # SUMO would keep simulating them otherwise
                if not keep.any():
                    break
                kept = np.nonzero(keep)[0].tolist()
                ids = [[lst[i] for i in kept] for lst in ids]
                slots = [slots[i] for i in kept]
                rows, x, v, nxt = rows[keep], x[keep], v[keep], nxt[keep]
                row_streams = row_streams.subset(keep)
            states = nxt


def _read(ids) -> tuple[np.ndarray, np.ndarray]:
    """Front positions and speeds (B, R) of the vehicles, read back from SUMO."""
    pos, speed = libsumo.vehicle.getLanePosition, libsumo.vehicle.getSpeed
    x = np.array([[pos(vid) for vid in role] for role in ids]).T
    v = np.array([[speed(vid) for vid in role] for role in ids]).T
    return x.reshape(-1, len(ids)), v.reshape(-1, len(ids))


def _stop_exactly(ids, slots, x_prev, v_prev, actions, stopping):
    """A commanded vehicle that stops inside the step travels v^2 / (2|u|) in the spec;
    SUMO's ballistic update of a speed command v -> 0 assumes the deceleration v/dt
    instead (distance v*dt/2, up to |u|*dt^2/8 = 6 mm more). Put it where the spec says."""
    move = libsumo.vehicle.moveTo
    for row, col in zip(*np.nonzero(stopping)):
        vel, acc = float(v_prev[row, col]), float(actions[row, col])
        target = float(x_prev[row, col + 1]) + vel * vel / (2.0 * abs(acc))
        move(ids[col + 1][row], network.lane_id(slots[row]), target)
