"""SIGINT and SIGTERM during a campaign: stop at the next chunk boundary with a
checkpoint; a second SIGINT aborts at once (the last checkpoint stands, as after kill -9)."""

from __future__ import annotations

import signal


class stop_on_signals:
    """While inside, SIGINT / SIGTERM ask ``campaign`` (set it once it exists) to stop; a
    signal that comes before is kept and passed on when it is set."""

    def __init__(self, campaign=None):
        self._campaign = campaign
        self._asked = False

    @property
    def campaign(self):
        return self._campaign

    @campaign.setter
    def campaign(self, campaign) -> None:
        self._campaign = campaign
        if self._asked:
            campaign.stop()

    def _handle(self, signum, frame):
        if self._asked and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self._asked = True
        if self._campaign is not None:
            self._campaign.stop()

    def __enter__(self):
        self.previous = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def __exit__(self, *exc):
        for s, handler in self.previous.items():
            signal.signal(s, handler)
        return False
