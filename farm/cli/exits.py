"""Exit codes of ``scenario-farm``, which one an error ends with, and its one line.

The table is a public interface (scripts branch on it): README.md and
``scenario-farm --help`` show it as ``TABLE`` has it. The lines:

    scenario-farm: error: <what is wrong with the input, and what is allowed>          (2)
    scenario-farm: internal error: <type: message>; ... the traceback in <file>        (3)
    scenario-farm: infrastructure error: <what failed> (the last checkpoint stands ...) (4)
    scenario-farm: stopped ...                                                          (130)
"""

from __future__ import annotations

import errno
import os
import sys
import tempfile
import traceback

from scenarios.errors import FarmError, InfrastructureError, Stopped, UserError
from scenarios.version import __version__

OK, FINDING, USER, BUG, INFRASTRUCTURE, STOPPED = 0, 1, 2, 3, 4, 130
DEBUG = "SCENARIO_FARM_DEBUG"  # set to 1: tracebacks, and Ray's log lines on stderr

TABLE = (
    (OK, "done: certified, or the campaign finished (a used-up quantify.budget: not certified, its last lines say)"),
    (FINDING, "a finding: a counterexample (validate, replay), a refuted Gamma* (falsify)"),
    (USER, "your input: a config value, a flag, a file or directory, your scenario's code (one line names it; "
           "nothing was changed)"),
    (BUG, "our bug: one line, and the traceback in a file (SCENARIO_FARM_DEBUG=1 prints it)"),
    (INFRASTRUCTURE, "infrastructure: Ray lost or failing, a full disk (the last checkpoint stands: resume)"),
    (STOPPED, "stopped by a signal (Ctrl-C, SIGTERM, SIGHUP): checkpointed; resume continues"),
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


# -- the lines ------------------------------------------------------------------------------
def report(exc: BaseException, campaign_dir: str | None = None) -> int:
    """Print the one line ``exc`` ends a command with (its traceback too under DEBUG);
    -> the exit code. ``campaign_dir``: the directory a resume would continue."""
    if os.environ.get(DEBUG):
        traceback.print_exception(exc, file=sys.stderr)
    if isinstance(exc, Stopped):
        # a stop that names its own way on (an estimate's) keeps it
        _say(str(exc) if "continue with" in str(exc) else
             f"{exc}; checkpointed (continue with `scenario-farm resume {campaign_dir or 'DIR'}`)")
        return STOPPED
    code, text = exit_code(exc), one_line(exc)
    if code == USER:
        _say(f"error: {text}")
    elif code == INFRASTRUCTURE:
        _say(f"infrastructure error: {text}{_resume_hint(campaign_dir)}")
    else:
        fd, path = tempfile.mkstemp(prefix="scenario-farm-bug-", suffix=".txt")
        with os.fdopen(fd, "w") as fh:
            fh.write(f"scenario-farm {__version__}\n{' '.join(sys.argv)}\n\n")
            traceback.print_exception(exc, file=fh)
        _say(f"internal error: {text}; this is a bug: please report it with the traceback in {path} ({DEBUG}=1 "
             f"prints it)")
    return code


def interrupted(campaign_dir: str | None = None) -> int:
    """A signal stopped the command before a campaign's own handler could (e.g. while Ray starts)."""
    where = f" (continue with `scenario-farm resume {campaign_dir}`)" if _resumable(campaign_dir) else ""
    _say(f"stopped by a signal; the files are as the last checkpoint left them{where}")
    return STOPPED


def lost(why: str, campaign_dir: str | None = None) -> None:
    """The local Ray died under a command: our line and exit code at once, before Ray's
    core worker ends the process with its own exit code 1 and no word."""
    _say(f"infrastructure error: {why}{_resume_hint(campaign_dir)}")
    sys.stderr.flush()
    os._exit(INFRASTRUCTURE)


def one_line(exc: BaseException, limit: int = 600) -> str:
    """The error's message on one line, its type named unless it is one of ours."""
    text = " ".join(str(exc).split())
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"  # e.g. "/out/summary.json: No space left on device"
    if not isinstance(exc, FarmError):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return _fit(text, limit)


LONG_WORD = 80  # characters a shortened word (a path) keeps: its start and its end


def _fit(text: str, limit: int) -> str:
    """``text`` in ``limit`` characters: its longest words (paths) shortened in their middle
    first, so that the reason after a 4,000-character path is kept; cut at the end last."""
    words = text.split(" ")
    for i in sorted(range(len(words)), key=lambda i: -len(words[i])):
        excess = len(" ".join(words)) - limit
        if excess <= 0 or len(words[i]) <= LONG_WORD:
            break
        keep = max(LONG_WORD, len(words[i]) - excess) - 3
        words[i] = f"{words[i][: keep // 2]}...{words[i][len(words[i]) - (keep - keep // 2):]}"
    text = " ".join(words)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _resume_hint(campaign_dir: str | None) -> str:
    return f" (the last checkpoint stands: `scenario-farm resume {campaign_dir}` continues)" \
        if _resumable(campaign_dir) else ""


def _resumable(campaign_dir: str | None) -> bool:
    """Whether ``campaign_dir`` holds a campaign to resume: its frozen config.json (what
    resume reads first); a hint to resume a directory never made (an error while the
    config was read) sends the user astray."""
    return campaign_dir is not None and os.path.isfile(os.path.join(campaign_dir, "config.json"))


def _say(text: str) -> None:
    print(f"scenario-farm: {text}", file=sys.stderr)
