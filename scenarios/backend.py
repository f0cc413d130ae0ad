"""The back-end contract: a simulator that advances a batch of runs in lock-step.

The shared rollout core (``scenarios.rollout``) owns the bookkeeping every back end
needs the same way: action draws from each run's own stream, classification of every
state (continue / truncated / failure), run ends, lengths, outcomes, the finiteness
check and the step-bound check. A back end implements only the simulator side:

    insert(starts, horizon, streams)
                                place runs exactly at ``starts`` (B, n), each to last at most
                                ``horizon`` states; return the states read back (B, n).
                                ``streams``: the runs' keyed random streams
                                (``scenarios.streams.RunStreams``), for a simulator's own
                                randomness
    step(states, actions, noise, out)
                                advance every held run one ``dt`` under ``actions`` (k, m)
                                and write the states read back into ``out`` (n, k);
                                ``states`` (k, n) are the held runs' last read-back states
    keep(rows)                  forget the runs whose flag is False: they ended in the step
                                just taken, and are never stepped again
    clear()                     end of the batch: release whatever the runs hold

plus attributes: ``max_batch`` (None, or the most runs one simulation holds: the core
runs larger batches in consecutive pieces) and ``deterministic`` (a run's outcome
depends on its key alone: needed for exactness).

``NumpyBackend`` is the back end of every scenario with a functional ``step_into``;
``scenarios.sumo`` is a black-box simulator behind the same four calls, and
``scenarios.per_run`` adapts a simulator that advances one scene at a time.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from scenarios.base import Scenario
from scenarios.errors import ConfigError
from scenarios.streams import RunStreams


@runtime_checkable
class Backend(Protocol):
    """A batch simulator for one scenario (see the module docstring)."""

    scenario: Scenario
    deterministic: bool
    max_batch: int | None

    def insert(self, starts: np.ndarray, horizon: int, streams: RunStreams) -> np.ndarray: ...

    def step(self, states: np.ndarray, actions: np.ndarray, noise: np.ndarray | None, out: np.ndarray) -> None: ...

    def keep(self, rows: np.ndarray) -> None: ...

    def clear(self) -> None: ...


class NumpyBackend:
    """The scenario's own vectorized dynamics, stateless: the states are the core's.

    The core hands ``step`` a slab of its trajectory store as ``out``, so a step writes
    straight into the store."""

    name = "numpy"
    deterministic = True  # the spec's dynamics: a run is a function of its key
    max_batch = None

    def __init__(self, scenario: Scenario, options: dict | None = None):
        if options:
            raise ConfigError(f"scenario.numpy: the numpy back end takes no options; got {sorted(options)}")
        self.scenario = scenario

    def insert(self, starts: np.ndarray, horizon: int, streams: RunStreams) -> np.ndarray:
        return starts

    def step(self, states, actions, noise, out) -> None:
        self.scenario.step_into(states, actions, noise, out)

    def keep(self, rows: np.ndarray) -> None:
        pass

    def clear(self) -> None:
        pass
