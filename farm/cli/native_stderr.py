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
            to_devnull(fd)
            if getattr(sys, name) is None:
                setattr(sys, name, open(fd, mode, closefd=False))
            continue
        if getattr(sys, name) is None:  # closed at start-up, and the fd since taken by a file: not ours to write
            setattr(sys, name, open(os.devnull, mode))


class OutlivingReader:
    """``sys.stderr`` that outlives its reader: when the pipe's reader has gone (``quantify
    ... 2>&1 | head``, a ``tee`` killed), what is written is dropped, as with ``2>&-``, and
    the work goes on. (A BrokenPipeError out of a progress line ended a campaign at its
    first line, before it had run anything, with exit 0.) The exit code still says how
    the command ended."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._to_null()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._to_null()

    def _to_null(self) -> None:
        """The stream's file descriptor is /dev/null from now on (its buffer is written there)."""
        try:
            fd = self._stream.fileno()
        except (OSError, ValueError):  # no descriptor of its own: a stream of nothing
            self._stream = open(os.devnull, "w")
            return
        to_devnull(fd)
        try:
            self._stream.flush()
        except OSError:
            self._stream = open(os.devnull, "w")

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def outlive_reader() -> None:
    """From now on, a stderr whose reader has gone drops what is written to it."""
    if not isinstance(sys.stderr, OutlivingReader):
        sys.stderr = OutlivingReader(sys.stderr)


def to_devnull(fd: int) -> None:
    """File descriptor ``fd`` (open or closed) is /dev/null from now on: what is written
    to it is dropped."""
    null = os.open(os.devnull, os.O_RDWR)
    if null != fd:  # (a closed fd is the lowest free one: the open may have taken it)
        os.dup2(null, fd)
        os.close(null)


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
    sys.stderr = OutlivingReader(open(real, "w", buffering=1, encoding=sys.stderr.encoding,
                                      errors="backslashreplace", closefd=False))
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
        try:
            data = data[os.write(fd, data):]
        except BrokenPipeError:  # the reader has gone: dropped from now on (``OutlivingReader``)
            to_devnull(fd)
