"""Starting or joining Ray for a campaign: a private local Ray as the CLI starts it
(loopback only, with ``RAY_SYSTEM_CONFIG``), or a cluster at an address. Benchmarks
and tests start their local Ray here too, so it has the CLI's settings.
"""

from __future__ import annotations

import logging
import os
import signal
import threading

# Return values up to this size come back inside the task's reply instead of through
# the object store (Ray's default: 100 KB). A chunk's summary is ~150 KB for 1,024
# lead-follow runs (mostly witnesses), and the store's create, seal, get and free of it
# cost the driver's Ray threads more than its bytes; the visited states (~1.1 MB a
# chunk) stay above the limit, in the worker's store, until the driver asks for them
# (docs/benchmarks.md has what it gains). A local Ray gets it here; a cluster from
# RAY_max_direct_call_object_size on every `ray start` (deploy/), read by each Ray
# process when it starts.
INLINE_RETURN_BYTES = 256 * 1024
RAY_SYSTEM_CONFIG = {"max_direct_call_object_size": INLINE_RETURN_BYTES}


def connect(address: str, workers: int) -> None:
    """Start a private local Ray (``address = "local"``) or join a cluster. Local Ray's
    workers get the working directory on their path, as the CLI has it: a config's
    'module:Class' imports there as it does in the coordinator."""
    import ray

    if ray.is_initialized():
        return
    with _keep_sigterm_handler():
        _init(ray, address, workers)
    from farm import ray_watch

    ray_watch.watch(ray)  # a lost raylet or head: our line, not Ray's exit 1


def _init(ray, address: str, workers: int) -> None:
    if address == "local":
        start_local(workers)
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False)


def start_local(num_cpus: int, extra_path: str | None = None) -> None:
    """A private local Ray as the CLI starts it (benchmarks and tests start theirs here
    too): loopback only, ``RAY_SYSTEM_CONFIG``, and ``extra_path``, the working directory
    and PYTHONPATH on the workers' import path."""
    import ray

    # the banner says token auth is on by default; it stays on, the line goes
    logging.getLogger("ray._private.authentication").setLevel(logging.ERROR)
    path = os.pathsep.join(p for p in (extra_path, os.getcwd(), os.environ.get("PYTHONPATH")) if p)
    with _loopback_only():
        ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False, configure_logging=False,
                 _node_ip_address="127.0.0.1", dashboard_host="127.0.0.1", _system_config=RAY_SYSTEM_CONFIG,
                 runtime_env={"env_vars": {"PYTHONPATH": path}})


class _keep_sigterm_handler:
    """``ray.init`` makes SIGTERM exit the driver at once (``sys.exit``); a campaign's
    handler stops at a chunk boundary with a checkpoint instead, so it is put back."""

    def __enter__(self):
        main = threading.current_thread() is threading.main_thread()
        self.previous = signal.getsignal(signal.SIGTERM) if main else None

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGTERM, self.previous)
        return False


class _loopback_only:
    """A private local Ray listens on the loopback interface only.

    ``ray.init(_node_ip_address="127.0.0.1")`` alone is not enough: Ray 2.60 maps a
    loopback node address back to the machine's routable one, unless it thinks clusters
    are off (its Windows/macOS default), and then every server binds 127.0.0.1. That
    switch is read when the node starts, so it is set for ``ray.init`` only."""

    def __enter__(self):
        from ray._private import ray_constants

        self.constants, self.before = ray_constants, ray_constants.ENABLE_RAY_CLUSTER
        ray_constants.ENABLE_RAY_CLUSTER = False

    def __exit__(self, *exc):
        self.constants.ENABLE_RAY_CLUSTER = self.before
        return False
