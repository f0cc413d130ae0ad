"""The executors, by the config's ``farm.executor`` (the contract is coordinator/executor.py):

- ``local``: in-process (farm/local_executor.py);
- ``ray``: stateless Ray actors on a local Ray or a cluster (farm/ray_executor.py).

Each is imported only when chosen (Ray takes seconds to import and start).
"""

from __future__ import annotations

from coordinator.executor import Executor
from scenarios.simulator import SimSpec


def make_executor(farm_cfg, spec: SimSpec, check_step_bound: bool = False) -> Executor:
    """The executor the ``[farm]`` section (``farm.config.FarmConfig``) names, simulating
    ``spec``; ``check_step_bound``: check the scenario's step bound on every batch."""
    if farm_cfg.executor == "ray":
        from farm.ray_executor import RayExecutor

        return RayExecutor(spec, farm_cfg.workers, farm_cfg.address, farm_cfg.max_retries, check_step_bound,
                           farm_cfg.pipeline_depth)
    from farm.local_executor import LocalExecutor

    return LocalExecutor(spec, check_step_bound)
