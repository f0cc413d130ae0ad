"""The executor conformance suite (farm/testing.py) on every executor we ship: in-process
and Ray actors on a real local Ray."""

import os
import signal

import pytest

from farm import testing
from farm.local_executor import LocalExecutor
from scenarios.simulator import SimSpec

SPEC = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 30, testing.SETTINGS.seed)


def ray_executor(workers: int = 2):
    from farm.ray_executor import RayExecutor

    return lambda spec: RayExecutor(spec, workers, "local", max_retries=3, pipeline_depth=2)


def kill_first_actor(executor) -> None:
    os.kill(executor.pids()[0], signal.SIGKILL)


@pytest.fixture(params=["local", "ray"])
def make_executor(request):
    if request.param == "local":
        return LocalExecutor
    request.getfixturevalue("ray_local")
    return ray_executor()


def test_chunks(make_executor):
    testing.check_chunks(make_executor, SPEC)


def test_cancel(make_executor):
    testing.check_cancel(make_executor, SPEC)


def test_close(make_executor):
    testing.check_close(make_executor, SPEC)


def test_same_campaign(make_executor):
    testing.check_same_campaign(make_executor, SPEC)


def test_a_killed_ray_worker_costs_time_not_results(ray_local):
    testing.check_worker_failure(ray_executor(), SPEC, kill_first_actor)
