"""How far ahead of the head the next batch is drawn (sequential counting on workers).

Every run in flight is a draw that a change can move before the head commits it, and each
moved draw costs a replacement (a discarded run, a call, a pass): the replacements grow
with the runs in flight (docs/window.md). A batch is drawn ahead of the head only so that
its chunks are back by the time the head gets there; drawn earlier, it buys nothing and
costs replacements. So, where the window cannot change a result (sequential counting),
workers simulate while the head commits (a concurrent executor) and runs are fast (the
measured run time under ``FAST_RUN_S``: a batch the head must wait for is back within
milliseconds, and the driver's CPU is what bounds the farm), the next batch is drawn once
the head's runs ahead fall to a *lead*, a share of the ``(depth - 1) x batch`` runs a full
pipeline keeps ahead, and the share follows the head:

- the head waited for a worker since it reached the batch before (for a chunk of that
  batch, or for this one's first): the lead was too short, or the workers are the
  bottleneck; the share grows by ``GROW`` (up to the full pipeline, where the workers are
  never starved: the old behaviour);
- it never waited: the share shrinks by ``SHRINK`` (down to ``MIN_SHARE``), until the head
  just about meets batches as they come back.

(Whether the batch reached was back alone says too little: where the workers are the
bottleneck the head waits for the last chunk of a batch while the next one's first is
done; shrinking on it slowed SUMO campaigns on 2 workers: docs/benchmarks.md, "2026-11-30".)

Growing by steps rather than doubling: a wait for fast runs costs the head a batch's
latency once, a lead too long costs replacements on every batch. Slow runs keep the full
pipeline: there a wait costs the head a run's seconds while the workers idle (1,000 virtual
workers of 1 s runs took longer to the result with the lead: docs/benchmarks.md, "2026-11-30").

The share is a function of the workers' timing, as the window was; the committed runs
never depend on it (shared/spec/scaling.md: sequential counting at any window).
"""

from __future__ import annotations

import math

MIN_SHARE = 1 / 32  # of the full pipeline's runs ahead: at least a chunk's worth on a few workers
SHRINK = 0.9  # per batch the head reached without waiting for a worker on the way
GROW = 1 / 8  # per batch it waited for one on the way to
FAST_RUN_S = 1e-3  # [s] runs measured shorter than this (a worker's, per run) follow the lead


class Lead:
    """The runs ahead of the head below which another batch is drawn."""

    def __init__(self, adaptive: bool):
        """``adaptive``: sequential counting on a concurrent executor; otherwise the
        lead is always the full pipeline's (the window is the settings', as deferred
        counting's result needs, and an in-process executor simulates nothing ahead)."""
        self.adaptive = adaptive
        self.active = False  # the latest ``runs`` followed the share (runs fast)
        self.share = 1.0
        self._waited = False  # since the head reached the batch before

    def runs(self, batch: int, depth: int, run_s: float | None) -> float:
        """Draw another batch (up to ``depth`` ahead) while the head's runs ahead are at
        most this many; ``run_s``: a worker's seconds per run as measured (None: not yet)."""
        self.active = self.adaptive and run_s is not None and run_s < FAST_RUN_S
        return self.share * (depth - 1) * batch if self.active else math.inf

    def waited(self) -> None:
        """The head waits for a chunk that is not back."""
        self._waited = True

    def reached(self, ahead: bool) -> None:
        """The head reached a batch (its run is fetched); ``ahead``: it was drawn ahead of
        the head (not where the head stood: after a round end or at the start)."""
        if self.active and ahead:
            self.share = min(1.0, self.share + GROW) if self._waited else max(MIN_SHARE, self.share * SHRINK)
        self._waited = False
