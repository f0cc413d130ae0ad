"""A Ray actor killed under queued calls (farm/ray_runtime/pool.py ``ActorPool.failed``): every
chunk still comes back, whoever noticed the death first.

A failed call is "ready" to ``ray.wait``, so a poll can take it off its actor's queue as
done before its result is read; losing the actor then did not send it again, and the read
spun at full CPU (the soak test test_parallel_contract.py::test_a_killed_worker_costs_time_not_results
did, for minutes). Here the poll is made to come first: the chunks hang (tests/user_scenarios.py
``Hanging``, while its marker file exists) until one actor is killed and polled."""

import os
import signal
import threading
from pathlib import Path

import numpy as np

from farm.ray_runtime.executor import RayExecutor
from scenarios.simulator import SimSpec
from user_scenarios import HANG_MARKER

SPEC = SimSpec({"name": "user_scenarios:Hanging", "sv_policy": "idm"}, {"mode": "uniform"}, 30, 0)


def test_a_call_a_poll_took_off_its_dead_actor_is_sent_again(ray_local):
    import ray

    marker = Path(os.environ[HANG_MARKER])
    ex = RayExecutor(SPEC, 2, "local", max_retries=3, pipeline_depth=2).start()
    try:
        pids = dict(zip(map(id, ex.pool.slots), ray.get([s.handle.pid.remote() for s in ex.pool.slots])))
        ex.sizer.ran(64, 0.01)  # measured: no one-run probe first (it would hang, waited for)
        marker.touch()
        starts = np.tile([[19.5, 0.5, 68.0]], (64, 1))  # Hanging's corner: every chunk hangs
        handles = ex.submit(0, starts)
        victim = next(s for s in ex.pool.slots if s.queue)
        refs = [c.ref for c in victim.queue]
        os.kill(pids[id(victim)], signal.SIGKILL)
        ready, _ = ray.wait(refs, num_returns=len(refs), timeout=30)  # they fail: ready
        assert len(ready) == len(refs)
        for _ in refs:  # each poll takes the failed head call off the dead actor's queue, as done
            ex.pool.poll()
        assert not victim.queue and not victim.down  # nobody noticed the death
        marker.unlink()  # the chunks run to their end from now on

        chunks, error = [], []

        def read():
            try:
                chunks.extend(ex.result(h) for h in handles)
            except BaseException as exc:  # noqa: BLE001 - reported below
                error.append(exc)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        reader.join(60)
        assert not reader.is_alive(), "reading the chunks of a dead actor never ended"
        assert not error, error
        assert sum(len(c) for c in chunks) == len(starts)  # every run, once
    finally:
        marker.unlink(missing_ok=True)
        ex.close()
