import os

import pytest


@pytest.fixture(scope="session")
def ray_local(tmp_path_factory):
    """A real local Ray with two CPUs, shared by the tests that need it. Its workers see
    FARM_TEST_HANG (tests/user_scenarios.py: Hanging hangs while that file exists)."""
    import ray

    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    os.environ.setdefault("FARM_TEST_HANG", str(tmp_path_factory.mktemp("hang") / "marker"))
    # workers import user scenarios defined under tests/, like a user's own package, and
    # the benchmarks' slow back ends
    from farm.ray_runtime.session import start_local

    here = os.path.dirname(os.path.abspath(__file__))
    start_local(2, os.pathsep.join([here, os.path.join(os.path.dirname(here), "benchmarks")]))
    yield ray
    ray.shutdown()
