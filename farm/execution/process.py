"""What a worker simulates, from a config (``spec_of``), and a simulator in a process that
simulates batches from now on (``build_simulator``: the coordinator with the local
executor, a Ray actor, a re-run), and its release (``close_simulator``)."""

from __future__ import annotations

from farm.config import Config
from farm.execution.chunking import close_limit
from farm.execution.memory import keep_freed_memory
from farm.execution.waiting import InThread
from scenarios.simulator import SimSpec, Simulator


def build_simulator(spec: SimSpec, check_step_bound: bool = False) -> Simulator:
    """The scenario, back end and action policy of ``spec``, checked now (a bad config
    fails here, before any file is written)."""
    keep_freed_memory()  # this process simulates batches from now on: keep freed memory for reuse
    return Simulator(spec, check_step_bound)


def spec_of(cfg: Config, failure_facets: list | None = None) -> SimSpec:
    """What a quantification's workers simulate; ``failure_facets`` replaces the
    configured ones (a side campaign)."""
    scenario = cfg.scenario.model_dump()
    if failure_facets is not None:
        scenario["failure_facets"] = list(failure_facets)
    return SimSpec(scenario, cfg.actions.model_dump(), cfg.quantify.horizon, cfg.farm.seed,
                   deep_margins=cfg.refinement() == "margin")


def close_simulator(simulator: Simulator, chunk_timeout: float, thread: InThread | None = None) -> None:
    """Release the simulator's back end now (a per-run simulator's ``close()``), in
    ``thread`` and within farm.chunk_timeout (``close_limit``): a close that hangs is a WorkerError naming it
    (exit 4), not a process that never ends; one that raises is the user's ScenarioError."""
    backend = simulator.backend
    close = getattr(backend, "close", None)
    if close is None:
        return
    thread = thread or InThread()
    if thread.stuck:  # the simulator hangs already, and was named: a close would wait behind it
        return
    thread.run(close, close_limit(chunk_timeout), lambda: backend.where() or backend.method_name("close"), interruptible=False)
