"""The Ray actor of the executor: holds a scenario back end (for SUMO, one libsumo
simulation per actor process) and a mirror of the coverage its runs are screened
against (farm/ray_runtime/executor.py sends what the mirror lacks); simulates and screens
whatever chunk it is sent. The class is made when first asked for: Ray is imported only
when the Ray executor is chosen."""

from __future__ import annotations

import os
import time

import numpy as np

from coordinator.coverage import Coverage
from coordinator.executor import ChunkSummary, screen_piece
from farm import lazy
from farm.execution.process import build_simulator
from farm.ray_runtime import where
from farm.ray_runtime.packing import pack, unpack
from scenarios.simulator import SimSpec

RESYNC = "resync"  # a worker's answer when its mirror cannot reach the chunk's version


def actor_class():
    """The actor class (a function: ``ray.remote`` needs Ray imported)."""
    ray = lazy.ray

    @ray.remote(num_cpus=1)
    class SimWorker:
        """Holds a scenario back end and a coverage mirror; simulates and screens
        whatever chunk it is sent."""

        def __init__(self, spec: dict, check_step_bound: bool, where_key: str):
            """``where_key``: the name the driver gave this actor, under which it says where
            a per-run back end hangs (farm/ray_runtime/where.py)."""
            self.simulator = build_simulator(SimSpec(**spec), check_step_bound)
            where.watch(self.simulator.backend, where_key)
            self.mirror: Coverage | None = None
            self.static = (None, None)
            self.busy_s = 0.0
            self.tasks = 0
            self.runs = 0

        @ray.method(num_returns=2)
        def run(self, chunk: tuple):
            """``chunk`` = (first_index, starts, message, actions, indices), one argument:
            Ray serializes each argument of a call on its own, and a chunk's five cost the
            driver ~40 % more CPU per call than one tuple (docs/benchmarks.md). Returns the
            summary packed (farm/ray_runtime/packing.py) and the visited states."""
            first_index, starts, message, actions, indices = chunk
            t0 = time.perf_counter()
            screen = self._screen(message)
            if screen is RESYNC:
                return RESYNC, None
            batch = self.simulator.simulate(first_index, starts, indices=indices, actions=actions)
            summary, visited = ChunkSummary.of(batch, screen)
            busy = time.perf_counter() - t0
            summary.busy_s = busy
            self.busy_s += busy
            self.tasks += 1
            self.runs += len(starts)
            return pack(summary), visited

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
            for block in payload:  # inline blocks come packed (farm/ray_runtime/packing.py)
                self.mirror.sync(ray.get(block) if isinstance(block, ray.ObjectRef) else unpack(block))
            return self.mirror

        def revisit(self, first_index: int, starts: np.ndarray, actions=None, indices=None):
            """A chunk's visited states again (they were lost with their node): a run
            depends on its key, start and the policy's state only."""
            return self.simulator.simulate(first_index, starts, indices=indices, actions=actions).visited()

        def replay_screen(self, pieces, source_refs, message, actions=None):
            """Experience replay on stored pieces (packed): each one's new states under the
            coverage, packed. All of an actor's pieces come in one call: a call costs the
            driver ~0.7 ms, and a round end has a piece per chunk that kept states."""
            if actions is not None:  # a re-simulation needs the policy the runs had
                self.simulator.policy.load(actions)
            screen = self._screen(message)
            if screen is RESYNC:
                return RESYNC
            found = []
            for piece, refs in zip(unpack(pieces), source_refs):
                source = None
                if refs:
                    try:
                        source = ray.get(refs[0])
                    except ray.exceptions.ObjectLostError:  # its worker died: re-simulate from the keys
                        source = None
                found.append(screen_piece(self.simulator, source, piece, screen))
            return pack(found)

        def stats(self) -> dict:
            return {"busy_s": self.busy_s, "tasks": self.tasks, "runs": self.runs, "pid": os.getpid()}

        def pid(self) -> int:
            return os.getpid()

        def node(self) -> str:
            return ray.get_runtime_context().get_node_id()

    return SimWorker
