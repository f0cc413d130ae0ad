"""SIGINT, SIGTERM and SIGHUP (a closed terminal) during a campaign: the first stops it
within a fraction of a second with a checkpoint (a wait for a chunk wakes up:
farm/execution/waiting.py); a second aborts at once (the last checkpoint stands, as after
kill -9). An ignored SIGHUP (``nohup``) stays ignored: the campaign is to outlive its terminal."""

from __future__ import annotations

import signal
import threading

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


_HELD: list[int] = []  # stop signals that came while the command started
_BEFORE_HOLD: dict[int, object] = {}  # the handlers ``hold_stops`` replaced


def hold_stops() -> None:
    """From a command's first line on: a stop signal is kept for the command to take once its
    own handlers are in place (``stops_held``), rather than ending the process by the default
    action (SIGTERM, SIGHUP: a death by the signal, exit 143) or breaking an import half-way
    (SIGINT's KeyboardInterrupt) while the modules behind it load (numpy: up to a second).
    An ignored signal (SIGINT in a background job, SIGHUP under nohup) stays ignored."""
    for signum in STOP_SIGNALS:
        if signal.getsignal(signum) != signal.SIG_IGN:
            _BEFORE_HOLD[signum] = signal.signal(signum, _hold)


def release_stops() -> None:
    """The handlers from before ``hold_stops`` back, where none was set since (SIGINT's
    KeyboardInterrupt); what came meanwhile stays in ``stops_held``."""
    for signum, handler in _BEFORE_HOLD.items():
        if signal.getsignal(signum) is _hold:
            signal.signal(signum, handler)
    _BEFORE_HOLD.clear()


def _hold(signum, frame):
    _HELD.append(signum)


def stops_held() -> bool:
    """Whether a stop signal came while ``hold_stops`` held them."""
    return bool(_HELD)


def catch(signum: int, handler):
    """Set ``handler`` for ``signum`` unless it is an ignored SIGHUP (nohup); -> the handler before."""
    if signum == signal.SIGHUP and signal.getsignal(signum) == signal.SIG_IGN:
        return signal.SIG_IGN
    return signal.signal(signum, handler)


class stop_on_signals:
    """While inside, SIGINT / SIGTERM / SIGHUP ask ``campaign`` (set it once it exists) to stop and
    set ``event`` (the executor's waits end on it); a signal that comes before is kept and
    passed on when the campaign is set. A second signal raises KeyboardInterrupt."""

    def __init__(self, campaign=None):
        self._campaign = campaign
        self._asked = False
        self.event = threading.Event()

    @property
    def campaign(self):
        return self._campaign

    @campaign.setter
    def campaign(self, campaign) -> None:
        self._campaign = campaign
        if self._asked:
            campaign.stop()

    def _handle(self, signum, frame):
        if self._asked:
            raise KeyboardInterrupt
        self._asked = True
        self.event.set()
        if self._campaign is not None:
            self._campaign.stop()

    def __enter__(self):
        self.previous = {s: catch(s, self._handle) for s in STOP_SIGNALS}
        return self

    def __exit__(self, *exc):
        for s, handler in self.previous.items():
            signal.signal(s, handler)
        return False
