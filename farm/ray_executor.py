"""The Ray executor: stateless actors, each holding one scenario back end (for SUMO, one
libsumo simulation per actor process) and a mirror of the coverage its runs are
screened against.

A batch is cut into workers / pipeline_depth chunks (of MIN_CHUNK runs at least), so
that the batches in flight keep every worker busy; chunks go to the actor with the fewest
chunks queued. With each chunk goes what its actor's mirror lacks: the coverage changes
since the version the actor was last sent (small blocks inside the call, large ones put
in the object store once and shared by every actor that needs the same range), or a whole
snapshot for a new or restarted actor. A chunk returns two objects: a small per-run
summary (outcome, length, screening), which comes back to the driver, and the visited
states, which stay in the worker node's object store until the driver
asks for them (re-screening, experience replay, recordings) or drops them.

An actor whose process dies is restarted by Ray and its chunk retried on another actor
(bounded); an exception inside a scenario surfaces as a one-line error naming the
sample index and start state. The mirror is a cache, not state: an actor that lost it
asks for a snapshot.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from coordinator.coverage import Coverage, Reset
from coordinator.executor import Chunk, Executor, chunk_of, screen_piece, summarize
from farm.simulators import build_simulator
from farm.ray_session import connect
from scenarios.errors import FarmError, InfrastructureError
from scenarios.simulator import SimSpec

RESYNC = "resync"  # a worker's answer when its mirror cannot reach the chunk's version
STORED_PART = 4096  # runs per replay task when a stored piece must be re-simulated


MIN_CHUNK = 256  # runs: the smallest chunk a batch is cut into for a worker
INLINE_BYTES = 1 << 16  # change blocks up to this size travel inside the task call
CLOSE_GRACE_S = 2.0  # [s] an actor's time to finish its chunks at close before it is killed


def chunks_per_batch(workers: int, pipeline_depth: int, batch_size: int) -> int:
    """The chunks a batch of ``batch_size`` runs is cut into for ``workers`` workers.

    ``pipeline_depth`` batches are in flight: workers / depth chunks per batch keep every
    worker busy with the fewest Ray calls (2 workers at depth 2: one chunk per batch).
    None under MIN_CHUNK runs: a smaller chunk costs the driver a Ray call (~1-2 ms) for
    little simulation, and a worker its per-step overhead for few runs; more workers are
    kept busy by more runs in flight (farm.batch_size x farm.pipeline_depth), not by
    thinner chunks."""
    return min(-(-workers // pipeline_depth), max(1, batch_size // MIN_CHUNK))


def busy_at_most(workers: int, pipeline_depth: int, batch_size: int) -> int:
    """Workers that batches of ``batch_size`` runs, ``pipeline_depth`` in flight, can keep
    busy (docs/window.md: what raising them costs)."""
    return min(workers, pipeline_depth * chunks_per_batch(workers, pipeline_depth, batch_size))


def _nbytes(changes) -> int:
    """Array bytes of logged coverage changes (a whole-coverage Reset counts as large)."""
    total = 0
    for _, _, change in changes:
        if isinstance(change, Reset):
            return INLINE_BYTES + 1
        total += sum(v.nbytes for v in vars(change).values() if isinstance(v, np.ndarray))
    return total


class WorkerError(InfrastructureError):
    """Ray lost the workers of a chunk more often than ``farm.max_retries`` allows."""


def _actor_class():
    import ray

    @ray.remote(num_cpus=1)
    class SimWorker:
        """Holds a scenario back end and a coverage mirror; simulates and screens
        whatever chunk it is sent."""

        def __init__(self, spec: dict, check_step_bound: bool):
            self.simulator = build_simulator(SimSpec(**spec), check_step_bound)
            self.mirror: Coverage | None = None
            self.static = (None, None)
            self.busy_s = 0.0
            self.tasks = 0

        @ray.method(num_returns=2)
        def run(self, first_index: int, starts: np.ndarray, message, actions=None):
            t0 = time.perf_counter()
            screen = self._screen(message)
            if screen is RESYNC:
                return RESYNC, None
            batch = self.simulator.simulate(first_index, starts, actions=actions)
            summary, visited = summarize(batch, screen)
            self.busy_s += time.perf_counter() - t0
            self.tasks += 1
            return summary, visited

        def _screen(self, message):
            kind, payload, base = message
            if kind == "none":
                return None
            if kind == "static":  # fetched once per screen
                if self.static[0] != payload.hex():
                    self.static = (payload.hex(), ray.get(payload))
                return self.static[1]
            if kind == "snapshot":  # a whole coverage, as plain arrays
                self.mirror = Coverage.from_state(ray.get(payload))
                return self.mirror
            # "changes": change blocks (inline, or refs) holding every change after number ``base``
            # (a mirror ahead of base skips what it has: the chunk that took it there was
            # dropped by the coordinator, which then sends from what it knows was applied)
            if self.mirror is None or self.mirror.seq < base:
                return RESYNC
            for block in payload:
                self.mirror.sync(ray.get(block) if isinstance(block, ray.ObjectRef) else block)
            return self.mirror

        def replay_screen(self, pieces, source_refs, message, actions=None):
            """Experience replay on stored pieces: each one's new states under the
            coverage. All of an actor's pieces come in one call: a call costs the
            driver ~0.7 ms, and a round end has a piece per chunk that kept states."""
            if actions is not None:  # a re-simulation needs the policy the runs had
                self.simulator.policy.load(actions)
            screen = self._screen(message)
            if screen is RESYNC:
                return RESYNC
            found = []
            for piece, refs in zip(pieces, source_refs):
                source = None
                if refs:
                    try:
                        source = ray.get(refs[0])
                    except ray.exceptions.ObjectLostError:  # its worker died: re-simulate from the keys
                        source = None
                found.append(screen_piece(self.simulator, source, piece, screen))
            return found

        def stats(self) -> dict:
            return {"busy_s": self.busy_s, "tasks": self.tasks, "pid": os.getpid()}

        def pid(self) -> int:
            return os.getpid()

        def node(self) -> str:
            return ray.get_runtime_context().get_node_id()

    return SimWorker


@dataclasses.dataclass
class _InFlight:
    """A chunk sent to an actor and not yet read back."""

    ref: object  # the summary's object ref
    visited_ref: object
    actor: int
    first: int
    starts: np.ndarray
    screen: object
    actions: dict | None = None  # the policy's adaptive state for this chunk
    sent: tuple | None = None  # the coverage (id, epoch, seq) its message brings the actor to
    tries: int = 0


class RayExecutor(Executor):
    name = "ray"

    def __init__(self, spec: SimSpec, workers: int, address: str = "local", max_retries: int = 3,
                 check_step_bound: bool = False, pipeline_depth: int = 1):
        """``pipeline_depth``: batches the caller keeps in flight (farm.pipeline_depth);
        it decides only how batches are cut into chunks, never a result."""
        import ray

        connect(address, workers)
        self.ray = ray
        self.spec = spec
        self.workers = workers
        self.max_retries = max_retries
        self.pipeline_depth = max(1, int(pipeline_depth))
        # More workers than CPUs (a test asking for 4 on a 2-core Ray) share the CPUs
        # instead of waiting forever for a free one.
        cpus = float(ray.cluster_resources().get("CPU", workers))
        per_actor = min(1.0, cpus / workers)
        # spread over the cluster's nodes: simulators are what the farm scales
        cls = _actor_class().options(num_cpus=per_actor, max_restarts=max_retries, max_task_retries=max_retries,
                                     scheduling_strategy="SPREAD")
        self.actors = [cls.remote(dataclasses.asdict(spec), check_step_bound) for _ in range(workers)]
        self._queued = [0] * workers
        self._synced: list[tuple[int, int, int] | None] = [None] * workers  # (coverage id, epoch, seq) sent
        self._confirmed: list[tuple[int, int, int] | None] = [None] * workers  # ... known applied
        self._blocks: dict[tuple, object] = {}  # (coverage id, from seq, to seq) -> ref
        self._static: dict[int, object] = {}  # id(screen) -> ref of a fixed screen
        self._snapshot: tuple = (None, None)  # (coverage id, epoch, seq), ref of its state
        self._jobs: dict[int, _InFlight] = {}
        self._next = 0
        self._actions: dict | None = None  # the newest adaptive policy state submitted

    def pids(self) -> list[int]:
        return self.ray.get([a.pid.remote() for a in self.actors])

    def nodes(self) -> list[str]:
        """The Ray node of each actor."""
        return self.ray.get([a.node.remote() for a in self.actors])

    def worker_stats(self) -> list[dict]:
        """Busy seconds and tasks per actor (for idle-fraction measurements)."""
        return self.ray.get([a.stats.remote() for a in self.actors])

    # -- what a chunk's actor needs to screen it ------------------------------------------
    def _message(self, actor: int, screen, fresh: bool = False):
        if screen is None:
            return ("none", None, 0)
        if not isinstance(screen, Coverage):
            key = id(screen)
            if key not in self._static:
                self._static = {key: self.ray.put(screen)}
            return ("static", self._static[key], 0)
        screen.start_log()
        now = (id(screen), screen.epoch, screen.seq)
        sent = self._synced[actor]
        self._synced[actor] = now
        if fresh or sent is None or sent[:2] != now[:2]:
            if self._snapshot[0] != now:
                self._snapshot = (now, self.ray.put(screen.state()))
            return ("snapshot", self._snapshot[1], 0)
        if sent[2] == now[2]:
            return ("changes", [], sent[2])
        key = (id(screen), sent[2], now[2])
        if key not in self._blocks:
            self._blocks = {k: v for k, v in self._blocks.items() if k[2] == now[2]}  # older ranges are done
            changes = screen.changes_since(sent[2])
            # a small block goes inside the call (Ray inlines it; a put costs the driver
            # ~1 ms), a large one once into the object store for every actor that needs it
            self._blocks[key] = changes if _nbytes(changes) <= INLINE_BYTES else self.ray.put(changes)
        self._trim(screen)
        return ("changes", [self._blocks[key]], sent[2])

    def _trim(self, screen: Coverage) -> None:
        """Forget the changes every actor that was sent this coverage has applied. An
        actor never sent it gets a snapshot, not changes, so it holds nothing back: with
        fewer chunks in flight than workers (8 at the defaults) the actors past the
        eighth are never used, and waiting for them kept every change of the campaign."""
        now = (id(screen), screen.epoch)
        holding = [c for s, c in zip(self._synced, self._confirmed) if s is not None and s[:2] == now]
        if holding and all(c is not None and c[:2] == now for c in holding):
            screen.trim_log(min(c[2] for c in holding))

    # -- the contract -------------------------------------------------------------------
    def submit(self, first_index: int, starts: np.ndarray, screen=None, actions: dict | None = None) -> list[int]:
        # the policy's adaptive state goes with every chunk (a few numbers): an actor that
        # Ray restarted from its constructor needs nothing else
        self._actions = actions
        handles = []
        for rows in np.array_split(np.arange(len(starts)), self.chunks_per_batch(len(starts))):
            if len(rows) == 0:
                continue
            actor = int(np.argmin(self._queued))
            first = first_index + int(rows[0])
            job = _InFlight(None, None, actor, first, starts[rows], screen, actions)
            self._launch(job)
            self._jobs[self._next] = job
            handles.append(self._next)
            self._next += 1
        return handles

    def chunks_per_batch(self, batch_size: int) -> int:
        """The chunks a batch of ``batch_size`` runs is cut into (``submit``)."""
        return chunks_per_batch(self.workers, self.pipeline_depth, batch_size)

    def busy_at_most(self, batch_size: int) -> int:
        """Workers that batches of ``batch_size`` runs, ``pipeline_depth`` in flight, can
        keep busy: the others are never sent a chunk."""
        return busy_at_most(self.workers, self.pipeline_depth, batch_size)

    def _launch(self, job: _InFlight, fresh: bool = False) -> None:
        self._queued[job.actor] += 1
        message = self._message(job.actor, job.screen, fresh)
        job.sent = self._synced[job.actor]
        job.ref, job.visited_ref = self.actors[job.actor].run.remote(job.first, job.starts, message, job.actions)

    def result(self, handle: int) -> Chunk:
        job = self._jobs.pop(handle)
        while True:
            summary = self._get(job)
            if not (isinstance(summary, str) and summary == RESYNC):
                break
            self._launch(job, fresh=True)  # the actor lost its mirror (restarted)
        visited_ref = job.visited_ref
        return chunk_of(summary, lambda: self.ray.get(visited_ref), lambda rows, takes: visited_ref)

    def screen_stored(self, pieces, screen):
        """The pieces shared out among the actors by runs, one call per actor; a piece
        whose states are gone (resume) is re-simulated in shares, so that every actor
        takes a share."""
        from coordinator.experience_replay import Stored

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
        groups: list[list[int]] = [[] for _ in self.actors]
        load = np.zeros(len(self.actors))
        for i, share in enumerate(shares):
            actor = int(np.argmin(load))
            groups[actor].append(i)
            load[actor] += len(share.indices)
        calls = []
        for actor, members in enumerate(groups):
            if members:
                self._queued[actor] += 1
                calls.append((actor, members, self._replay_call(actor, [shares[i] for i in members], screen)))
        found: list = [None] * len(shares)
        for actor, members, ref in calls:
            result = self.ray.get(ref)
            while isinstance(result, str):  # the actor was restarted without its mirror
                result = self.ray.get(self._replay_call(actor, [shares[i] for i in members], screen, fresh=True))
            self._queued[actor] -= 1
            for i, piece_found in zip(members, result):
                found[i] = piece_found
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
        return out

    def _replay_call(self, actor: int, shares: list, screen, fresh: bool = False):
        from coordinator.experience_replay import Stored

        stripped = [Stored(None, p.indices, p.rows, p.takes, p.parents, p.starts) for p in shares]
        sources = [[p.source] if p.source is not None else [] for p in shares]  # nested: not resolved by Ray
        return self.actors[actor].replay_screen.remote(stripped, sources, self._message(actor, screen, fresh),
                                                       self._actions)

    def _get(self, job: _InFlight):
        ray = self.ray
        while True:
            try:
                summary = ray.get(job.ref)
                self._queued[job.actor] -= 1
                if job.sent is not None:  # the actor's mirror has reached what was sent
                    known = self._confirmed[job.actor]
                    if known is None or known[:2] != job.sent[:2] or known[2] < job.sent[2]:
                        self._confirmed[job.actor] = job.sent
                return summary
            except ray.exceptions.RayTaskError as exc:
                self._queued[job.actor] -= 1
                cause = getattr(exc, "cause", None)
                if isinstance(cause, FarmError):  # e.g. the user's scenario raised: its own one line
                    raise cause from None
                raise  # a bug in the worker's code: the traceback shows where
            except (ray.exceptions.RayActorError, ray.exceptions.WorkerCrashedError,
                    ray.exceptions.ObjectLostError) as exc:
                self._queued[job.actor] -= 1
                job.tries += 1
                if job.tries > self.max_retries:
                    raise WorkerError(f"runs from sample index {job.first} failed {job.tries} times "
                                      f"(last: {type(exc).__name__}); giving up") from None
                self._synced[job.actor] = None  # Ray restarts it without its mirror
                job.actor = (job.actor + 1) % self.workers  # try another actor meanwhile
                self._launch(job, fresh=True)

    def cancel(self, handle: int) -> None:
        job = self._jobs.pop(handle, None)
        if job is None:
            return
        self._queued[job.actor] -= 1
        # its changes may never reach the actor: the next message starts from what is known
        self._synced[job.actor] = self._confirmed[job.actor]
        # The chunk is left to finish, its results unread (and freed with the refs): no
        # ray.cancel. Cancelling a queued actor task can leave a gap in the actor's
        # sequence numbers that stalls its next tasks until Ray's 30 s reorder timeout
        # (Ray issues 65785, 66020); seen once here, a round end's replay screening
        # retried after "Timed out waiting for seq_no". A running actor task is not
        # cancelled anyway, and a round end drops at most the batches in flight.

    def close(self) -> None:
        """End the actors. Each first finishes what it was sent (at a round's end, chunks
        that were dropped: short) and exits; one still busy after ``CLOSE_GRACE_S`` is
        killed. Killing at once failed the running chunk, which Ray reports on the
        driver as "Task SimWorker.run failed ... will be retried" at the end of every
        normal campaign."""
        if not self.actors:
            return
        ends = [a.__ray_terminate__.options(max_task_retries=0).remote() for a in self.actors]
        _, busy = self.ray.wait(ends, num_returns=len(ends), timeout=CLOSE_GRACE_S)
        for actor, end in zip(self.actors, ends):
            if end in busy:
                self.ray.kill(actor)
        self.actors = []

