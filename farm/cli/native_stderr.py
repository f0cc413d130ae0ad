"""The CLI's stderr without Ray's C++ log lines.

Ray's core worker in the driver writes its ERROR lines straight to file descriptor 2
("[2026-11-25 08:25:51,080 E 24710 25156] task_manager.cc:1545: ..."): dozens of them
when a raylet dies, around the one line of ours that says what happened. They are also
in the driver's log file of the Ray session, so on the terminal they go. ``install``
points fd 2 at a pipe whose lines, those aside, a thread passes on to the real stderr;
Python's own ``sys.stderr`` writes to the real stderr directly, so no line of ours
waits on the thread. ``SCENARIO_FARM_DEBUG=1`` keeps everything.
"""

from __future__ import annotations

import atexit
import os
import re
import sys
import threading

RAY_LOG_LINE = re.compile(rb"^\[\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} [DIWEF] \d+ \d+\] ")
_installed = False


def keep_standard_fds() -> None:
    """Standard streams that were closed (``2>&-``, as some service managers start a
    process) become /dev/null: what is written to them is dropped. Else
    ``sys.stderr`` is None, and fd 2 goes to the next file opened (a lock, a ledger
    segment), where Ray's and our lines would be written."""
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
            if getattr(sys, name) is None:
                setattr(sys, name, open(fd, mode, closefd=False))
            continue
        if getattr(sys, name) is None:  # closed at start-up, and the fd since taken by a file: not ours to write
            setattr(sys, name, open(os.devnull, mode))


def install() -> None:
    """From now on, fd 2 drops Ray's log lines (POSIX; once per process)."""
    global _installed
    if _installed or os.name != "posix":
        return
    _installed = True
    sys.stderr.flush()
    real = os.dup(2)
    read, write = os.pipe()
    os.dup2(write, 2)  # what a child or C++ writes to fd 2 now goes through the filter
    os.close(write)
    sys.stderr = open(real, "w", buffering=1, encoding=sys.stderr.encoding, errors="backslashreplace",
                      closefd=False)
    threading.Thread(target=_pump, args=(read, real), name="native-stderr", daemon=True).start()
    # at exit (after Ray's own shutdown, registered later, has run) fd 2 is the real one
    # again: nothing written then can wait on a pipe nobody reads
    atexit.register(os.dup2, real, 2)


def _pump(read: int, real: int) -> None:
    pending = b""
    while chunk := os.read(read, 65536):
        pending += chunk
        *lines, pending = pending.split(b"\n")
        _write_all(real, b"".join(line + b"\n" for line in lines if not RAY_LOG_LINE.match(line)))
    if not RAY_LOG_LINE.match(pending):
        _write_all(real, pending)


def _write_all(fd: int, data: bytes) -> None:
    while data:
        data = data[os.write(fd, data):]
