"""The in-process executor's probe (its first run, simulated alone under the first-run
limit) is not simulated again with its batch: its result is joined to the rest's, bit
for bit what the whole batch simulated at once gives, and the step bound is still
checked on the whole first batch."""

import numpy as np
import pytest

from coordinator.executor import ChunkSummary
from farm.execution.local import LocalExecutor
from scenarios.errors import ScenarioError
from scenarios.simulator import Simulator, SimSpec

SPEC = SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "uniform"}, 60, 7)


def counted(executor):
    """The runs the executor's simulator is asked to simulate, call by call."""
    calls = []
    simulate = executor.simulator.simulate

    def counting(first_index, starts, **kwargs):
        calls.append(len(starts))
        return simulate(first_index, starts, **kwargs)

    executor.simulator.simulate = counting
    return calls


@pytest.mark.parametrize("replacements", [False, True])
def test_the_probe_run_is_simulated_once_and_the_chunk_is_the_whole_batch_bit_for_bit(replacements):
    sc = Simulator(SPEC).scenario
    starts = np.random.default_rng(5).uniform(sc.lower, sc.upper, (200, sc.n))
    indices = np.arange(5000, 5400, 2, dtype=np.int64) if replacements else None
    want, (want_states, want_offsets) = ChunkSummary.of(Simulator(SPEC).simulate(300, starts, indices=indices), None)
    assert len(set(want.lengths.tolist())) > 5 and len(set(want.outcomes.tolist())) > 1  # runs of many kinds

    ex = LocalExecutor(SPEC)
    calls = counted(ex)
    try:
        got = [ex.result(h) for h in ex.submit(300, starts, indices=indices)]
        assert calls == [1, 199]  # the probe, then the rest: 200 runs simulated, not 201
        again = [ex.result(h) for h in ex.submit(500, starts[:10])]
        assert calls == [1, 199, 10]  # measured now: no probe
    finally:
        ex.close()
    (chunk,) = got
    for key in ("lengths", "outcomes", "last", "exits", "margins", "indices"):
        assert np.array_equal(getattr(chunk, key), getattr(want, key)), key
    assert chunk.first_index == want.first_index and len(again[0]) == 10
    states, offsets = chunk.visited()
    assert np.array_equal(offsets, want_offsets) and np.array_equal(states, want_states)


def test_the_step_bound_is_checked_on_the_whole_first_batch_not_the_probe_alone():
    """Run 0 keeps the bound, run 3 breaks it: caught in the batch after the probe."""
    spec = SimSpec({"name": "user_scenarios:JumpsHigh"}, {"mode": "uniform"}, 5, 0)
    starts = np.full((8, 2), 0.2)
    starts[3, 0] = 0.8
    ex = LocalExecutor(spec)
    try:
        with pytest.raises(ScenarioError, match=r"step_bound\(\) = 0.1 but sample index 3 moved 0.4 along b"):
            for handle in ex.submit(0, starts):
                ex.result(handle)
    finally:
        ex.close()
    ex = LocalExecutor(spec)
    try:
        for handle in ex.submit(0, starts[:3]):  # a first batch that keeps the bound
            ex.result(handle)
        for handle in ex.submit(3, starts[3:]):  # checked in the first batch only (farm.check_step_bound)
            assert len(ex.result(handle)) == 5
    finally:
        ex.close()
