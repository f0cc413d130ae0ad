"""The virtual farm: the real coordinator on a simulated clock (farm.executor = "virtual").

Runs are simulated in this process by the in-process executor, so every result, the
committed sequence included, is a real run's (results never depend on the executor).
Only time is modelled, to plan clusters of hundreds to thousands of workers for a slow
simulator (shared/spec/scaling.md):

- ``workers`` simulated workers take chunks in submission order, each as soon as one is
  free; batches are cut into chunks as the Ray executor cuts them (farm/execution/chunking.py's
  ``ChunkSizer``, fed the modelled chunk times: a one-run probe first, then sizes from
  the measured cost per run and per call);
- a run takes ``run_time * steps / (horizon - 1)`` (a run that ends early takes its
  share) times a lognormal jitter of sigma ``jitter`` (mean 1), drawn from the run's own
  key, so the timing is reproducible too;
- a chunk's call costs ``call_cost`` twice: the coordinator's (it sends and reads the
  chunk) and its worker's;
- the coordinator's own CPU time between executor calls is charged to the clock (its
  thread time, the in-process simulation excluded): a driver that cannot keep up shows
  (``charge_coordinator = False`` with ``call_cost = 0``: a free coordinator, what the
  counting rule itself allows, benchmarks/bench_virtual.py ``--free-coordinator``);
- a chunk cancelled before a worker took it never runs; experience replay's screening
  is shared by the workers;
- replacements, as on Ray: while chunks are long (farm/execution/chunking.py ``one_at_a_time``)
  a worker holds one chunk and the driver the others, so the next free worker takes a
  replacement first; short chunks are all sent at once and replacements go to fast
  lanes (one per 16 workers) as a wave over them; the lanes' time is not counted in the
  workers' utilisation.

``clock`` is the simulated time to the result; ``utilisation`` the share of worker time
spent on runs.
"""

from __future__ import annotations

import heapq
import time
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from coordinator.executor import Chunk, Executor
from farm.execution.chunking import ChunkSizer, fast_lanes
from farm.execution.local import LocalExecutor
from scenarios.simulator import SimSpec
from scenarios.streams import RunStreams

PURPOSE_TIMING = 7  # the stream purpose of a run's modelled duration (no simulation draws from it)


class VirtualClock(NamedTuple):
    """Where a virtual campaign's simulated time went (summary.json's virtual keys)."""

    elapsed_s: float  # to the result
    utilisation: float  # the workers' share of it on runs
    waiting_s: float  # the coordinator waiting for runs
    coordinator_s: float  # the coordinator's own CPU charged


@dataclass
class _Batch:
    """A submitted batch: simulated in-process at once, when a worker takes its first chunk."""

    local: int  # the in-process executor's handle
    replacements: bool = False  # the runs of mispredicted indices (submitted with their indices)
    chunk: Chunk | None = None
    waiting: int = 0  # its chunks no worker has taken yet


@dataclass
class _Job:
    batch: _Batch
    rows: tuple[int, int]  # its rows of the batch
    submitted: float
    start: float = -1.0  # when a worker took it (-1: queued)
    end: float = 0.0
    chunk: Chunk | None = None
    measured: bool = False  # its time fed to the sizer (when it came back)


class VirtualExecutor(Executor):
    name = "virtual"
    concurrent = True

    def __init__(self, spec: SimSpec, workers: int, run_time: float, jitter: float = 0.0, call_cost: float = 0.001,
                 pipeline_depth: int = 2, check_step_bound: bool = False, lanes: int | None = None):
        """``lanes``: while chunks are short, replacements go to workers of their own that
        take nothing else, as a wave over them (None: as many as the Ray executor starts,
        farm/execution/chunking.py ``fast_lanes``; 0: to the next free worker, before any queued chunk)."""
        self.spec = spec
        self.local = LocalExecutor(spec, check_step_bound)
        self.workers = workers
        self.run_time, self.jitter, self.call_cost = float(run_time), float(jitter), float(call_cost)
        self.pipeline_depth = pipeline_depth
        self.charge_coordinator = True  # the coordinator's CPU is charged to the clock (False: free)
        self.sizer = ChunkSizer(workers)
        self.clock = 0.0  # simulated seconds since the executor started
        self._runs: list[tuple[float, float]] = []  # (from, to) of each chunk's runs on its worker
        self.chunks = 0
        self.coordinator_s = 0.0  # the coordinator's CPU charged to the clock
        self.waited_s = 0.0  # the clock's time spent waiting for a chunk
        self.waited_replacements_s = 0.0  # of which for a chunk of replacements
        self._free: list[float] = [0.0] * workers  # a heap of the workers' free times
        self._queue: deque[int] = deque()  # handles no worker has taken yet, in order
        self.lanes = fast_lanes(workers) if lanes is None else int(lanes)
        self._one_at_a_time = False  # the latest batch's chunks are long (see submit)
        self._lane_free: list[float] = [0.0] * self.lanes  # a heap of the lanes' free times
        self._lane_queue: deque[int] = deque()
        self._jobs: dict[int, _Job] = {}
        self._next = 0
        self._mark = time.thread_time()  # the coordinator's CPU time charged up to here

    # -- the clock ------------------------------------------------------------------------
    def _enter(self) -> None:
        """Charge the coordinator's CPU since it last called the executor."""
        now = time.thread_time()
        if self.charge_coordinator:
            self.clock += now - self._mark
            self.coordinator_s += now - self._mark
        self._mark = now

    def _leave(self) -> None:
        self._mark = time.thread_time()  # what the executor did in-process is the workers' work

    def _dispatch(self, until: float, handle: int | None = None) -> None:
        """Workers (and lanes) take queued chunks in order: every one that starts by
        ``until``, and those up to ``handle`` whatever their start."""
        self._take(self._queue, self._free, until, handle)
        if self.lanes:
            self._take(self._lane_queue, self._lane_free, until, handle, lane=True)

    def _take(self, queue: deque, free: list[float], until: float, handle: int | None, lane: bool = False) -> None:
        target = handle if handle is not None and queue and self._jobs[handle].start < 0 and handle in queue else None
        while queue:
            key = queue[0]
            job = self._jobs[key]
            start = max(job.submitted, free[0])
            if start > until and target is None:
                break
            queue.popleft()
            job.start = start
            batch = job.batch
            if batch.chunk is None:  # one in-process call per batch, whatever its chunks
                batch.chunk = self.local.result(batch.local)
            batch.waiting -= 1
            job.chunk = batch.chunk.part(*job.rows)
            duration = self._duration(job.chunk)
            job.end = start + self.call_cost + duration
            if not lane:  # the lanes are not counted among the workers
                self._runs.append((start + self.call_cost, job.end))
            heapq.heapreplace(free, job.end)
            if key == target:
                break

    def _duration(self, chunk: Chunk) -> float:
        share = (chunk.lengths.astype(float) - 1) / max(self.spec.horizon - 1, 1)
        if self.jitter > 0:
            u = RunStreams.of(self.spec.seed, chunk.indices).uniform(0, PURPOSE_TIMING, 2)
            z = np.sqrt(-2.0 * np.log1p(-u[:, 0])) * np.cos(2 * np.pi * u[:, 1])  # Box-Muller
            share = share * np.exp(self.jitter * z - self.jitter**2 / 2)
        return float(self.run_time * share.sum())

    # -- the contract -------------------------------------------------------------------
    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None,
               indices: np.ndarray | None = None) -> list[int]:
        self._enter()
        (local,) = self.local.submit(first_index, starts, screen, actions, indices)
        batch = _Batch(local, replacements=indices is not None)
        n, at, handles = len(starts), 0, []
        if n and self.sizer.run_s is None:  # as the Ray executor: a one-run probe, waited for
            handles.append(self._cut(batch, 0, 1, indices))
            self._dispatch(self.clock, handles[0])
            self._measure(self._jobs[handles[0]])
            at = 1
        # as on Ray: while chunks are long, each worker holds one and the others wait with
        # the driver, so a replacement goes to the next free worker; short chunks are all
        # sent at once, and replacements go to the fast lanes
        lanes = 0 if self._one_at_a_time else self.lanes
        if n > at:
            idle = self._idle() if indices is None else 0
            cut = self.sizer.cut(n - at, indices is not None, lanes, idle=idle)
            if indices is None:
                self._one_at_a_time = self.sizer.one_at_a_time(max(len(rows) for rows in cut))
            for rows in cut:
                handles.append(self._cut(batch, at + int(rows[0]), at + int(rows[-1]) + 1, indices))
        if indices is None:
            self._queue.extend(handles[at:])
        elif lanes:  # replacements: to the lanes, which take nothing else
            self._lane_queue.extend(handles[at:])
        else:  # replacements: the next free worker takes them first
            self._queue.extendleft(reversed(handles[at:]))
        self._dispatch(self.clock)
        self._leave()
        return handles

    def _idle(self) -> int:
        """Workers free now with nothing queued for them."""
        if self._queue or self._free[0] > self.clock:
            return 0
        return int(np.count_nonzero(np.asarray(self._free) <= self.clock))

    def _cut(self, batch: _Batch, lo: int, hi: int, indices) -> int:
        """A chunk of rows ``lo:hi`` of ``batch`` (the caller queues it; the probe, cut
        before anything was measured, is queued here, first)."""
        self.clock += self.call_cost  # the coordinator sends it (and reads it back)
        batch.waiting += 1
        handle = self._next
        self._jobs[handle] = _Job(batch, (lo, hi), self.clock)
        if self.sizer.run_s is None:
            self._queue.appendleft(handle)
        self._next += 1
        self.chunks += 1
        return handle

    def _measure(self, job: _Job) -> None:
        """What the Ray executor measures of a chunk that came back."""
        if not job.measured:
            job.measured = True
            self.sizer.ran(job.rows[1] - job.rows[0], job.end - job.start)
            self.sizer.called(self.call_cost)
            waited = max(0.0, job.end - self.clock)
            self.waited_s += waited
            if job.batch.replacements:
                self.waited_replacements_s += waited
            self.clock = max(self.clock, job.end)

    def ready(self, handle: int) -> bool:
        self._enter()
        self._dispatch(self.clock)
        job = self._jobs[handle]
        back = 0 <= job.start and job.end <= self.clock
        self._leave()
        return back

    def result(self, handle: int) -> Chunk:
        self._enter()
        self._dispatch(self.clock, handle)
        job = self._jobs.pop(handle)
        self._measure(job)
        self._leave()
        return job.chunk

    def cancel(self, handle: int) -> None:
        self._enter()
        self._dispatch(self.clock)
        job = self._jobs.pop(handle, None)
        if job is not None and job.start < 0:  # no worker took it: it never runs
            (self._queue if handle in self._queue else self._lane_queue).remove(handle)
            job.batch.waiting -= 1
            if job.batch.waiting == 0 and job.batch.chunk is None:
                self.local.cancel(job.batch.local)
        self._leave()

    def screen_stored(self, pieces, screen):
        self._enter()
        t0 = time.thread_time()
        found = self.local.screen_stored(pieces, screen)
        self.clock += self.call_cost + (time.thread_time() - t0) / self.workers
        self._leave()
        return found

    def run_seconds(self) -> float | None:
        return self.sizer.run_s

    def batch_size(self, requested: int) -> int:
        return self.sizer.batch_size(requested)

    def close(self) -> None:
        self._jobs.clear()
        self._queue.clear()
        self.local.close()

    def report(self) -> VirtualClock:
        return VirtualClock(self.clock, self.utilisation, self.waited_s, self.coordinator_s)

    @property
    def utilisation(self) -> float:
        """The share of the workers' time up to now spent on runs."""
        if self.clock <= 0 or not self._runs:
            return 0.0
        spans = np.array(self._runs)
        busy = np.clip(np.minimum(spans[:, 1], self.clock) - spans[:, 0], 0, None).sum()
        return float(busy / (self.workers * self.clock))
