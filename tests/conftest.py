import os

import pytest


@pytest.fixture(scope="session")
def ray_local():
    """A real local Ray with two CPUs, shared by the tests that need it."""
    import ray

    os.environ.setdefault("RAY_DEDUP_LOGS", "0")
    # workers import user scenarios defined under tests/, like a user's own package
    tests_dir = os.path.dirname(os.path.abspath(__file__))
    path = os.pathsep.join(p for p in (tests_dir, os.environ.get("PYTHONPATH")) if p)
    from farm.ray_executor import RAY_SYSTEM_CONFIG

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": path}}, _system_config=RAY_SYSTEM_CONFIG)
    yield ray
    ray.shutdown()
