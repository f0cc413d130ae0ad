"""``scenario-farm`` (also ``python -m farm``): parse the command line (farm/cli/parser.py),
then run the command's handler (farm/cli/handlers.py, a thin layer over ``farm.api``).

Every error ends as one line on stderr and an exit code (farm/cli/exits.py: the table and the
lines); ``SCENARIO_FARM_DEBUG=1`` also prints the traceback, and keeps Ray's own log lines.
This module loads in a fraction of a second: the handlers, and pydantic, scipy and the
coordinator behind them, load only once the signal handlers and error lines are in place.
"""

from __future__ import annotations

import os
import signal
import stat
import sys
import warnings
from typing import NoReturn

from farm import lazy
from farm.cli import exits
from farm.cli.native_stderr import install as quiet_native_stderr, keep_standard_fds, outlive_reader, to_devnull
from farm.cli.parser import build_parser
from farm.execution.memory import keep_freed_memory
from farm.jobs.signals import STOP_SIGNALS, catch, release_stops, stops_held
from farm.ray_runtime import watch as ray_watch
from farm.ray_runtime.session import exit_now, exit_process


def run() -> NoReturn:
    """The ``scenario-farm`` command (and ``python -m farm``): ``main`` on the command
    line's arguments, then the process ends with its exit code (farm/ray_runtime/session.py
    ``exit_process``: at once after a private local Ray, or after a stop)."""
    try:
        code = main()
    except KeyboardInterrupt:  # a signal in the instant main returned
        code = exits.STOPPED
    # the command is over: a signal now (a second one after a stop) hastens the exit, and
    # must not turn it into a death by the signal (exit 143) once the interpreter's shutdown
    # has put the default handlers back
    _exit_at_once_on_signals(code)
    exit_process(code, at_once=code == exits.STOPPED)


def main(argv=None) -> int:
    # SIGTERM and SIGHUP outside a campaign's own handler (start-up, finishing) end like
    # Ctrl-C (SIGINT: Python's KeyboardInterrupt): the files stay as the last checkpoint
    # left them, and the exit says "stopped"
    for signum in (signal.SIGTERM, signal.SIGHUP):
        catch(signum, _terminate)
    release_stops()  # SIGINT: Python's KeyboardInterrupt again (farm/cli/entry.py held it while this module loaded)
    try:
        if stops_held():  # a signal while this module loaded (farm/cli/entry.py)
            return exits.interrupted()
        return _main(argv)
    except KeyboardInterrupt:  # before a command ran
        return exits.interrupted()


def _main(argv) -> int:
    keep_standard_fds()
    outlive_reader()  # progress lines to a reader that has gone do not end the work
    parser = build_parser()
    args = parser.parse_args(argv)
    if not os.environ.get(exits.DEBUG):
        quiet_native_stderr()  # Ray's C++ log lines stay in its session's log files
    warnings.showwarning = _one_line_warning
    ray_watch.on_lost = lambda why: exits.lost(why, _campaign_dir(args))
    # like `python -m`: 'module:Class' in a config imports from the working directory
    if os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    keep_freed_memory()  # the coordinator's batch queries allocate like a simulator's steps
    try:
        return getattr(lazy.handlers, f"cmd_{args.command}")(args)
    except BrokenPipeError as exc:
        if _stdout_closed():  # the reader went away (`scenario-farm status DIR | head -1`): nothing to say
            return exits.OK
        return exits.report(exc, _campaign_dir(args))
    except Exception as exc:  # noqa: BLE001 - the one place where errors become exit codes
        return exits.report(exc, _campaign_dir(args))
    except KeyboardInterrupt:
        return exits.interrupted(_campaign_dir(args))


def _stdout_closed() -> bool:
    """Whether the broken pipe is stdout's (its reader went away); if so stdout is pointed
    at /dev/null, so that the interpreter's final flush does not fail again."""
    try:
        if not stat.S_ISFIFO(os.fstat(sys.stdout.fileno()).st_mode):
            return False
        to_devnull(sys.stdout.fileno())
        return True
    except (OSError, ValueError):
        return False


def _terminate(signum, frame):
    _exit_at_once_on_signals(exits.STOPPED)  # a second signal stops at once, still "stopped"
    raise KeyboardInterrupt


def _exit_at_once_on_signals(code: int) -> None:
    for signum in STOP_SIGNALS:
        catch(signum, lambda signum, frame: exit_now(code))


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"scenario-farm: warning: {' '.join(str(message).split())}", file=sys.stderr)


def _campaign_dir(args) -> str | None:
    """The campaign directory a command works in, for "resume DIR" hints."""
    if args.command == "quantify":
        return args.out
    return args.dir if args.command == "resume" else None
