"""How a chunk travels: its summary back inside the task's reply, its visited states
left in the worker's object store until the driver asks for them (issue 11, point 2)."""

import subprocess
import sys
import textwrap


def test_a_local_ray_returns_chunk_summaries_inline_and_keeps_visited_states_in_the_store(tmp_path):
    """A fresh process, so that ``connect("local")`` starts the Ray it describes (the
    tests' shared Ray is started by conftest). A return value is inline when Ray knows
    no node that holds it (within 3 s: a stored object's location is reported late at
    times)."""
    script = textwrap.dedent("""
        import time

        import numpy as np
        import ray
        from farm.ray_runtime import executor as ray_executor
        from farm.ray_runtime import session as ray_session
        from scenarios.simulator import SimSpec

        ray_session.connect("local", 1)
        limit = ray_session.INLINE_RETURN_BYTES

        @ray.remote
        def payload(n):
            return np.zeros(n, np.uint8)

        def inline(ref):
            # a stored object's location can reach its owner a moment after its value
            ray.get(ref)
            for _ in range(30):
                if ray.experimental.get_object_locations([ref])[ref]["node_ids"]:
                    return False
                time.sleep(0.1)
            return True

        # Ray's own default (100 KB) would put the first in the store
        print("sized", inline(payload.remote(limit - 4096)), inline(payload.remote(2 * limit)))
        spec = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 50, 0)
        ex = ray_executor.RayExecutor(spec, 1).start()
        ex.sizer.ran(1024, 0.01)  # as if measured: the batch is one chunk, no one-run probe first
        (handle,) = ex.submit(0, np.tile([10.0, 10.0, 40.0], (1024, 1)))
        part = ex._jobs[handle]
        summary_ref = part.ref  # released once read: its bytes are unpacked into copies
        chunk = ex.result(handle)
        states, offsets = chunk.visited()
        print("chunk", len(chunk), inline(summary_ref), inline(part.visited_ref), states.nbytes > limit,
              part.ref is None)
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines() if line.startswith(("sized", "chunk")))
    assert lines["sized"] == "True False", out.stdout + out.stderr[-3000:]
    assert lines["chunk"] == "1024 True False True True", out.stdout + out.stderr[-3000:]


def test_packed_summaries_and_change_blocks_give_what_the_simulator_and_screen_give_in_process(ray_local):
    """A chunk's summary comes back packed in one buffer, and the coverage's small change
    blocks go packed (farm/ray_runtime/packing.py): after a snapshot and then a change
    block (a kill and a failure), the chunk the driver reads is, array for array, what
    simulating and screening the same runs in this process gives."""
    import dataclasses

    import numpy as np

    from coordinator.coverage import AddFailures, Coverage, Insert, Kill
    from coordinator.executor import ChunkSummary
    from farm.ray_runtime.executor import RayExecutor
    from scenarios.simulator import Simulator, SimSpec

    spec = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 50, 3)
    sc = Simulator(spec).scenario
    rng = np.random.default_rng(1)
    coverage = Coverage(sc.n, 2.0, sc.lower, bounds=(sc.lower, sc.upper))
    coverage.apply(Insert(rng.uniform(sc.lower, sc.upper, (400, sc.n))), 1)
    starts = rng.uniform(sc.lower, sc.upper, (64, sc.n))
    ex = RayExecutor(spec, 1, fast_lane=False).start()
    messages = []
    message_of = ex.mirrors.message
    ex.mirrors.message = lambda *args, **kwargs: messages.append(message_of(*args, **kwargs)) or messages[-1]
    try:
        ex.sizer.ran(64, 0.01)  # as if measured: one chunk, no one-run probe first
        for version, change in ((2, None), (3, Kill(np.arange(0, 400, 3))), (4, AddFailures(starts[:2]))):
            if change is not None:
                coverage.apply(change, version)
            (handle,) = ex.submit(100 * version, starts, coverage)
            job = ex._jobs[handle]
            got = ex.result(handle)
            want, _ = ChunkSummary.of(Simulator(spec).simulate(100 * version, starts), coverage)
            for name in ("lengths", "outcomes", "last", "indices", "margins"):
                assert np.array_equal(getattr(got, name), getattr(want, name)), (version, name)
            for field in dataclasses.fields(want.screening):
                a, b = getattr(got.screening, field.name), getattr(want.screening, field.name)
                assert np.array_equal(a, b), (version, field.name)
            assert job.sent[2] == coverage.seq  # the actor's mirror reached the coverage
        assert [m[0] for m in messages] == ["snapshot", "changes", "changes"]
        assert all(isinstance(block, bytes) for m in messages[1:] for block in m[1])  # packed, inline
    finally:
        ex.close()
