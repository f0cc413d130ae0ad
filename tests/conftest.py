import os

import pytest


@pytest.fixture(scope="session")
def ray_local():
    """A real local Ray with two CPUs, shared by the tests that need it."""
    import ray

    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    # workers import user scenarios defined under tests/, like a user's own package
    from farm.ray_session import start_local

    start_local(2, os.path.dirname(os.path.abspath(__file__)))
    yield ray
    ray.shutdown()
