"""The executors, by the config's ``farm.executor`` (the contract is coordinator/executor.py):

- ``local``: in-process (farm/execution/local.py);
- ``ray``: stateless Ray actors on a local Ray or a cluster (farm/ray_runtime/executor.py);
- ``virtual``: in-process on a simulated clock of many workers (farm/execution/virtual.py).

Each is imported only when chosen (Ray takes seconds to import and start).
"""

from __future__ import annotations

import threading
from typing import Callable

from coordinator.executor import Executor
from farm import lazy
from scenarios.simulator import SimSpec


def make_executor(farm_cfg, spec: SimSpec, check_step_bound: bool = False,
                  stop: threading.Event | None = None, notify: Callable[[str], None] | None = None) -> Executor:
    """The executor the ``[farm]`` section (``farm.config.FarmConfig``) names, simulating
    ``spec``, started; ``check_step_bound``: check the scenario's step bound on every batch;
    ``stop``: an event that ends a wait for a chunk when set (a signal: farm/jobs/signals.py);
    ``notify``: takes a line for the user (e.g. a Ray worker replaced)."""
    return EXECUTORS[farm_cfg.executor](farm_cfg, spec, check_step_bound, stop, notify)


def _ray(farm_cfg, spec, check_step_bound, stop, notify) -> Executor:
    return lazy.ray_executor.RayExecutor(spec, farm_cfg.workers, farm_cfg.address, farm_cfg.max_retries,
                                         check_step_bound, farm_cfg.pipeline_depth, farm_cfg.chunk_timeout, stop,
                                         notify).start()


def _virtual(farm_cfg, spec, check_step_bound, stop, notify) -> Executor:
    v = farm_cfg.virtual
    return lazy.virtual_executor.VirtualExecutor(spec, farm_cfg.workers, v.run_time, v.jitter, v.call_cost,
                                                 farm_cfg.pipeline_depth, check_step_bound)


def _local(farm_cfg, spec, check_step_bound, stop, notify) -> Executor:
    return lazy.local_executor.LocalExecutor(spec, check_step_bound, farm_cfg.chunk_timeout, stop)


# farm.executor -> its builder; an executor's module is imported only when it is chosen
EXECUTORS = {"local": _local, "ray": _ray, "virtual": _virtual}
