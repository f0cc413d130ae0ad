"""Starting or joining Ray for a campaign: a private local Ray as the CLI starts it
(loopback only, with ``RAY_SYSTEM_CONFIG``, its processes ended with the driver's), or a
cluster at an address, checked to answer before anything is written. Benchmarks and
tests start their local Ray here too, so it has the CLI's settings.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import NoReturn

from farm import lazy
from farm.ray_runtime import watch as ray_watch
from farm.ray_runtime.address import reachable
from scenarios.errors import ConfigError, InfrastructureError

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
    'module:Class' imports there as it does in the coordinator. A SIGTERM while Ray
    starts is a KeyboardInterrupt (the CLI: "stopped", exit 130)."""
    ray = lazy.ray
    if ray.is_initialized():
        return
    # The executor reports a failed chunk once, as one line; the refs of chunks it drops
    # (a round's end, a failure) hold the same error, which Ray would print on the
    # driver as "Unhandled error" with the worker's traceback when they are freed.
    os.environ.setdefault("RAY_IGNORE_UNHANDLED_ERRORS", "1")
    target = None if address == "local" else reachable(address)
    try:
        with _keep_sigterm_handler():
            if target is None:
                start_local(workers)
            else:
                ray.init(address=target, log_to_driver=False, configure_logging=False)
    except SystemExit as exc:
        # ray.init makes SIGTERM exit the driver at once (sys.exit) until it returns
        if exc.code != signal.SIGTERM:
            raise
        ray.shutdown()
        raise KeyboardInterrupt from None
    except (ConfigError, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - whatever Ray raises while starting or joining
        ray.shutdown()
        text = " ".join(str(exc).split())
        if target is None:
            raise InfrastructureError(f"Ray did not start on this machine ({type(exc).__name__}: {text})") from None
        raise ConfigError(f"farm.address: {address!r} answers at {target}, but joining it as a Ray cluster failed "
                          f"({type(exc).__name__}: {text})") from None
    ray_watch.watch(ray)  # a lost raylet or head: our line, not Ray's exit 1


def start_local(num_cpus: int, extra_path: str | None = None) -> None:
    """A private local Ray as the CLI starts it (benchmarks and tests start theirs here
    too): loopback only, ``RAY_SYSTEM_CONFIG``, and ``extra_path``, the working directory
    and PYTHONPATH on the workers' import path."""
    ray = lazy.ray
    # the banner says token auth is on by default; it stays on, the line goes
    logging.getLogger("ray._private.authentication").setLevel(logging.ERROR)
    guard = _reaper("--starting", str(os.getpid()))  # a kill -9 inside ray.init: its agents end too
    try:
        with _loopback_only(), _workers_path(extra_path):
            # address "local": a new Ray here; without it ray.init joins RAY_ADDRESS or the
            # latest `ray start` of this machine (a stale export, a parent that ran ray.init)
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, log_to_driver=False,
                     configure_logging=False, _node_ip_address="127.0.0.1", dashboard_host="127.0.0.1",
                     _system_config=RAY_SYSTEM_CONFIG)
        _start_reaper(ray)
    finally:
        if guard is not None:  # Ray is up and watched (or did not start): the guard steps down
            try:
                guard.stdin.write(b"up")
                guard.stdin.close()
            except OSError:
                pass


_reapers: list[subprocess.Popen] = []  # their stdin pipes stay open as long as this process


def exit_process(code: int, *, at_once: bool = False) -> NoReturn:
    """End this process with ``code``: at once when ``at_once`` (a command a signal
    stopped: nothing is left to do, and a second signal must find no interpreter shutdown
    under way, whose default handlers make it a death by that signal), or when a private
    local Ray runs here and its reaper watches it (its processes then end as after kill -9
    of the driver), sparing ``ray.shutdown``'s stop of each process in turn, which waits
    up to a second for each to exit; else as usual (``sys.exit``). Everything a command
    writes is in its files when it returns; what is still buffered on stdout and stderr
    is flushed."""
    ray = sys.modules.get("ray")  # not imported: no Ray here
    connected = ray is not None and ray.is_initialized()
    reaped = connected and any(r.poll() is None for r in _reapers)
    if at_once and connected and not reaped:
        ray.shutdown()  # a cluster's connection closed, a local Ray no reaper watches stopped
    if at_once or reaped:
        exit_now(code)
    sys.exit(code)


def exit_now(code: int) -> NoReturn:
    """End this process with ``code`` at once, stdout and stderr flushed (no atexit, no
    interpreter shutdown)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nobody reads it any more
            pass
    os._exit(code)


def _start_reaper(ray) -> None:
    """farm/ray_runtime/reaper.py: ends what this Ray started when this process ends, kill -9 included."""
    node = ray._private.worker._global_node
    pids = {name: [p.process.pid for p in procs] for name, procs in getattr(node, "all_processes", {}).items()}
    if not sys.platform.startswith("linux") or not pids.get("raylet"):
        return
    others = [pid for name, group in pids.items() if name != "raylet" for pid in group]
    session = ["--session", node.session_name] if getattr(node, "session_name", "") else []
    _reapers[:] = [r for r in _reapers if r.poll() is None]  # those of an earlier Ray here have ended
    _reapers.append(_reaper(*session, str(pids["raylet"][0]), *map(str, others)))


def _reaper(*args: str) -> subprocess.Popen | None:
    """farm/ray_runtime/reaper.py with ``args``, its stdin a pipe this process holds (Linux only)."""
    if not sys.platform.startswith("linux"):
        return None
    return subprocess.Popen([sys.executable, "-I", str(Path(__file__).with_name("reaper.py")), *args],
                            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


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
        ray_constants = lazy.ray_constants
        self.constants, self.before = ray_constants, ray_constants.ENABLE_RAY_CLUSTER
        ray_constants.ENABLE_RAY_CLUSTER = False

    def __exit__(self, *exc):
        self.constants.ENABLE_RAY_CLUSTER = self.before
        return False


class _workers_path:
    """The workers' import path (``extra_path``, the working directory, PYTHONPATH) as the
    PYTHONPATH of the environment the raylet starts with: it and every worker it starts
    inherit it. Not a runtime_env, which made each actor wait for Ray's runtime-env agent
    (docs/benchmarks.md has what that cost). The driver's own environment is put back
    after ``ray.init`` (its later subprocesses)."""

    def __init__(self, extra_path: str | None):
        self.extra_path = extra_path

    def __enter__(self):
        self.kept = os.environ.get("PYTHONPATH")
        os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (self.extra_path, os.getcwd(), self.kept) if p)

    def __exit__(self, *exc):
        if self.kept is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = self.kept
        return False
