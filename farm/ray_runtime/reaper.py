"""Ends a private local Ray's processes when its driver is gone, kill -9 included.

Ray ties the processes it starts itself (GCS, raylet, ...) to the driver with
PR_SET_PDEATHSIG, but not what the raylet starts: its dashboard and runtime-env agents
noticed the raylet's death and still lived on for a minute (they report it to the GCS,
which is gone too, and wait for the RPC to time out). Run as a script by
``farm.ray_runtime.session`` (standard library only, ``python -I``):

    python -I reaper.py [--session SESSION_NAME] RAYLET_PID [PID ...]

    python -I reaper.py --starting DRIVER_PID

guards ``ray.init`` itself (a kill -9 there left the agents running): it learns the
driver's descendants every ``START_SCAN_S`` and the sessions their command lines name,
until the driver writes a byte (Ray is up and the reaper above watches it: it exits) or
its stdin ends (the driver is gone: it kills them, as below).

It learns the raylet's descendants every ``SCAN_S`` seconds, and when its stdin (a pipe
the driver holds) reaches end of file or the raylet is gone, it kills those of them that
are still the same processes (pid and start time), and every process whose command line
names the session (``--session-name=SESSION_NAME``: a worker the raylet forked after the
last scan, orphaned when the raylet went with the driver), and exits. Linux only (/proc).
"""

from __future__ import annotations

import os
import select
import signal
import sys

SCAN_S = 1.0
START_SCAN_S = 0.1  # [s] while Ray starts: its processes come and go within a second


def start_time(pid: int) -> str | None:
    """The process's start time in clock ticks (field 22 of /proc/PID/stat), or None if gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def children(pid: int) -> list[int]:
    found = []
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as fh:
                found += [int(p) for p in fh.read().split()]
    except OSError:
        pass
    return found


def learn(raylet: int, known: dict[int, str]) -> None:
    stack = [raylet]
    while stack:
        for child in children(stack.pop()):
            if child not in known and (started := start_time(child)) is not None:
                known[child] = started
            stack.append(child)


def of_session(session: str) -> dict[int, str]:
    """Processes whose command line names Ray session ``session``, with their start times."""
    found, mark = {}, f"--session-name={session}".encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as fh:
                words = fh.read().split(b"\0")
        except OSError:
            continue
        if mark in words and (started := start_time(int(entry))) is not None:
            found[int(entry)] = started
    return found


def session_of(pid: int) -> str | None:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as fh:
            words = fh.read().split(b"\0")
    except OSError:
        return None
    for word in words:
        if word.startswith(b"--session-name="):
            return word.split(b"=", 1)[1].decode(errors="replace")
    return None


def guard_start(driver: int) -> None:
    """While the driver starts Ray: its descendants and their sessions, killed if the driver dies."""
    known: dict[int, str] = {}
    sessions: set[str] = set()
    while True:
        learn(driver, known)
        sessions.update(s for pid in known if (s := session_of(pid)))
        ready, _, _ = select.select([sys.stdin], [], [], START_SCAN_S)
        if ready:
            if os.read(sys.stdin.fileno(), 4096):
                return  # Ray is up, and watched by a reaper of its own
            break  # the driver is gone
    for session in sessions:
        known.update(of_session(session))
    known.pop(os.getpid(), None)
    kill(known)


def kill(known: dict[int, str]) -> None:
    for pid, started in known.items():
        if start_time(pid) == started:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass


def main(argv: list[str]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C is for the driver
    if argv[:1] == ["--starting"]:
        guard_start(int(argv[1]))
        return
    session = ""
    if argv[:1] == ["--session"]:
        session, argv = argv[1], argv[2:]
    raylet = int(argv[0])
    known = {pid: started for pid in map(int, argv) if (started := start_time(pid)) is not None}
    if raylet not in known:
        return
    while start_time(raylet) == known[raylet]:
        learn(raylet, known)
        ready, _, _ = select.select([sys.stdin], [], [], SCAN_S)
        if ready and not os.read(sys.stdin.fileno(), 4096):
            break  # the driver is gone
    learn(raylet, known)
    if session:
        known.update(of_session(session))
    kill(known)


if __name__ == "__main__":
    main(sys.argv[1:])
