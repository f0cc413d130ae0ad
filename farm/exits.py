"""Exit codes of ``scenario-farm``, and which one an error ends with.

The table is a public interface (scripts branch on it): README.md and
``scenario-farm --help`` show it as ``TABLE`` has it.
"""

from __future__ import annotations

import errno
import sys

from scenarios.errors import FarmError, InfrastructureError, UserError

OK, FINDING, USER, BUG, INFRASTRUCTURE, STOPPED = 0, 1, 2, 3, 4, 130

TABLE = (
    (OK, "done: certified, or the campaign finished"),
    (FINDING, "a finding: a counterexample (validate, replay), a refuted Gamma* (falsify)"),
    (USER, "your input: a config value, a flag, a file or directory, your scenario's code (one line names it; "
           "nothing was changed)"),
    (BUG, "our bug: one line, and the traceback in a file (SCENARIO_FARM_DEBUG=1 prints it)"),
    (INFRASTRUCTURE, "infrastructure: Ray lost or failing, a full disk (the last checkpoint stands: resume)"),
    (STOPPED, "stopped by a signal (Ctrl-C, SIGTERM): checkpointed; resume continues"),
)

# a full or failing disk is the machine's, not the input's: resume once there is room
DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def table_text() -> str:
    """The exit-code table as plain lines (``--help``)."""
    return "\n".join(f"  {code:>3}  {text}" for code, text in TABLE)


def exit_code(exc: BaseException) -> int:
    """USER, INFRASTRUCTURE or BUG for an error that ended a command."""
    if isinstance(exc, UserError):
        return USER
    if isinstance(exc, (InfrastructureError, MemoryError)):
        return INFRASTRUCTURE
    if isinstance(exc, OSError) and exc.errno is not None:
        # a path that is missing, not writable, not a directory ...: named in the message
        return INFRASTRUCTURE if exc.errno in DISK_ERRNOS else USER
    ray_error = _ray_error(exc)
    if ray_error is not None:
        return ray_error
    return BUG


def _ray_error(exc: BaseException) -> int | None:
    """A Ray error that escaped the executor: a task's own error is judged by its cause;
    any other (an actor or node lost, the GCS gone) is the infrastructure's."""
    ray = sys.modules.get("ray")
    exceptions = getattr(ray, "exceptions", None)
    if exceptions is None or not isinstance(exc, exceptions.RayError):
        return None
    if isinstance(exc, exceptions.RayTaskError):
        cause = getattr(exc, "cause", None)
        return exit_code(cause) if isinstance(cause, FarmError) else BUG
    return INFRASTRUCTURE
