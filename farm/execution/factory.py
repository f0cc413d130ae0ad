"""The executors, by the config's ``farm.executor`` (the contract is coordinator/executor.py):

- ``local``: in-process (farm/execution/local.py);
- ``ray``: stateless Ray actors on a local Ray or a cluster (farm/ray_runtime/executor.py);
- ``virtual``: in-process on a simulated clock of many workers (farm/execution/virtual.py).

Each is imported only when chosen (Ray takes seconds to import and start).
"""

from __future__ import annotations

import threading

from coordinator.executor import Executor
from scenarios.simulator import SimSpec


def make_executor(farm_cfg, spec: SimSpec, check_step_bound: bool = False,
                  stop: threading.Event | None = None) -> Executor:
    """The executor the ``[farm]`` section (``farm.config.FarmConfig``) names, simulating
    ``spec``; ``check_step_bound``: check the scenario's step bound on every batch;
    ``stop``: an event that ends a wait for a chunk when set (a signal: farm/jobs/signals.py)."""
    if farm_cfg.executor == "ray":
        from farm.ray_runtime.executor import RayExecutor

        return RayExecutor(spec, farm_cfg.workers, farm_cfg.address, farm_cfg.max_retries, check_step_bound,
                           farm_cfg.pipeline_depth, farm_cfg.chunk_timeout, stop)
    if farm_cfg.executor == "virtual":
        from farm.execution.virtual import VirtualExecutor

        v = farm_cfg.virtual
        return VirtualExecutor(spec, farm_cfg.workers, v.run_time, v.jitter, v.call_cost, farm_cfg.pipeline_depth,
                               check_step_bound)
    from farm.execution.local import LocalExecutor

    return LocalExecutor(spec, check_step_bound, farm_cfg.chunk_timeout, stop)
