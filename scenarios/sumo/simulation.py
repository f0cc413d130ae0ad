"""The one SUMO simulation of this process.

libsumo runs one simulation per process and a second ``start`` silently replaces the
first, so every SUMO scenario of the process shares this one, started lazily on the
first rollout and reloaded only when it lacks something: more run slots, longer roads,
or an SV vType it has not loaded yet (SUMO cannot change a vType's car-following model
at run time). Between batches the vehicles are removed and new ones added, which costs
microseconds per vehicle instead of the tens of milliseconds of a reload.

This is the only module that imports libsumo.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import libsumo

from scenarios.errors import ConfigError
from scenarios.sumo import network

STEP_LENGTH = 0.1  # [s] the spec's dt

# Why each option:
#   --step-method.ballistic  position update x = (v + v')/2 * dt = v*dt + a*dt^2/2, the
#                            spec's kinematics (SUMO's default Euler update is x = v'*dt)
#   --insertion-checks none  insert at exactly the requested gap and speed, even unsafe ones
#   --collision.action warn  a crash must not remove or stop vehicles: the back end
#   --collision.mingap-factor 0   classifies the read-back gap itself
#   --time-to-teleport -1    never teleport a vehicle that waits (a stopped SV)
#   --no-warnings, --no-step-log  quiet (emergency braking and collisions are the point)
#   --seed 0                 fixed, although no randomness is enabled (see config.py)
#   --xml-validation never   the files are generated here; skip the schema lookups
SUMO_OPTIONS = [
    "--step-length", repr(STEP_LENGTH),
    "--step-method.ballistic", "true",
    "--insertion-checks", "none",
    "--collision.action", "warn",
    "--collision.mingap-factor", "0",
    "--collision.check-junctions", "false",
    "--time-to-teleport", "-1",
    "--no-warnings", "true",
    "--no-step-log", "true",
    "--duration-log.disable", "true",
    "--seed", "0",
    "--xml-validation", "never",
    "--xml-validation.net", "never",
    "--xml-validation.routes", "never",
]

MIN_SLOTS = 64
MIN_LENGTH = 2000.0  # [m]


class SumoLoadError(ConfigError):
    """SUMO refused the generated files (in practice: a vType attribute value)."""


class World:
    def __init__(self):
        self.slots = 0
        self.length = 0.0
        self.vtypes: dict[str, dict[str, str]] = {}
        self.loaded = False
        self.batches = 0  # makes vehicle ids unique across batches
        self._dir: str | None = None

    # -- (re)loading -------------------------------------------------------------------
    def ensure(self, slots: int, length: float, vtype_id: str, vtype_attrs: dict[str, str]) -> None:
        """Make sure the simulation has >= ``slots`` roads of >= ``length`` m and the vType."""
        if self.loaded and slots <= self.slots and length <= self.length and vtype_id in self.vtypes:
            return
        previous = dict(self.vtypes)
        self.slots = max(self.slots, MIN_SLOTS, 1 << max(slots - 1, 0).bit_length())
        # Grow geometrically so that a slowly growing horizon reloads O(log) times.
        if length > self.length:
            self.length = max(MIN_LENGTH, 2.0 * length, self.length)
        self.vtypes[vtype_id] = vtype_attrs
        try:
            self._load()
        except SumoLoadError:
            self.vtypes = previous  # keep the world loadable for the other scenarios
            raise

    def _load(self) -> None:
        if self._dir is None:
            self._dir = tempfile.mkdtemp(prefix="scenario-farm-sumo-")
            atexit.register(shutil.rmtree, self._dir, True)
        net = os.path.join(self._dir, "roads.net.xml")
        routes = os.path.join(self._dir, "types.rou.xml")
        errors = os.path.join(self._dir, "errors.log")
        network.write_net(net, self.slots, self.length)
        network.write_routes(routes, self.slots, self.vtypes)
        if os.path.exists(errors):
            os.remove(errors)  # so that only this load's errors are reported
        args = ["-n", net, "-r", routes, "--error-log", errors, *SUMO_OPTIONS]
        try:
            if self.loaded:
                libsumo.simulation.load(args)
            else:
                libsumo.simulation.start(["sumo", *args])
                atexit.register(_close)
        except libsumo.TraCIException as exc:
            self.loaded = False
            detail = " ".join((_read(errors) or str(exc)).split())  # one line
            raise SumoLoadError(f"scenario.sumo.params: SUMO rejected the SV vType: {detail}") from None
        self.loaded = True

    # -- vehicles ------------------------------------------------------------------------
    def clear(self) -> None:
        """Remove every vehicle (also those an interrupted batch left behind)."""
        remove = libsumo.vehicle.remove
        for vid in libsumo.vehicle.getIDList():
            remove(vid)
        self.batches += 1


def _read(path: str) -> str:
    try:
        with open(path) as fh:
            lines = [ln.strip() for ln in fh if ln.strip()]
    except OSError:
        return ""
    return " ".join(ln.removeprefix("Error: ") for ln in lines[-3:])


def _close() -> None:
    try:
        libsumo.close()
    except Exception:  # already closed or never started: nothing to release
        pass


_WORLD: World | None = None


def world() -> World:
    global _WORLD
    if _WORLD is None:
        _WORLD = World()
    return _WORLD
