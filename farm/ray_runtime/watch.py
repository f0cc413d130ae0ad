"""Watching what a Ray driver cannot live without: its node's raylet and the cluster's
GCS (the head node).

When either goes, Ray's core worker ends the driver with exit code 1 (the code that
means "a counterexample" here) and Ray's own lines: at once for the raylet, after 60 s
of retries for the GCS. A thread here sees it first and calls ``on_lost`` with one
line; the CLI prints it and exits with its infrastructure code (the last checkpoint
stands; ``resume`` continues). A lost worker node is not this: the executor carries on
without it (farm/ray_runtime/pool.py).

The raylet is always on the driver's machine; it is watched by its pid (Linux pidfd: no
polling), found by its socket's name. The GCS is watched by its pid when it runs here
too, else by connecting to its address every ``CHECK_S`` (``MISSES`` refusals in a row).
"""

from __future__ import annotations

import os
import select
import socket
import threading
from pathlib import Path
from typing import Callable

CHECK_S = 0.5  # [s] between probes of a GCS on another machine
MISSES = 4  # refused or timed-out probes in a row that mean the GCS is gone

# Called from the watch thread with a one-line reason (the CLI sets it); None: not watched.
on_lost: Callable[[str], None] | None = None


def watch(ray) -> None:
    """Start watching the raylet and the GCS of the Ray this process is connected to."""
    node = ray._private.worker.global_worker.node
    raylet = _pid_with(f"--raylet_socket_name={node.raylet_socket_name}")
    gcs = _pid_with(f"--session-dir={node.get_session_dir_path()}", "gcs_server")
    fds = {}
    for name, pid in (("raylet", raylet), ("GCS (the head node)", gcs)):
        if pid is not None:
            try:
                fds[os.pidfd_open(pid)] = f"this node's Ray {name} (pid {pid}) ended"
            except (AttributeError, OSError):  # not Linux >= 5.3
                pass
    probe = None if gcs is not None and len(fds) == 2 else node.gcs_address
    if not fds and probe is None:
        return
    threading.Thread(target=_wait, args=(ray, fds, probe), name="ray-watch", daemon=True).start()


def _wait(ray, fds: dict, gcs_address: str | None) -> None:
    misses = 0
    while True:
        ready, _, _ = select.select(list(fds), [], [], CHECK_S if gcs_address else None)
        if ready:
            why = fds[ready[0]]
            break
        if gcs_address is not None:
            misses = 0 if _answers(gcs_address) else misses + 1
            if misses >= MISSES:
                why = f"the Ray cluster's GCS at {gcs_address} (the head node) stopped answering"
                break
    if ray.is_initialized() and on_lost is not None:  # a shutdown disconnects first
        on_lost(f"{why} while the campaign ran")
    for fd in fds:
        os.close(fd)


def _answers(address: str) -> bool:
    host, _, port = address.rpartition(":")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=CHECK_S).close()
        return True
    except (OSError, ValueError):
        return False


def _pid_with(argument: str, program: str = "") -> int | None:
    """The pid of a process on this machine whose command line holds ``argument``."""
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            args = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if argument.encode() in args and (not program or program.encode() in args[0]):
            return int(proc.name)
    return None
