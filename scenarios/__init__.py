"""Scenario systems and the back ends that simulate them (the bottom layer).

- ``Scenario`` (``base.py``): the state box Sigma, facets, actions Gamma and Gamma*, and
  the vectorized dynamics ``step``; one file per scenario.
- ``Backend`` (``backend.py``): a batch simulator (numpy, SUMO, ...); the shared
  rollout core ``run_scenario`` (``rollout.py``) does every run's bookkeeping.
- ``registry.py``: scenarios and back ends by name; ``simulator.py``: what a worker holds.
- ``streams.py``: per-run random streams keyed by (seed, sample index).
"""

from scenarios.backend import Backend, NumpyBackend
from scenarios.base import (CONTINUE, EXTERNAL_SV, FAILURE, HORIZON, NO_SV, OUTCOME_NAMES, TRUNCATED, Scenario,
                            ScenarioError, Slices, View)
from scenarios.registry import (backend_class, make_backend, make_scenario, register_backend, register_scenario,
                                scenario_class)
from scenarios.rollout import RunBatch, run_scenario
from scenarios.simulator import SimSpec, Simulator
from scenarios.streams import RunStreams
from scenarios.version import __version__

__all__ = ["Backend", "CONTINUE", "EXTERNAL_SV", "FAILURE", "HORIZON", "NO_SV", "NumpyBackend", "OUTCOME_NAMES",
           "RunBatch", "RunStreams", "Scenario", "ScenarioError", "SimSpec", "Simulator", "Slices", "TRUNCATED",
           "View", "__version__", "backend_class", "make_backend", "make_scenario", "register_backend",
           "register_scenario", "run_scenario", "scenario_class"]
