"""SIGINT, SIGTERM and SIGHUP (a closed terminal) during a campaign: the first stops it
within a fraction of a second with a checkpoint (a wait for a chunk wakes up:
farm/execution/waiting.py); a second aborts at once (the last checkpoint stands, as after
kill -9). An ignored SIGHUP (``nohup``) stays ignored: the campaign is to outlive its terminal."""

from __future__ import annotations

import signal
import threading

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


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
