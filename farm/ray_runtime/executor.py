"""The Ray executor: stateless actors, each holding one scenario back end (for SUMO, one
libsumo simulation per actor process) and a mirror of the coverage its runs are
screened against.

A batch is cut into chunks whose size follows the simulator (farm/execution/chunking.py: each
worker a share of every batch, about a second of simulation at most, no more Ray calls
than the driver can afford); the first batch begins with a one-run chunk that measures
the run time before the rest is cut. Chunks go to the actor with the fewest runs queued;
replacements (the runs the commit head waits for under sequential counting) go first to a
fast lane, one more actor that takes nothing else, so that they never wait behind the
chunks queued on a worker.
With each chunk goes what its actor's mirror lacks (farm/ray_runtime/mirror.py); the actor
is farm/ray_runtime/actor.py. A chunk returns two objects: a small per-run
summary (outcome, length, screening, the actor's busy time), which comes back to the
driver, and the visited states, which stay in the worker node's object store until the
driver asks for them (re-screening, experience replay, recordings) or drops them.

Every wait wakes for a stop and watches the chunks' time limits (farm/ray_runtime/pool.py): a
hung or lost actor is replaced and its chunks retried on the others (bounded by
``farm.max_retries``); an exception inside a scenario surfaces as a one-line error
naming the sample index and start state. The mirror is a cache, not state: an actor
that lost it asks for a snapshot.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Callable

import numpy as np

from coordinator.executor import Chunk, ChunkSummary, Executor
from coordinator.experience_replay import Stored, merged_by_source, split_found
from farm import lazy
from farm.execution.chunking import ChunkSizer, fast_lanes
from farm.ray_runtime import where
from farm.ray_runtime.actor import RESYNC, actor_class
from farm.ray_runtime.mirror import Mirrors
from farm.ray_runtime.packing import pack, unpack
from farm.ray_runtime.pool import ActorPool, Call, check_started
from farm.ray_runtime.session import connect
from farm.execution.waiting import WorkerError, culprit, name_runs
from scenarios.errors import FarmError
from scenarios.simulator import SimSpec

__all__ = ["RayExecutor", "WorkerError"]

STORED_PART = 4096  # runs per replay task when a stored piece must be re-simulated
CLOSE_GRACE_S = 2.0  # [s] an actor's time to finish its chunks at close before it is killed


@dataclasses.dataclass(eq=False)
class _Job(Call):
    """A chunk: runs ``first, first + 1, ...`` (or ``indices``) from ``starts``."""

    first: int = 0
    starts: np.ndarray | None = None
    screen: object = None
    actions: dict | None = None  # the policy's adaptive state for this chunk
    indices: np.ndarray | None = None
    visited_ref: object = None
    sent: tuple | None = None  # the coverage (id, epoch, seq) its message brings the actor to
    fresh: bool = False  # send a whole snapshot (the actor lost its mirror)
    summary: ChunkSummary | None = None


class RayExecutor(Executor):
    name = "ray"
    concurrent = True

    def __init__(self, spec: SimSpec, workers: int, address: str = "local", max_retries: int = 3,
                 check_step_bound: bool = False, pipeline_depth: int = 1, chunk_timeout: float = 0.0,
                 stop: threading.Event | None = None, notify: Callable[[str], None] | None = None,
                 fast_lane: bool = True):
        """Stores its settings; ``start`` starts or joins Ray and its actors.
        ``pipeline_depth``: batches the caller keeps in flight (farm.pipeline_depth);
        ``chunk_timeout``: seconds a chunk may take (farm.chunk_timeout; 0: derived from
        the measured run time); ``stop``: set on SIGINT / SIGTERM, it ends a wait for a
        chunk (``farm.execution.waiting.Interrupted``); ``notify``: takes a line for the user (a
        worker replaced); ``fast_lane``: actors for replacements only (one per 16 workers).
        None of them changes a result."""
        self.spec = spec
        self.workers = workers
        self.address = address
        self.max_retries = max_retries
        self.pipeline_depth = max(1, int(pipeline_depth))
        self.sizer = ChunkSizer(workers, chunk_timeout)
        self._culprit = culprit(spec.scenario)
        self._check_step_bound = check_step_bound
        self._stop, self._notify = stop, notify
        self._lanes = fast_lanes(workers) if fast_lane else 0
        self._lane = fast_lane  # started with the first replacement (many campaigns need none)
        self.ray = None
        self.pool: ActorPool | None = None
        self.startup_s = 0.0
        self.mirrors: Mirrors | None = None
        self._jobs: dict[int, _Job] = {}
        self._next = 0
        self._actions: dict | None = None  # the newest adaptive policy state submitted

    def start(self) -> "RayExecutor":
        """Start or join Ray (``address``) and start the actors; -> self."""
        ray = lazy.ray
        t0 = time.monotonic()
        connect(self.address, self.workers)
        self.ray = ray
        # More workers than CPUs (a test asking for 4 on a 2-core Ray) share the CPUs
        # instead of waiting forever for a free one.
        cpus = float(ray.cluster_resources().get("CPU", self.workers))
        per_actor = min(1.0, cpus / self.workers)
        # spread over the cluster's nodes: simulators are what the farm scales. Ray
        # restarts a dead actor (for ever: a chunk's tries are bounded instead) and
        # retries none of its calls: the pool sends them elsewhere.
        cls = actor_class().options(num_cpus=per_actor, max_restarts=-1, max_task_retries=0,
                                    scheduling_strategy="SPREAD")
        keys = [where.new_key() for _ in range(self.workers)]
        handles = [cls.remote(dataclasses.asdict(self.spec), self._check_step_bound, key) for key in keys]
        self.pool = ActorPool(ray, list(zip(handles, keys)), self.sizer.limit, self.max_retries, self._stop,
                              self._notify)
        self.mirrors = Mirrors(ray, self.pool)
        self.startup_s = time.monotonic() - t0
        return self

    def started(self, counting: str, batch_size: int, pipeline_depth: int) -> list[str]:
        lines = [f"Ray ({self.address}) up with {self.workers} workers in {self.startup_s:.1f} s"]
        busy = self.busy_at_most(batch_size)
        if counting != "sequential" and busy < self.workers:
            # deferred counting: the window is result-relevant, so said, not changed (under
            # sequential counting the batch follows the workers)
            lines.append(f"note: {batch_size} x {pipeline_depth} runs in flight (farm.batch_size x "
                         f"farm.pipeline_depth) keep at most {busy} of the {self.workers} workers busy; raise them "
                         f"for more (it costs runs: README, 'Many workers', and docs/window.md)")
        return lines

    @property
    def actors(self) -> list:
        """The workers (not the fast lane)."""
        return [s.handle for s in self.pool.slots if not s.lane]

    def _actor(self, slot: int):
        return self.pool.slots[slot].handle

    @property
    def stop(self) -> threading.Event | None:
        return self._stop

    @stop.setter
    def stop(self, event: threading.Event | None) -> None:
        self._stop = event
        if self.pool is not None:
            self.pool.stop = event

    @property
    def notify(self):
        return self._notify

    @notify.setter
    def notify(self, notify) -> None:
        self._notify = notify
        if self.pool is not None:
            self.pool.notify = notify

    @property
    def chunks_sent(self) -> int:
        """Chunks submitted so far (a retry is not another)."""
        return self._next

    def pids(self) -> list[int]:
        return self.ray.get([a.pid.remote() for a in self.actors])

    def nodes(self) -> list[str]:
        """The Ray node of each actor."""
        return self.ray.get([a.node.remote() for a in self.actors])

    def worker_stats(self) -> list[dict]:
        """Busy seconds, tasks and runs per worker (for idle-fraction measurements)."""
        return self.ray.get([a.stats.remote() for a in self.actors])

    # -- the contract -------------------------------------------------------------------
    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None,
               indices: np.ndarray | None = None) -> list[int]:
        # the policy's adaptive state goes with every chunk (a few numbers): an actor that
        # Ray restarted from its constructor needs nothing else
        self._actions = actions
        n, handles, at = len(starts), [], 0
        if n and self.sizer.run_s is None:
            # nothing measured yet: one run first, then the rest cut by its time (a
            # simulator of a second per run must not start with minutes-long chunks)
            handles.append(self._send(first_index, starts, screen, actions, indices, np.arange(1)))
            self._read(self._jobs[handles[0]])
            at = 1
        if n > at:
            urgent = indices is not None
            lanes = self._lanes if urgent else 0  # replacements go to the lanes
            idle = 0 if urgent else sum(1 for slot in self.pool.slots if not slot.queue and not slot.lane and not slot.down)
            cut = self.sizer.cut(n - at, urgent, lanes, idle)
            if not urgent:  # long chunks wait in the pool, so that a replacement waits for none of them
                self.pool.depth = 1 if self.sizer.one_at_a_time(max(len(rows) for rows in cut)) else 0
                self.pool.dispatch()
            for rows in cut:
                handles.append(self._send(first_index, starts, screen, actions, indices, rows + at))
        return handles

    def _start_lane(self) -> None:
        """The fast lanes (farm/execution/chunking.py ``fast_lanes``): under sequential counting the
        commit head may wait for a replacement, which behind a worker's queued chunks would
        wait seconds. They reserve no CPU: they are busy only with replacements, a few %
        of the runs."""
        lane = actor_class().options(num_cpus=0, max_restarts=-1, max_task_retries=0, scheduling_strategy="SPREAD")
        for _ in range(self._lanes):
            key = where.new_key()
            self.pool.add(lane.remote(dataclasses.asdict(self.spec), self._check_step_bound, key), key, lane=True)
        self._lane = False

    def _send(self, first_index, starts, screen, actions, indices, rows) -> int:
        if indices is not None and self._lane:
            self._start_lane()
        first = first_index + int(rows[0])
        picked = None if indices is None else np.asarray(indices, dtype=np.int64)[rows]
        job = _Job(len(rows), name_runs(self._culprit, first, starts[rows], picked), None, first=first, starts=starts[rows],
                   screen=screen, actions=actions, indices=picked, urgent=indices is not None)
        job.launch = lambda actor, job=job: self._launch(job, actor)
        self.pool.send(job)
        self._jobs[self._next] = job
        self._next += 1
        return self._next - 1

    def run_seconds(self) -> float | None:
        return self.sizer.run_s

    def batch_size(self, requested: int) -> int:
        return self.sizer.batch_size(requested)

    def busy_at_most(self, batch_size: int) -> int:
        """Workers that batches of ``batch_size`` runs, ``pipeline_depth`` in flight, can
        keep busy by the run time measured so far: the others are never sent a chunk."""
        return self.sizer.busy_at_most(batch_size, self.pipeline_depth)

    def _launch(self, job: _Job, actor: int) -> None:
        t0 = time.perf_counter()
        message = self.mirrors.message(actor, job.screen, job.fresh)
        job.sent = self.pool.slots[actor].synced
        job.ref, job.visited_ref = self._actor(actor).run.remote((job.first, job.starts, message, job.actions,
                                                                  job.indices))
        job.fresh = False
        job.call_s += time.perf_counter() - t0
        self.pool.sent(job, actor)

    def ready(self, handle: int) -> bool:
        job = self._jobs[handle]
        if job.summary is not None:
            return True
        self.pool.poll_now()  # chunks waiting in the pool go out as actors finish
        if job.ref is None:
            return False
        ready, _ = self.ray.wait([job.ref], timeout=0)
        return bool(ready)

    def result(self, handle: int) -> Chunk:
        job = self._jobs.pop(handle)
        summary = self._read(job)
        visited_ref = job.visited_ref
        return summary.chunk(lambda: self._visited(job), lambda rows, takes: visited_ref)

    def _visited(self, job: _Job):
        """A chunk's visited states from its node's object store, or simulated again on a
        live actor when that node is gone."""
        try:
            return self.ray.get(job.visited_ref)
        except self.ray.exceptions.ObjectLostError:
            pass
        call = Call(job.runs, f"{job.what} (simulated again: their node was lost)", None)

        def launch(actor: int) -> None:
            call.ref = self._actor(actor).revisit.remote(job.first, job.starts, job.actions, job.indices)
            self.pool.sent(call, actor)

        call.launch = launch
        self.pool.send(call, interruptible=False)
        return self._get(call, interruptible=False)  # in the middle of a commit: not stopped there

    def _get(self, call: Call, interruptible: bool = True):
        """``call``'s value once it is back: it is sent again, to another actor, while its
        actor is lost (a stop ends the wait when ``interruptible``)."""
        ray = self.ray
        while True:
            self.pool.wait(call, interruptible)
            t0 = time.perf_counter()
            try:
                value = ray.get(call.ref)
            except ray.exceptions.RayTaskError as exc:
                cause = getattr(exc, "cause", None)
                if isinstance(cause, FarmError):  # e.g. the user's scenario raised: its own one line
                    raise cause from None
                raise WorkerError(f"worker failed on {call.what}: {cause if cause is not None else exc}") from None
            except (ray.exceptions.RayActorError, ray.exceptions.WorkerCrashedError,
                    ray.exceptions.ObjectLostError) as exc:
                check_started(exc)
                self.pool.failed(call, type(exc).__name__, interruptible)
                continue
            call.call_s += time.perf_counter() - t0
            self.pool.finished(call)
            return value

    def _read(self, job: _Job) -> ChunkSummary:
        """The chunk's summary (once: it is kept), sent again where its actor was restarted
        without its mirror; the chunk sizes learn from its time."""
        while job.summary is None:
            summary = self._get(job)
            if isinstance(summary, str) and summary == RESYNC:  # restarted without its mirror
                job.fresh = True
                job.launch(job.actor)
                continue
            summary = unpack(summary)  # packed by the actor (farm/ray_runtime/packing.py)
            job.ref = None  # its bytes leave Ray's store: the arrays unpacked are copies
            slot = self.pool.slots[job.actor]
            if job.sent is not None:  # the actor's mirror has reached what was sent
                known = slot.confirmed
                if known is None or known[:2] != job.sent[:2] or known[2] < job.sent[2]:
                    slot.confirmed = job.sent
            self.sizer.ran(job.runs, summary.busy_s)
            self.sizer.called(job.call_s)
            job.summary = summary
        return job.summary

    def screen_stored(self, pieces, screen):
        """The pieces shared out among the actors by runs, one call per actor; a piece
        whose states are gone (resume) is re-simulated in shares, so that every actor
        takes a share; the pieces of one chunk go as one (``merged_by_source``)."""
        pieces, parts = merged_by_source(pieces)
        shares = []
        for piece in pieces:
            if piece.source is None and len(piece.indices) > STORED_PART:
                for lo in range(0, len(piece.indices), STORED_PART):
                    sl = slice(lo, lo + STORED_PART)
                    shares.append(Stored(None, piece.indices[sl], piece.rows[sl], piece.takes[sl], piece.parents[sl],
                                        piece.starts[sl]))
            else:
                shares.append(piece)
        # one call per actor with its share (balanced by runs), results
        # back in the shares' order
        up = [i for i, slot in enumerate(self.pool.slots) if not slot.down and not slot.lane] or [0]
        groups: list[list[int]] = [[] for _ in up]
        load = np.zeros(len(up))
        for i, share in enumerate(shares):
            g = int(np.argmin(load))
            groups[g].append(i)
            load[g] += len(share.indices)
        calls = []
        t0 = time.monotonic()
        for members in groups:
            if members:
                call = self._replay_call([shares[i] for i in members], screen)
                self.pool.send(call, interruptible=False)
                calls.append((members, call))
        found: list = [None] * len(shares)
        for members, call in calls:
            for i, piece_found in zip(members, self._read_replay(call)):
                found[i] = piece_found
        if calls:  # the actors replayed at once: the largest share took the time
            self.sizer.replayed(max(call.runs for _, call in calls), time.monotonic() - t0)
        # back to one result per piece (re-simulated pieces came in shares)
        out, at = [], 0
        for piece in pieces:
            if piece.source is None and len(piece.indices) > STORED_PART:
                k = -(-len(piece.indices) // STORED_PART)
                states = np.concatenate([found[at + i][0] for i in range(k)])
                run = np.concatenate([found[at + i][1] + i * STORED_PART for i in range(k)])
                out.append((states, run))
                at += k
            else:
                out.append(found[at])
                at += 1
        return split_found(out, parts)

    def _replay_call(self, shares: list, screen) -> Call:
        """Experience replay of ``shares`` on one actor (one call: a call costs the driver
        ~0.7 ms, and a round end has a piece per chunk that kept states)."""
        stripped = [Stored(None, p.indices, p.rows, p.takes, p.parents, p.starts) for p in shares]
        sources = [[p.source] if p.source is not None else [] for p in shares]  # nested: not resolved by Ray
        pieces = pack(stripped)  # a piece's arrays are small, and a round end has hundreds (packing.py)
        runs = sum(len(p.indices) for p in shares)
        call = Call(runs, f"{self._culprit}: experience replay of {runs} runs", None,
                    limit=self.sizer.replay_limit(runs))

        def launch(actor: int, fresh: bool = False) -> None:
            message = self.mirrors.message(actor, screen, fresh)
            call.ref = self._actor(actor).replay_screen.remote(pieces, sources, message, self._actions)
            self.pool.sent(call, actor)

        call.launch = launch
        call.relaunch_fresh = lambda: launch(call.actor, fresh=True)
        return call

    def _read_replay(self, call: Call) -> list:
        while True:
            result = self._get(call, interruptible=False)  # a round end's replay finishes before a stop
            if not isinstance(result, str):
                return unpack(result)
            call.relaunch_fresh()  # the actor was restarted without its mirror

    def cancel(self, handle: int) -> None:
        job = self._jobs.pop(handle, None)
        if job is None:
            return
        job.dropped = True  # a chunk still waiting in the pool is never sent
        if job.summary is None and job.actor >= 0:
            # its changes may never reach the actor: the next message starts from what is known
            slot = self.pool.slots[job.actor]
            slot.synced = slot.confirmed
        # The chunk is left to finish, its results unread (and freed with the refs): no
        # ray.cancel. Cancelling a queued actor task can leave a gap in the actor's
        # sequence numbers that stalls its next tasks until Ray's 30 s reorder timeout
        # (Ray issues 65785, 66020); seen once here, a round end's replay screening
        # retried after "Timed out waiting for seq_no". A running actor task is not
        # cancelled anyway, and a round end drops at most the batches in flight; its
        # time on the actor still counts towards the next chunk's limit (farm/ray_runtime/pool.py).

    def close(self) -> None:
        """End the actors. Each first finishes what it was sent (at a round's end, chunks
        that were dropped: short) and exits; one still busy after ``CLOSE_GRACE_S`` (at
        once after a stop), or down, is killed. Killing at once failed the running chunk, which Ray reports on
        the driver as "Task SimWorker.run failed ... will be retried" at the end of every
        normal campaign."""
        slots = self.pool.slots if self.pool is not None else []
        if not slots:
            return
        live = [s for s in slots if not s.down]
        ends = [s.handle.__ray_terminate__.options(max_task_retries=0).remote() for s in live]
        busy = []
        if ends:  # no grace on a stop: a hung chunk would hold it up
            grace = 0.0 if self.stop is not None and self.stop.is_set() else CLOSE_GRACE_S
            _, busy = self.ray.wait(ends, num_returns=len(ends), timeout=grace)
        for slot in slots:
            if slot.down and not slot.dead:
                self.ray.kill(slot.handle, no_restart=True)
        for slot, end in zip(live, ends):
            if end in busy:
                self.ray.kill(slot.handle, no_restart=True)
        self.pool.slots = []
