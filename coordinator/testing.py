"""The conformance suite every quantification algorithm passes (the contract is
coordinator/algorithm.py; scenarios/testing.py is the back ends' suite): plain functions
that raise ``AssertionError`` naming what broke.

    from coordinator.testing import check_algorithm
    check_algorithm(lambda: MyAlgorithm(scenario, settings, seed), make_executor)

``make`` builds a fresh algorithm in its initial state; ``make_executor`` a fresh
executor that simulates its scenario (an in-process one is enough). What the driver
relies on, and what each check tests:

- ``check_draw``: a draw gives start states that are alive centres (their vertex ids),
  inside Sigma, and depends on the streams and the state alone: drawing again from the
  same state gives the same starts, and drawing changes nothing.
- ``check_apply``: a committed run that changes the state bumps ``version`` and moves the
  coverage (``coverage.seq``): workers' mirrors follow it by its changes alone.
- ``check_rounds``: ``end_round`` decays delta until ``final_round``, then returns False;
  a single-round algorithm (``decays`` False) is final from the start.
- ``check_determinism``: two campaigns of the same settings end in the same state, array
  by array, and the same result.
- ``check_state_round_trip``: ``state()`` loaded into a fresh algorithm gives the same
  state, and a campaign continued from it ends where an uninterrupted one does.
- ``check_certification``: an algorithm that ``certifies`` ends a campaign with
  ``certify`` in its certification round (``enumerates`` for a deterministic system);
  one that does not refuses ``begin_certification`` and is never asked.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from coordinator.algorithm import Algorithm, Event
from coordinator.driver import Campaign, CampaignSettings, DriverState
from scenarios.streams import RunStreams

MakeAlgorithm = Callable[[], Algorithm]
SETTINGS = CampaignSettings(epsilon=0.02, beta=0.2, budget=60_000, batch_size=128, pipeline_depth=2, seed=5)


def _name(algo: Algorithm) -> str:
    return algo.name or type(algo).__name__


def _run(make: MakeAlgorithm, make_executor, settings: CampaignSettings = SETTINGS, algo: Algorithm | None = None):
    algo = algo if algo is not None else make()
    executor = make_executor()
    try:
        counters = Campaign(algo, executor, settings).run()
    finally:
        executor.close()
    return algo, counters


def _same_state(a: dict, b: dict, what: str) -> None:
    assert a.keys() == b.keys(), f"{what}: state arrays differ in names: {sorted(a.keys() ^ b.keys())}"
    for key in a:
        assert np.array_equal(np.asarray(a[key]), np.asarray(b[key])), f"{what}: state array {key!r} differs"


def check_draw(make: MakeAlgorithm, scenario, runs: int = 256) -> None:
    algo = make()
    name = _name(algo)
    streams = RunStreams.of(11, np.arange(1000, 1000 + runs, dtype=np.uint64))
    version, seq = algo.version, algo.coverage.seq
    draws = algo.draw(streams)
    ids = draws.ids
    starts = algo.vertices.points[ids]
    assert 0 < len(ids) <= runs and np.all(draws.versions == version), f"{name}: draw shapes or versions"
    assert np.all(algo.vertices.alive[ids]), f"{name}: a drawn vertex is not alive"
    assert np.all((starts >= scenario.lower - 1e-9) & (starts <= scenario.upper + 1e-9)), f"{name}: start outside Sigma"
    again = algo.draw(RunStreams.of(11, np.arange(1000, 1000 + runs, dtype=np.uint64)))
    assert np.array_equal(again.ids, ids), f"{name}: a draw is not reproducible"
    assert (algo.version, algo.coverage.seq) == (version, seq), f"{name}: drawing changed the state"
    assert not algo.moved(draws).any(), f"{name}: a draw moved while nothing changed"
    # each run's draw is its own: the same stream draws the same vertex in any batch
    alone = algo.draw(RunStreams.of(11, np.arange(1000 + runs - 1, 999, -1, dtype=np.uint64)[:7]))
    assert np.array_equal(alone.ids, ids[::-1][:7]), f"{name}: a run's draw depends on its batch"


def check_apply(make: MakeAlgorithm, scenario) -> None:
    algo = make()
    name = _name(algo)
    draws = algo.draw(RunStreams.of(3, np.arange(64, dtype=np.uint64)))
    ids = draws.ids
    # a failing run from the first start: every algorithm changes its state on a failure
    version, seq = algo.version, algo.coverage.seq
    algo.apply(Event(0, algo.vertices.points[ids[0]], int(ids[0]), True, np.empty((0, scenario.n))))
    assert algo.version > version, f"{name}: apply did not bump the version"
    assert algo.coverage.seq > seq, f"{name}: apply changed no coverage (mirrors could not follow)"
    # a draw the change moved is flagged: ``moved`` may over-flag, never miss
    now = algo.draw(RunStreams.of(3, np.arange(64, dtype=np.uint64)))
    changed = now.ids != ids
    assert np.all(algo.moved(draws)[changed]), f"{name}: moved missed a draw that the change moved"


def check_rounds(make: MakeAlgorithm) -> None:
    algo = make()
    name = _name(algo)
    if not algo.decays:
        assert algo.final_round, f"{name}: a single-round algorithm must be final from the start"
        assert algo.end_round() is False, f"{name}: end_round after the last round must return False"
        return
    deltas = [algo.delta]
    for _ in range(64):
        if algo.final_round:
            break
        version = algo.version
        assert algo.end_round() is True, f"{name}: end_round before the last round must return True"
        assert algo.version > version, f"{name}: end_round did not bump the version"
        assert algo.delta < deltas[-1], f"{name}: delta did not decay"
        algo.apply_replay([], [])  # nothing stored: replay adds nothing
        deltas.append(algo.delta)
    assert algo.final_round, f"{name}: never reached its last round ({deltas})"
    assert algo.end_round() is False, f"{name}: end_round after the last round must return False"


def check_determinism(make: MakeAlgorithm, make_executor, settings: CampaignSettings = SETTINGS) -> None:
    a, ca = _run(make, make_executor, settings)
    b, cb = _run(make, make_executor, settings)
    name = _name(a)
    assert ca.committed == cb.committed and ca.round_ends == cb.round_ends, f"{name}: runs differ between repeats"
    _same_state(a.state(), b.state(), f"{name}: two identical campaigns")


def check_state_round_trip(make: MakeAlgorithm, make_executor, settings: CampaignSettings = SETTINGS) -> None:
    whole, counters = _run(make, make_executor, settings)
    name = _name(whole)
    # stop half-way at a chunk boundary, as a checkpoint does, and continue in a fresh
    # algorithm from the saved arrays
    half = counters.committed // 2
    part = make()

    def stop_half_way(campaign: Campaign) -> None:
        if campaign.counters.committed >= half:
            campaign.stop()

    first = Campaign(part, make_executor(), settings, observers=[stop_half_way])
    first.run()
    first.executor.close()
    state = {k: np.array(v, copy=True) for k, v in part.state().items()}
    fresh = make()
    fresh.load_state(state)
    fresh.state_epoch = part.state_epoch
    _same_state(fresh.state(), state, f"{name}: state() loaded into a fresh algorithm")
    arrays, meta = first.state()
    rest = Campaign(fresh, make_executor(), settings, restored=DriverState.read(arrays, meta))
    rest.run()
    rest.executor.close()
    assert rest.counters.committed == counters.committed, f"{name}: a continued campaign committed other runs"
    _same_state(fresh.state(), whole.state(), f"{name}: continued vs uninterrupted campaign")


def check_certification(make: MakeAlgorithm, make_executor, settings: CampaignSettings = SETTINGS) -> None:
    algo = make()
    name = _name(algo)
    if not algo.certifies:
        try:
            algo.begin_certification()
        except NotImplementedError:
            pass
        else:
            raise AssertionError(f"{name}: certifies is False but begin_certification did not refuse")
        _, counters = _run(make, make_executor, dataclasses.replace(settings, certify=True), algo)
        assert not algo.certifying, f"{name}: a campaign asked a non-certifying algorithm to certify"
        return
    _, counters = _run(make, make_executor, dataclasses.replace(settings, certify=True), algo)
    if counters.converged:
        assert algo.certifying, f"{name}: a certified campaign ended outside its certification round"
        assert counters.attempts >= 1, f"{name}: no certification attempt was counted"
        assert algo.enumerates == algo.deterministic, f"{name}: enumerates must follow determinism while certifying"


def check_algorithm(make: MakeAlgorithm, make_executor, scenario, settings: CampaignSettings = SETTINGS) -> None:
    """Every check above."""
    check_draw(make, scenario)
    check_apply(make, scenario)
    check_rounds(make)
    check_determinism(make, make_executor, settings)
    check_state_round_trip(make, make_executor, settings)
    check_certification(make, make_executor, settings)
