"""How big a chunk is and how long it may take: from the run time and the Ray call cost
the executor measures (shared/spec/scaling.md, "Chunking and the virtual farm").

A chunk is the runs one worker simulates in one call. Its time on the worker is
``t(c) = a + b c`` for ``c`` runs: ``a`` the worker's cost per chunk (a vectorized back
end's per-step overhead, screening, Ray: ~7 ms for lead-follow on numpy here), ``b`` per
run. Its size follows them:

- every worker gets a share of every batch (``ceil(runs / workers)`` runs at most), so
  the ``pipeline_depth`` batches in flight keep each worker ``pipeline_depth`` chunks deep
  and none idles when the oldest batch is committed;
- a chunk holds at most ``CHUNK_S`` seconds of work, so that a round end (whose dropped
  chunks still run to their end on their workers) waits about that long;
- but the worker's cost per chunk stays under ``OVERHEAD_SHARE`` of the chunk's time, and
  the driver spends at most ``DRIVER_SHARE`` of its time on Ray calls with every worker
  busy (scaling.md's ``c ~ 4 W t_call / t_run``): past those, chunks grow (and fewer
  workers are busy) rather than the workers or the driver wasting most of their time.

``a`` and ``b`` are fitted (least squares) to the latest chunks' busy times, the driver's
time per chunk ``t_call`` (its call and the read of its result) smoothed likewise. The
floor that follows from them extrapolates the fit at most ``EXTRAPOLATE`` times beyond the
largest chunk measured: a fit over many one-run replacements and a few large chunks can
put ``b`` near zero by noise, and a floor of ``~ a / b`` would grow a batch to the whole
campaign; larger chunks, once measured, fit ``b`` better and let the floor grow on. The
first chunk of a campaign is a single run (the executor's probe): until chunks of
another size come back, ``t(1)`` counts as per-run cost. How a batch is cut never changes
a result: runs are committed in index order and re-screened.

The time limit of a chunk is ``LIMIT_FACTOR`` times its expected time plus
``LIMIT_FLOOR_S`` (``farm.chunk_timeout`` replaces it), counted from when its worker
starts it; before any chunk has come back nothing is measured, and a chunk may take
``FIRST_RUN_LIMIT_S`` per run: the executors' first chunk is a single run (Ray's probe,
the in-process executor's first run alone), so a simulator that hangs in its first run
is given up after that long.
"""

from __future__ import annotations

import math

import numpy as np

CHUNK_S = 1.0  # [s] of work a chunk holds at most (unless the workers or the driver cannot afford smaller)
OVERHEAD_SHARE = 0.1  # of a chunk's time on the worker's cost per chunk, at most
DRIVER_SHARE = 0.5  # of the driver's time on Ray calls, every worker busy
CALL_S = 1e-3  # [s] the driver's time per chunk until it is measured
DECAY = 0.8  # weight of the older chunks in the fitted times, per chunk
SPREAD = 0.1  # chunk sizes' coefficient of variation below which a and b are not refitted
EXTRAPOLATE = 4  # the floor's chunks hold at most this many times the largest chunk measured
LIMIT_FACTOR = 10.0  # a chunk may take this many times its expected time ...
LIMIT_FLOOR_S = 5.0  # [s] ... plus this (a loaded machine, a garbage collection)
REPLAY_FLOOR_S = 120.0  # [s] an experience replay's limit at least (a few runs): its cost per run is not a chunk's
FIRST_RUN_LIMIT_S = 60.0  # [s] per run of a chunk before any chunk has come back (and a close())
WORKERS_PER_LANE = 16  # workers per fast lane (an actor that takes only replacements)
ONE_AT_A_TIME_S = 0.2  # [s] chunks at least this long are sent to an actor one at a time


def fast_lanes(workers: int) -> int:
    """Actors that take only replacements, beside ``workers``: enough that a replacement
    never waits behind another (the head may be waiting for it); on the virtual farm,
    1,000 workers of 0.1 s runs with one lane took 21x the time of one lane per 16
    workers, which is within 5 % of replacements taken by the next free worker."""
    return max(1, math.ceil(workers / WORKERS_PER_LANE))


def close_limit(chunk_timeout: float) -> float:
    """[s] the time a simulator's close() may take: farm.chunk_timeout, else a first run's."""
    return chunk_timeout if chunk_timeout > 0 else FIRST_RUN_LIMIT_S


class ChunkSizer:
    """The measured run and call times of one executor, and what follows from them."""

    def __init__(self, workers: int, chunk_timeout: float = 0.0):
        """``chunk_timeout``: a fixed limit per chunk in seconds (farm.chunk_timeout); 0: derived."""
        self.workers = max(1, int(workers))
        self.chunk_timeout = float(chunk_timeout)
        self._fit = [0.0] * 5  # decayed sums of 1, c, c^2, t, c t over chunks
        self.chunk_cost_s: float | None = None  # a: a worker's time per chunk
        self.run_cost_s: float | None = None  # b: a worker's time per run
        self._call = self._calls = 0.0  # decayed sums: t_call = call / calls
        self._largest = 0  # runs of the largest chunk measured
        self.replay_run_s: float | None = None  # an experience replay's seconds per run, the latest measured

    # -- measurements ----------------------------------------------------------------------
    def ran(self, runs: int, busy_s: float) -> None:
        """A worker spent ``busy_s`` seconds on a chunk of ``runs`` runs."""
        if runs <= 0 or busy_s < 0:
            return
        self._largest = max(self._largest, int(runs))
        f = self._fit
        for i, v in enumerate((1.0, runs, runs * runs, busy_s, runs * busy_s)):
            f[i] = DECAY * f[i] + v
        w, wc, wcc, wt, wct = f
        mean_c, mean_t = wc / w, wt / w
        var_c = wcc / w - mean_c**2
        a, b = 0.0, mean_t / mean_c  # one size seen: all of it per run
        if var_c > (SPREAD * mean_c) ** 2:
            slope = (wct / w - mean_c * mean_t) / var_c
            if slope > 0 and mean_t - slope * mean_c >= 0:
                a, b = mean_t - slope * mean_c, slope
        elif self.chunk_cost_s is not None and mean_t > self.chunk_cost_s:
            a, b = self.chunk_cost_s, (mean_t - self.chunk_cost_s) / mean_c  # sizes alike: a kept
        self.chunk_cost_s, self.run_cost_s = a, max(b, 1e-9)

    def replayed(self, runs: int, seconds: float) -> None:
        """An experience replay took ``seconds`` for ``runs`` runs (on one worker)."""
        if runs > 0 and seconds >= 0:
            self.replay_run_s = seconds / runs

    def called(self, seconds: float) -> None:
        """The driver spent ``seconds`` on one chunk's call and result."""
        if seconds >= 0:
            self._call = DECAY * self._call + seconds
            self._calls = DECAY * self._calls + 1

    @property
    def run_s(self) -> float | None:
        """A worker's seconds per run in the latest chunks, their cost per chunk shared out
        (None until a chunk has come back)."""
        f = self._fit
        return f[3] / f[1] if f[1] else None

    @property
    def call_s(self) -> float:
        """The driver's seconds per chunk."""
        return self._call / self._calls if self._calls else CALL_S

    def expected_s(self, runs: int) -> float | None:
        """A worker's expected seconds for a chunk of ``runs`` runs."""
        if self.run_cost_s is None:
            return None
        return self.chunk_cost_s + self.run_cost_s * runs

    # -- what follows ----------------------------------------------------------------------
    def size(self, runs: int, urgent: bool = False, lanes: int = 0) -> int:
        """Runs per chunk for a batch of ``runs`` runs (1 up to ``runs``). ``urgent``
        (replacements, which the commit head may be waiting for): one wave over the
        workers, however small its chunks; or, with ``lanes`` actors that take them
        (and nothing else), one wave over the lanes, in chunks of at most ``CHUNK_S`` of
        work: more calls to a lane would only cost the driver more."""
        share = math.ceil(runs / self.workers)
        if urgent and lanes:
            wave = math.ceil(runs / lanes)
            return wave if self.run_cost_s is None else max(1, min(wave, self._by_time()))
        if urgent or runs <= 1 or self.run_cost_s is None:
            return max(1, min(runs, share))
        return min(runs, max(min(share, self._by_time()), self._floor()))

    def _by_time(self) -> int:
        return max(1, math.floor((CHUNK_S - self.chunk_cost_s) / self.run_cost_s))

    def _floor(self) -> int:
        """The smallest chunk the workers' cost per chunk and the driver's calls afford
        (within ``EXTRAPOLATE`` times the largest chunk measured)."""
        if self.run_cost_s is None:
            return 1
        a, b = self.chunk_cost_s, self.run_cost_s
        efficient = math.ceil(a * (1 - OVERHEAD_SHARE) / (OVERHEAD_SHARE * b))
        afford = math.ceil((self.workers * self.call_s / DRIVER_SHARE - a) / b)
        return max(1, min(max(efficient, afford), EXTRAPOLATE * self._largest))

    def chunks(self, runs: int, urgent: bool = False, lanes: int = 0) -> int:
        """The chunks a batch of ``runs`` runs is cut into."""
        return max(1, math.ceil(runs / self.size(runs, urgent, lanes)))

    def cut(self, runs: int, urgent: bool = False, lanes: int = 0, idle: int = 0) -> list[np.ndarray]:
        """The rows of a batch of ``runs`` runs, chunk by chunk. With ``idle`` workers that
        have nothing queued (a round's first batch: the head waits for its first chunk),
        the batch's first ``idle`` chunks hold at most ``CHUNK_S`` of work even where the
        driver's calls want longer chunks: the head starts on the round a chunk of a
        second later, not of several, and the later chunks are cut as usual."""
        rows = np.arange(runs)
        if not urgent and idle and self.run_cost_s is not None:
            first = min(self.size(runs), self._by_time())
            if first < self.size(runs):
                head = min(runs, idle * first)
                return (np.array_split(rows[:head], math.ceil(head / first))
                        + (np.array_split(rows[head:], self.chunks(runs - head)) if head < runs else []))
        return np.array_split(rows, self.chunks(runs, urgent, lanes))

    def one_at_a_time(self, runs: int) -> bool:
        """Are chunks of ``runs`` runs long enough to send an actor one at a time (the
        others wait with the driver, replacements first)? An actor then waits for its next
        chunk as long as the driver takes to see it finish, a few ms: nothing against
        ``ONE_AT_A_TIME_S``; shorter chunks are sent at once (fast lanes take replacements)."""
        expected = self.expected_s(runs)
        return expected is not None and expected >= ONE_AT_A_TIME_S

    def batch_size(self, requested: int) -> int:
        """Runs per batch that give every worker a chunk of at least the affordable size
        (at least ``requested``): with ``pipeline_depth`` batches in flight each worker
        is then that many chunks deep. Only where the batch size cannot change a result
        (sequential counting) does the driver ask."""
        return max(requested, self.workers * self._floor())

    def busy_at_most(self, batch_size: int, pipeline_depth: int) -> int:
        """Workers that ``pipeline_depth`` batches of ``batch_size`` runs can keep busy."""
        return min(self.workers, pipeline_depth * self.chunks(batch_size))

    def replay_limit(self, runs: int) -> float:
        """[s] the time a round end's experience replay of ``runs`` runs may take: it
        screens (or re-simulates) every kept state of its stored runs, which the chunks'
        fit does not predict (10x + 5 s failed one at load 16 here), so its time per run
        is the larger of a chunk's and the latest replay's, and the limit grows with the
        runs: ``LIMIT_FACTOR`` times that, plus ``LIMIT_FLOOR_S``, at least
        ``REPLAY_FLOOR_S`` (a fixed 120 s ended a 7-D campaign's replay of 118,566 runs
        with exit 4, though nothing hung)."""
        if self.chunk_timeout > 0:
            return self.chunk_timeout
        per_run = max(self.run_s or 0.0, self.replay_run_s or 0.0)
        return max(REPLAY_FLOOR_S, LIMIT_FLOOR_S + LIMIT_FACTOR * runs * per_run)

    def limit(self, runs: int) -> float:
        """[s] the time a chunk of ``runs`` runs may take once its worker has started it."""
        if self.chunk_timeout > 0:
            return self.chunk_timeout
        expected = self.expected_s(runs)
        if expected is None:
            return FIRST_RUN_LIMIT_S * max(1, runs)
        return LIMIT_FLOOR_S + LIMIT_FACTOR * expected
