import os

import pytest


@pytest.fixture(scope="session")
def ray_local():
    """A real local Ray with two CPUs, shared by the tests that need it."""
    import ray

    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()
