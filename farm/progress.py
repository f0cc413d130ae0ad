"""Live progress of a long campaign on a terminal (quiet when not a terminal)."""

from __future__ import annotations

import sys
import time

from farm.status import snapshot


class Progress:
    def __init__(self, enabled: bool | None = None, stream=None):
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self._last = 0.0

    def update(self, label: str, algorithm, campaign, n_eps: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < 0.5 and not campaign.counters.done:
            return
        self._last = now
        s = snapshot(algorithm, campaign, n_eps)
        line = (f"[{label}] round {s['round']}  delta {s['delta']:g}  boxes {s['boxes']}  "
                f"N_eps {s['n_eps_counter']}/{n_eps}  runs {s['runs_committed']}  "
                f"{s['runs_per_s'] or 0:,.0f} runs/s  {s['elapsed_s']:.0f}s")
        self.stream.write("\r" + line.ljust(110))
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
