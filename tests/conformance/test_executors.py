"""The executor conformance suite (farm/execution/testing.py) on every executor we ship: in-process,
Ray actors on a real local Ray, and the virtual farm (64 simulated workers of 1 s runs)."""

import os
import signal

import pytest

from farm.execution import testing
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec

SPEC = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 30, testing.SETTINGS.seed)


def ray_executor(workers: int = 2):
    from farm.ray_runtime.executor import RayExecutor

    return lambda spec: RayExecutor(spec, workers, "local", max_retries=3, pipeline_depth=2).start()


def kill_first_actor(executor) -> None:
    os.kill(executor.pids()[0], signal.SIGKILL)


def virtual_executor(spec):
    from farm.execution.virtual import VirtualExecutor

    return VirtualExecutor(spec, 64, run_time=1.0, jitter=0.3, call_cost=0.001)


@pytest.fixture(params=["local", "ray", "virtual"])
def make_executor(request):
    if request.param == "local":
        return LocalExecutor
    if request.param == "virtual":
        return virtual_executor
    request.getfixturevalue("ray_local")
    return ray_executor()


def test_chunks(make_executor):
    testing.check_chunks(make_executor, SPEC)


def test_cancel(make_executor):
    testing.check_cancel(make_executor, SPEC)


def test_ready(make_executor):
    testing.check_ready(make_executor, SPEC)


def test_close(make_executor):
    testing.check_close(make_executor, SPEC)


def test_same_campaign(make_executor):
    testing.check_same_campaign(make_executor, SPEC)


def test_a_killed_ray_worker_costs_time_not_results(ray_local):
    testing.check_worker_failure(ray_executor(), SPEC, kill_first_actor)


def test_same_campaign_under_deferred_counting(make_executor):
    """Deferred counting's result depends on the window alone, not on where or when runs
    come back (docs/window.md): on Ray and on 64 virtual workers, holds and all, the
    in-process campaign's."""
    import dataclasses

    testing.check_same_campaign(make_executor, SPEC, dataclasses.replace(testing.SETTINGS, counting="deferred"))
