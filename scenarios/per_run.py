"""The per-run simulator contract: a simulator that advances one scene at a time (CARLA,
esmini, highway-env, an in-house tool), beside the vectorized back ends.

A user class subclasses ``RunSimulator`` and implements two calls:

    reset(state, key) -> state  place the scene exactly at the start state (n,); return the
                                state read back from the simulator (the core checks it to 1e-9)
    step(action) -> state       advance the scene one ``dt`` under the scenario action (m,)
                                and return the state read back (n,)
    close()                     optional: release the simulator (end of the worker)

``key`` is a ``RunKey``: the run's stream key ``(seed, index)``, from which the
simulator's own randomness must come (``key.generator()``) so that a run depends on its
key alone. One object is built per worker process (``Class(scenario, options)``) and
reused for every run it simulates, one run after the other: ``reset`` must forget the
previous run entirely.

``PerRunBackend`` adapts such a class to the batch contract of ``scenarios.backend``:
the rollout core runs a batch as pieces of one run (``max_batch = 1``), so the keyed
action streams, the classification of every state, the end of a run at its first facet
(a run that ended is never stepped again), the start and finiteness checks and the
step-bound check are the same code as for every other back end. A config names the class
as ``scenario.backend = "package.module:Class"``; its options table is
``[scenario."package.module:Class"]``.
"""

from __future__ import annotations

import sys
import threading
import weakref
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from scenarios.base import Scenario, ScenarioError
from scenarios.errors import ConfigError
from scenarios.streams import PURPOSE_USER, RunStreams


@dataclass(frozen=True)
class RunKey:
    """A run's stream key: the campaign ``seed`` and the run's global sample ``index``."""

    seed: int
    index: int

    def generator(self) -> np.random.Generator:
        """A numpy Generator of this run's own (the same key gives the same draws), for
        the simulator's randomness (e.g. highway-env's ``road.np_random``)."""
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(self.seed,
                                                                          spawn_key=(self.index, PURPOSE_USER))))


class RunSimulator(ABC):
    """A simulator of one scene at a time (see the module docstring).

    Class attributes:
      sv_policy   what the summary calls the SV (the simulator's own model), e.g.
                  "highway-env-idm"; a config's ``scenario.sv_policy`` must be this or unset
      stochastic  True if the scene draws from ``key.generator()``: a run then depends on
                  its key, not on its start alone (no exact enumeration of box centres)
    """

    sv_policy: str = "external"
    stochastic: bool = False

    def __init__(self, scenario: Scenario, options: dict | None = None):
        """``scenario`` declares the state space (Sigma, facets, actions, dt);
        ``options`` is the config's ``[scenario."module:Class"]`` table (or None)."""
        self.scenario = scenario
        self.options = dict(options or {})

    @abstractmethod
    def reset(self, state: np.ndarray, key: RunKey) -> np.ndarray:
        """Place the scene exactly at ``state`` (n,); -> the state read back (n,)."""

    @abstractmethod
    def step(self, action: np.ndarray) -> np.ndarray:
        """Advance one ``dt`` under ``action`` (m,); -> the state read back (n,)."""

    def close(self) -> None:
        """Release the simulator (called once, when the worker's back end goes away)."""


class PerRunBackend:
    """A ``RunSimulator`` class behind the four calls of ``scenarios.backend.Backend``:
    pieces of one run each, so the user object holds one scene at a time.

    Every call into the user's object goes through ``_call``: what it raises (SystemExit
    too: a ``sys.exit`` in a simulator is no verdict) is a one-line ScenarioError naming
    the class, the method and the run, and ``where()`` says which call it is in, so that
    an executor whose wait for it overruns can name where it hangs."""

    name = "per-run"
    max_batch = 1  # the core runs a batch run by run: one scene in the simulator at a time
    simulator_class: type[RunSimulator]  # set by ``per_run_backend``

    def __init__(self, scenario: Scenario, options: dict | None = None):
        if scenario.disturbance != 0.0:
            raise ConfigError(f"scenario.disturbance: a per-run simulator brings its own randomness "
                              f"(key.generator()); allowed: 0 (got {scenario.disturbance:g})")
        self.scenario = scenario
        self._n = scenario.n
        self._run = ""  # the run in the simulator: "sample index ... (start state ...)"
        self._calling: str | None = None  # the user method running now
        self.simulator = self._call("__init__", self.simulator_class, scenario, options)
        self._closer = weakref.finalize(self, _close_quietly, self.simulator, self.name, self.method_name("close"))

    def insert(self, starts: np.ndarray, horizon: int, streams: RunStreams) -> np.ndarray:
        key = RunKey(streams.seed, int(streams.indices[0]))
        self._run = f"sample index {key.index} (start state {np.round(starts[0], 6).tolist()})"
        return self._state(self._call("reset", self.simulator.reset, starts[0].copy(), key), "reset").reshape(1, self._n)

    def step(self, states, actions, noise, out) -> None:
        out[:, 0] = self._state(self._call("step", self.simulator.step, actions[0].copy()), "step")

    def keep(self, rows: np.ndarray) -> None:
        pass  # a piece holds one run: when it ends the piece ends

    def clear(self) -> None:
        pass  # the next run's reset places a new scene

    def close(self) -> None:
        """Release the user's simulator now (once; otherwise at garbage collection or exit)."""
        if self._closer.detach() is not None:
            self._call("close", self.simulator.close)

    def method_name(self, method: str) -> str:
        """``module:Class.method()``, as errors name a user method."""
        return f"{self.name}.{method}()"

    def where(self) -> str | None:
        """The user call running now, and on which run (None between calls)."""
        if self._calling is None:
            return None
        return self.method_name(self._calling) + (f" on {self._run}" if self._calling in ("reset", "step") else "")

    def _call(self, method: str, function, *args):
        self._calling = method
        try:
            value = function(*args)
        except ScenarioError:
            raise
        except (Exception, SystemExit) as exc:  # the user's code: their error, named (KeyboardInterrupt passes)
            on = f" on {self._run}" if self._run and method in ("reset", "step") else ""
            raise ScenarioError(f"{self.method_name(method)} raised {type(exc).__name__}: {exc}{on}") from None
        self._calling = None
        return value

    def _state(self, state, call: str) -> np.ndarray:
        state = np.asarray(state, dtype=float)
        if state.shape != (self._n,):
            raise ScenarioError(f"{self.method_name(call)} returned shape {state.shape}, expected ({self._n},): the "
                                f"state {self.scenario.state_names} read back, on {self._run}")
        return state


_WARNED: set[str] = set()  # the close() methods whose failure was printed
CLOSE_AT_EXIT_S = 60.0  # [s] a close() left to garbage collection or exit may take (the farm's own closes: farm.chunk_timeout)


def _close_quietly(simulator: RunSimulator, name: str, method: str) -> None:
    """A finalizer: the user's close() at garbage collection or interpreter exit, where
    an exception can only be printed (one line, not a traceback per simulator object) and
    a close that hangs must not keep the process from ending."""
    box: dict = {}

    def close():
        try:
            simulator.close()
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's code
            box["error"] = exc

    try:
        thread = threading.Thread(target=close, name="farm-close", daemon=True)
        thread.start()
    except RuntimeError:  # no new threads this late in the interpreter's shutdown
        close()
    else:
        thread.join(CLOSE_AT_EXIT_S)
        if thread.is_alive():
            box["hung"] = True
    if not box or method in _WARNED:  # a process builds the back end more than once: one line is enough
        return
    _WARNED.add(method)
    problem = (f"did not return within {CLOSE_AT_EXIT_S:g} s (left running)" if "hung" in box
               else f"raised {type(box['error']).__name__}: {box['error']}")
    print(f"scenario-farm: warning: {method} {problem}", file=sys.stderr)


def per_run_backend(cls: type[RunSimulator]) -> type[PerRunBackend]:
    """The back-end class of a ``RunSimulator`` class (what the registry hands out)."""
    return type(f"PerRun{cls.__name__}", (PerRunBackend,), {
        "simulator_class": cls, "external_sv": cls.sv_policy, "deterministic": not cls.stochastic,
        "name": f"{cls.__module__}:{cls.__qualname__}"})
