"""Which Ray cluster ``farm.address`` names, and whether it answers.

Ray waits for an address that answers nothing for ever, retrying (and rewrites a
loopback host to this machine's routable address first); ``auto`` also joins any raylet
it finds among the machine's processes. Here an address is resolved and probed with a
bounded wait, so that a wrong one is a one-line ConfigError within seconds, before
anything is written.
"""

from __future__ import annotations

import os
import socket

from farm import lazy
from scenarios.errors import ConfigError

PROBE_TIMEOUT_S = 3.0  # [s] for a cluster's address to accept a TCP connection


def reachable(address: str, timeout: float = PROBE_TIMEOUT_S) -> str:
    """The address to give ``ray.init`` for ``farm.address`` (``auto`` resolved), checked
    to accept a TCP connection within ``timeout`` seconds; else a one-line ConfigError."""
    target = _resolve(address)
    client = target.startswith("ray://")
    host, port = _host_port(target.removeprefix("ray://"), address)
    if not client:  # Ray connects to this host's routable address for a loopback one: probe that
        host, port = _host_port(lazy.ray_services.canonicalize_bootstrap_address(target), address)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__).lower()
        said = f"{address!r}" + (f" ({target})" if target != address else "")
        raise ConfigError(f"farm.address: nothing answers at {host}:{port} for {said}: {why} within {timeout:g} s; "
                          f"start the cluster first, or use --address local") from None
    return target


def _resolve(address: str) -> str:
    """``auto``: the cluster of a Ray job (RAY_ADDRESS) or of `ray start` on this machine
    (Ray's address file). Not Ray's own fallback, any raylet process found on the
    machine: on a shared machine that is another user's private Ray."""
    if address != "auto":
        return address
    found = os.environ.get("RAY_ADDRESS") or lazy.ray_utils.read_ray_address()
    if not found:
        raise ConfigError("farm.address: 'auto' found no Ray cluster (no RAY_ADDRESS, and no `ray start` on this "
                          "machine); start one, give its address, or use --address local")
    return found


def _host_port(text: str, address: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"farm.address: {address!r} is not 'local', 'auto', 'host:port' or 'ray://host:port'")
    return host.strip("[]"), int(port)
