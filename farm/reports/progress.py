"""Progress of long work, where the user looks.

- On a terminal: a live line drawn by ``rich`` (round, delta, boxes, the N_eps counter as
  a bar, runs, runs/s, elapsed), redrawn in place.
- Not a terminal (``ray job logs``, CI, a file): a plain line every ``interval`` seconds
  and at every round end, so a job log shows the campaign moving.
- ``quiet``: nothing; ``verbose``: plain lines every 2 s on a terminal too, plus round ends.
"""

from __future__ import annotations

import sys
import time

from farm import lazy
from farm.reports.status import snapshot

PLAIN_INTERVAL_S = 10.0


class Progress:
    def __init__(self, enabled: bool | None = None, stream=None, *, mode: str = "auto",
                 interval: float = PLAIN_INTERVAL_S):
        """``enabled`` False is ``mode="quiet"`` (the Python API's default); ``mode``:
        auto | quiet | verbose."""
        self.stream = stream or sys.stderr
        if enabled is False:
            mode = "quiet"
        self.mode = mode
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.live = mode == "auto" and tty
        self.interval = 2.0 if mode == "verbose" else interval
        self.enabled = mode != "quiet"
        self._last = 0.0
        self._round = None
        self._bar = None

    # -- campaigns -------------------------------------------------------------------------
    def update(self, side: str, campaign) -> None:
        if not self.enabled:
            return
        # called after every committed chunk: decide from cheap fields whether to show
        # anything before taking a snapshot (its counts are O(boxes) while certifying)
        rnd = campaign.algorithm.round
        new_round, self._round = rnd != self._round, rnd
        now = time.monotonic()
        due = now - self._last >= (0.2 if self.live else self.interval)
        if not (new_round or due or campaign.counters.done):
            return
        s = snapshot(campaign)
        if self.live:
            self._draw(side, s, campaign)
            return
        self._last = now
        prefix = "" if side == "total" else f"{side} side: "
        self.line(f"{prefix}round {s['round']}  delta {s['delta']:g}  boxes {s['boxes']:,}  {_counter(s)}  "
                  f"runs {s['runs_committed']:,}  {s['runs_per_s'] or 0:,.0f} runs/s  {s['elapsed_s']:.0f} s")

    def _draw(self, side, s, campaign) -> None:
        self._last = time.monotonic()
        if self._bar is None:
            bar = lazy.rich_progress
            self._bar = bar.Progress(bar.TextColumn("{task.description}"), bar.BarColumn(bar_width=12),
                                     bar.TextColumn("{task.fields[what]} {task.completed:,.0f}/{task.total:,.0f}"),
                                     bar.TextColumn("{task.fields[detail]}"), bar.TimeElapsedColumn(),
                                     console=lazy.rich_console.Console(file=self.stream), transient=False)
            self._bar.start()
            self._task = self._bar.add_task("", total=1, detail="", what="N_eps")
        done, total = (s["certified"], s["centres"]) if "certified" in s else (s["n_eps_counter"], s["n_eps_needed"])
        prefix = "" if side == "total" else f"{side} side: "  # no [brackets]: rich reads them as markup
        self._bar.update(self._task, description=f"{prefix}round {s['round']} delta {s['delta']:g}",
                         completed=done, total=max(total, 1), what="certified" if "certified" in s else _what(s),
                         detail=f"boxes {s['boxes']:,}  runs {s['runs_committed']:,}{_certification_runs(s)}  "
                                f"{s['runs_per_s'] or 0:,.0f}/s", refresh=True)

    # -- anything with a count ---------------------------------------------------------------
    def count(self, what: str, done: int, total: int) -> None:
        """Progress of a job of ``total`` items (validation runs, compare grid points)."""
        if not self.enabled:
            return
        now = time.monotonic()
        if done < total and now - self._last < (0.2 if self.live else self.interval):
            return
        self._last = now
        end = "\n" if done >= total or not self.live else ""
        self.stream.write(("\r" if self.live else "") + f"scenario-farm: {what} {done:,}/{total:,}" + end)
        self.stream.flush()

    def line(self, text: str) -> None:
        if self.enabled:
            self.stream.write(f"scenario-farm: {text}\n")
            self.stream.flush()

    def close(self, ending: str = "all runs done") -> None:
        """The runs are over: stop the live line, say how they ended (``ending``: e.g. a
        used-up budget) and what comes next (writing the results and figures takes seconds
        to a minute on a large set; without a line a job log would look stuck)."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
        self.line(f"{ending}; writing safe_set.parquet, summary.json and plots/")


def _counter(s: dict) -> str:
    if "certified" in s:
        return f"certified {s['certified']:,}/{s['centres']:,} centres"
    return f"{_what(s)} {s['n_eps_counter']:,}/{s['n_eps_needed']:,}" + _certification_runs(s)


def _what(s: dict) -> str:
    """What the quiet-run counter counts toward: a round's N_eps, a closing round's end, a
    check, or (margin refinement) the runs of the current wave."""
    if "splits" in s:
        return "wave"
    phase = s.get("certification_phase")
    if phase == "closing":
        return "closing"
    if phase == "check":  # with the violations it tolerated so far (quantify.certify_tolerance)
        seen = s.get("certification_check_violations", 0)
        return f"check {s['certification_attempts']}" + (f" ({seen} tolerated)" if seen else "")
    return "N_eps"


def _certification_runs(s: dict) -> str:
    return f" (certification {s['runs_certification']:,} runs)" if "runs_certification" in s else ""

