"""A simulator in a process that simulates batches from now on (the coordinator with the
local executor, a Ray actor, a re-run)."""

from __future__ import annotations

from farm.execution.memory import keep_freed_memory
from scenarios.simulator import SimSpec, Simulator


def build_simulator(spec: SimSpec, check_step_bound: bool = False) -> Simulator:
    """The scenario, back end and action policy of ``spec``, checked now (a bad config
    fails here, before any file is written)."""
    keep_freed_memory()  # this process simulates batches from now on: keep freed memory for reuse
    return Simulator(spec, check_step_bound)
