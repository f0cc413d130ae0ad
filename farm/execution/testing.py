"""The conformance suite every executor passes (the contract is coordinator/executor.py;
coordinator/testing.py is the algorithms' suite): plain functions that raise
``AssertionError`` naming what broke.

    from farm.execution.testing import check_executor
    check_executor(lambda spec: MyExecutor(spec, workers=4), spec)

``make_executor(spec)`` builds a fresh executor that simulates ``spec``. The reference
for every check is the in-process executor (farm/execution/local.py): results never
depend on where runs are simulated. What each check tests:

- ``check_chunks``: a batch comes back as chunks that cover its indices in order, each
  run as the in-process executor simulates it (outcome, length, last state), screened
  as the in-process executor screens it at the same coverage.
- ``check_cancel``: a cancelled chunk is never asked for, and the executor goes on: the
  next batch comes back right.
- ``check_close``: close ends the workers; a second close is harmless.
- ``check_same_campaign``: a whole quantification campaign (experience replay and
  certification included) commits the same runs and ends in the same state as in-process.
- ``check_worker_failure`` (executors with worker processes): a worker killed mid-campaign
  costs time, not results.
"""

from __future__ import annotations

from typing import Callable

import time

import numpy as np

from coordinator.driver import Campaign, CampaignSettings
from coordinator.coverage import Coverage, Insert
from coordinator.executor import Executor
from coordinator.spe import SPE, SPESettings
from farm.execution.local import LocalExecutor
from scenarios.registry import make_backend
from scenarios.simulator import SimSpec

MakeExecutor = Callable[[SimSpec], Executor]
SETTINGS = CampaignSettings(epsilon=0.02, beta=0.2, budget=200_000, batch_size=256, pipeline_depth=2, seed=5,
                            certify=True)


def _starts(spec: SimSpec, count: int, seed: int = 4) -> np.ndarray:
    scenario = make_backend(spec.scenario).scenario
    rng = np.random.default_rng(seed)  # test data only
    return rng.uniform(scenario.lower, scenario.upper, (count, scenario.n))


def _coverage(spec: SimSpec, seed: int = 6) -> Coverage:
    scenario = make_backend(spec.scenario).scenario
    cov = Coverage(scenario.n, 2.0, scenario.lower, bounds=(scenario.lower, scenario.upper))
    cov.apply(Insert(_starts(spec, 400, seed)), 1)
    return cov


def _chunks(executor: Executor, first: int, starts: np.ndarray, screen=None) -> list:
    return [executor.result(h) for h in executor.submit(first, starts, screen)]


def _same_runs(got: list, want: list, what: str) -> None:
    firsts = [c.first_index for c in got]
    assert firsts == sorted(firsts), f"{what}: chunks not in index order"
    cat = {k: np.concatenate([getattr(c, k) for c in got]) for k in ("lengths", "outcomes", "last")}
    ref = {k: np.concatenate([getattr(c, k) for c in want]) for k in ("lengths", "outcomes", "last")}
    for key in cat:
        assert np.array_equal(cat[key], ref[key]), f"{what}: {key} differ from the in-process executor's"


def check_chunks(make_executor: MakeExecutor, spec: SimSpec, runs: int = 700) -> None:
    starts, cov = _starts(spec, runs), _coverage(spec)
    reference = LocalExecutor(spec)
    want = _chunks(reference, 1000, starts, cov)
    executor = make_executor(spec)
    try:
        got = _chunks(executor, 1000, starts, cov)
    finally:
        executor.close()
    name = type(executor).__name__
    assert got and got[0].first_index == 1000, f"{name}: the first chunk does not start at the batch's index"
    assert sum(len(c) for c in got) == runs, f"{name}: chunks do not cover the batch"
    _same_runs(got, want, name)
    events = np.concatenate([c.screening.event for c in got])
    assert np.array_equal(events, want[0].screening.event), f"{name}: screening differs from in-process"


def check_cancel(make_executor: MakeExecutor, spec: SimSpec) -> None:
    starts = _starts(spec, 600)
    executor = make_executor(spec)
    name = type(executor).__name__
    try:
        kept = executor.submit(0, starts[:200])
        for handle in executor.submit(200, starts[200:400]):
            executor.cancel(handle)
        after = executor.submit(200, starts[400:])
        got = [executor.result(h) for h in kept + after]
    finally:
        executor.close()
    reference = LocalExecutor(spec)
    want = _chunks(reference, 0, starts[:200]) + _chunks(reference, 200, starts[400:])
    _same_runs(got, want, f"{name} after a cancel")


def check_ready(make_executor: MakeExecutor, spec: SimSpec) -> None:
    """``ready(handle)`` says whether ``result(handle)`` would return without waiting for a
    worker (the driver polls it to commit on past a replacement that is not back): once
    true it stays true, and it changes nothing a chunk holds. On a real clock it becomes
    true by waiting alone; on a simulated one, once the clock passed the chunk's end (a
    later chunk's result read). Replacement batches (``indices``) answer it too. An executor
    that is not ``concurrent`` has every handle ready as soon as it is submitted."""
    starts = _starts(spec, 300)
    executor = make_executor(spec)
    name = type(executor).__name__
    simulated = hasattr(executor, "waited_s")
    try:
        handles = executor.submit(0, starts[:200])
        replacements = executor.submit(5000, starts[200:], indices=np.arange(5000, 5100, dtype=np.int64))
        # one that is not ``concurrent`` simulates when asked: every handle is ready at once
        assert executor.concurrent or all(executor.ready(h) for h in handles + replacements), \
            f"{name}: not concurrent, yet a chunk is not ready when submitted"
        if simulated:  # a chunk it calls ready is read without the clock waiting for it
            got, again, said = [], [], []
            for h in replacements + handles:
                said.append(executor.ready(h))
                waited = executor.waited_s
                (again if h in replacements else got).append(executor.result(h))
                assert not said[-1] or executor.waited_s == waited, f"{name}: a ready chunk was waited for"
            assert any(said) and not all(said), f"{name}: ready never, or always, true on a simulated clock"
        else:
            deadline = time.monotonic() + 120
            while not all(executor.ready(h) for h in handles + replacements):
                assert time.monotonic() < deadline, f"{name}: chunks never became ready"
                time.sleep(0.01)
            assert all(executor.ready(h) for h in handles + replacements), f"{name}: a ready chunk is not ready any more"
            got = [executor.result(h) for h in handles]
            again = [executor.result(h) for h in replacements]
    finally:
        executor.close()
    reference = LocalExecutor(spec)
    _same_runs(got, _chunks(reference, 0, starts[:200]), f"{name}, chunks read once ready")
    assert sum(len(c) for c in again) == 100 and set(np.concatenate([c.indices for c in again])) == \
        set(range(5000, 5100)), f"{name}: replacement chunks lost runs"


def check_close(make_executor: MakeExecutor, spec: SimSpec) -> None:
    executor = make_executor(spec)
    _chunks(executor, 0, _starts(spec, 50))
    executor.close()
    executor.close()  # harmless


def _campaign(executor: Executor, spec: SimSpec, settings: CampaignSettings, observers=()):
    scenario = make_backend(spec.scenario).scenario
    algo = SPE(scenario, SPESettings(delta0=8.0, gamma=0.5, delta_min=2.0))
    campaign = Campaign(algo, executor, settings, observers)
    try:
        campaign.run()
    finally:
        executor.close()
    return campaign


def check_same_campaign(make_executor: MakeExecutor, spec: SimSpec, settings: CampaignSettings = SETTINGS,
                        observers=()) -> Campaign:
    """-> the campaign run on ``make_executor(spec)``, after checking it against in-process."""
    want = _campaign(LocalExecutor(spec), spec, settings)
    got = _campaign(make_executor(spec), spec, settings, observers)
    name = type(got.executor).__name__
    w, g = want.counters, got.counters
    assert (g.committed, g.round_ends, g.changes, g.attempts) == (w.committed, w.round_ends, w.changes, w.attempts), \
        f"{name}: the campaign committed other runs than in-process ({g.committed} vs {w.committed})"
    a, b = got.algorithm.content(), want.algorithm.content()
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), \
        f"{name}: the campaign ended in another state than in-process"
    return got


def check_worker_failure(make_executor: MakeExecutor, spec: SimSpec, kill_a_worker: Callable[[Executor], None]) -> None:
    """``kill_a_worker(executor)`` kills one of its worker processes (once, mid-campaign)."""
    killed = []

    def kill_once(campaign: Campaign) -> None:
        if not killed and campaign.counters.committed > 0:
            kill_a_worker(campaign.executor)
            killed.append(True)

    check_same_campaign(make_executor, spec, observers=[kill_once])
    assert killed, "the campaign ended before a worker could be killed"


def check_executor(make_executor: MakeExecutor, spec: SimSpec, kill_a_worker=None) -> None:
    """Every check above (``check_worker_failure`` when ``kill_a_worker`` is given)."""
    check_chunks(make_executor, spec)
    check_cancel(make_executor, spec)
    check_ready(make_executor, spec)
    check_close(make_executor, spec)
    check_same_campaign(make_executor, spec)
    if kill_a_worker is not None:
        check_worker_failure(make_executor, spec, kill_a_worker)
