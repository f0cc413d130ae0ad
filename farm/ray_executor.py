"""The Ray executor: stateless actors, each holding one scenario back end (for SUMO, one
libsumo simulation per actor process).

A batch is split into one chunk per worker so that even a pipeline depth of 1 keeps
every worker busy; chunks go to the actor with the fewest chunks queued. Results are
plain numpy arrays (compact: only the trajectory rows some run used). An actor whose
process dies is restarted by Ray and its chunk retried (bounded); an exception inside a
scenario surfaces as a one-line error naming the sample index and start state.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from farm.executors import SimSpec, build_simulator, simulate
from scenarios.run import RunBatch


class WorkerError(RuntimeError):
    pass


def _actor_class():
    import ray

    @ray.remote(num_cpus=1)
    class SimWorker:
        """Holds a scenario back end; simulates whatever batch it is sent."""

        def __init__(self, spec: dict):
            self.spec = SimSpec(**spec)
            self.scenario, self.policy = build_simulator(self.spec)
            self.busy_s = 0.0
            self.tasks = 0

        def run(self, first_index: int, starts: np.ndarray):
            t0 = time.perf_counter()
            b = simulate(self.scenario, self.policy, self.spec, first_index, starts)
            self.busy_s += time.perf_counter() - t0
            self.tasks += 1
            return b.indices, b.trajectories, b.lengths, b.outcomes

        def stats(self) -> dict:
            return {"busy_s": self.busy_s, "tasks": self.tasks, "pid": os.getpid()}

        def pid(self) -> int:
            return os.getpid()

    return SimWorker


def connect(address: str, workers: int) -> None:
    import ray

    if ray.is_initialized():
        return
    if address == "local":
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                 configure_logging=False)
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False)


class RayExecutor:
    name = "ray"

    def __init__(self, spec: SimSpec, workers: int, address: str = "local", max_retries: int = 3):
        import ray

        connect(address, workers)
        self.ray = ray
        self.spec = spec
        self.workers = workers
        self.max_retries = max_retries
        # More workers than CPUs (a test asking for 4 on a 2-core Ray) share the CPUs
        # instead of waiting forever for a free one.
        cpus = float(ray.cluster_resources().get("CPU", workers))
        per_actor = min(1.0, cpus / workers)
        cls = _actor_class().options(num_cpus=per_actor, max_restarts=max_retries, max_task_retries=max_retries)
        self.actors = [cls.remote(dataclasses.asdict(spec)) for _ in range(workers)]
        self._queued = [0] * workers
        self._jobs: dict[int, list] = {}
        self._next = 0
        self.runs_simulated = 0
        self.steps_simulated = 0

    def pids(self) -> list[int]:
        return self.ray.get([a.pid.remote() for a in self.actors])

    def worker_stats(self) -> list[dict]:
        """Busy seconds and tasks per actor (for idle-fraction measurements)."""
        return self.ray.get([a.stats.remote() for a in self.actors])

    def submit(self, first_index: int, starts: np.ndarray) -> int:
        chunks = np.array_split(np.arange(len(starts)), min(self.workers, len(starts)))
        parts = []
        for rows in chunks:
            if len(rows) == 0:
                continue
            w = int(np.argmin(self._queued))
            self._queued[w] += 1
            ref = self.actors[w].run.remote(first_index + int(rows[0]), starts[rows])
            parts.append([ref, w, first_index + int(rows[0]), starts[rows], 0])
        handle = self._next
        self._next += 1
        self._jobs[handle] = parts
        return handle

    def _get(self, part):
        ref, w, first, starts, tries = part
        while True:
            try:
                return self.ray.get(ref)
            except self.ray.exceptions.RayTaskError as exc:
                cause = exc.cause if getattr(exc, "cause", None) is not None else exc
                raise WorkerError(f"worker failed on runs from sample index {first}: {cause}") from None
            except (self.ray.exceptions.RayActorError, self.ray.exceptions.WorkerCrashedError,
                    self.ray.exceptions.ObjectLostError) as exc:
                tries += 1
                if tries > self.max_retries:
                    raise WorkerError(f"runs from sample index {first} failed {tries} times "
                                      f"(last: {type(exc).__name__}); giving up") from None
                w = (w + 1) % self.workers  # try another actor; Ray restarts the dead one
                ref = self.actors[w].run.remote(first, starts)

    def result(self, handle: int) -> RunBatch:
        parts = self._jobs.pop(handle)
        out = []
        for part in parts:
            self._queued[part[1]] -= 1
            out.append(self._get(part))
        k = max(p[1].shape[0] for p in out)
        n = out[0][1].shape[2]
        traj = np.zeros((k, sum(len(p[0]) for p in out), n))
        col = 0
        for idx, tr, _, _ in out:
            traj[: tr.shape[0], col : col + len(idx)] = tr
            col += len(idx)
        batch = RunBatch(np.concatenate([p[0] for p in out]), traj, np.concatenate([p[2] for p in out]),
                         np.concatenate([p[3] for p in out]))
        self.runs_simulated += len(batch)
        self.steps_simulated += batch.steps
        return batch

    def cancel(self, handle: int) -> None:
        for part in self._jobs.pop(handle, []):
            self._queued[part[1]] -= 1
            try:
                self.ray.cancel(part[0])
            except Exception:  # noqa: BLE001 - an actor task already running just finishes
                pass

    def close(self) -> None:
        for a in self.actors:
            self.ray.kill(a)
        self.actors = []


def make_executor(kind: str, spec: SimSpec, workers: int, address: str, max_retries: int):
    if kind == "ray":
        return RayExecutor(spec, workers, address, max_retries)
    from farm.executors import LocalExecutor

    return LocalExecutor(spec)
