"""Replacements never queue behind a worker's chunks on Ray: the sequential commit head
may wait for them. Short chunks are all sent at once, and replacements go to fast lanes,
actors that take nothing else; long chunks are sent to an actor one at a time, the
others wait with the driver, and a replacement goes to the next actor with room before
them. Either way the result is the in-process one."""

import sys
from pathlib import Path

import pytest

from farm import config as config_mod
from farm.jobs.campaign_setup import build_algorithm, build_campaign
from farm.execution.process import build_simulator, spec_of
from farm.execution.local import LocalExecutor
from farm.ray_runtime.executor import RayExecutor
from farm.ray_runtime.pool import ActorPool, Call, Slot

RAW = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
       "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30},
       "farm": {"workers": 2, "batch_size": 128, "pipeline_depth": 3, "seed": 11}}


def campaign(make_executor, raw=RAW):
    """The result hash, the counters and the stats of the fast lanes (if any) of a campaign
    on the executor ``make_executor(spec)`` builds (RayExecutor: and its pool)."""
    import ray

    cfg = config_mod.normalize(raw)
    sim = build_simulator(spec_of(cfg))
    algo = build_algorithm(cfg, sim)
    executor = make_executor(spec_of(cfg))
    try:
        counters = build_campaign(cfg, algo, sim, executor).run()
        lanes = [s.handle for s in executor.pool.slots if s.lane] if isinstance(executor, RayExecutor) else []
        stats = ray.get([lane.stats.remote() for lane in lanes])
        if isinstance(executor, RayExecutor):
            stats.append({"held_back": executor.pool.held_back})
    finally:
        executor.close()
    return algo.result().result_hash, counters, stats


def pool_of(queued: list[int], lane_queued: int | None) -> ActorPool:
    pool = ActorPool(ray=None, handles=[], limit=lambda runs: 10.0, max_retries=1)
    pool.slots = [Slot(handle=None, runs_queued=q) for q in queued]
    if lane_queued is not None:
        pool.slots.append(Slot(handle=None, lane=True, runs_queued=lane_queued))
    return pool


def test_a_replacement_goes_to_the_lane_and_a_chunk_never_does():
    pool = pool_of([500, 300], lane_queued=0)
    assert pool.pick(urgent=True) == 2
    assert pool.pick(urgent=False) == 1  # the lane is idle, but a chunk waits for a worker
    pool = pool_of([500, 300], lane_queued=400)  # a busy lane: the least-loaded worker
    assert pool.pick(urgent=True) == 1
    pool = pool_of([0, 0], lane_queued=0)  # a tie: the lane
    assert pool.pick(urgent=True) == 2


def test_with_every_worker_down_a_chunk_may_take_the_lane():
    pool = pool_of([0, 0], lane_queued=0)
    for slot in pool.slots[:2]:
        slot.down, slot.dead = True, True
    assert pool.pick(urgent=False) == 2


def test_a_call_remembers_it_is_urgent_for_its_retries():
    assert Call(1, "a replacement", None, urgent=True).urgent and not Call(1, "a chunk", None).urgent


def test_a_ray_campaign_sends_its_replacements_to_the_lane_and_gives_the_in_process_result(ray_local):
    local_hash, _, _ = campaign(LocalExecutor)
    ray_hash, counters, (lane, pool) = campaign(lambda spec: RayExecutor(spec, 2).start())
    assert ray_hash == local_hash
    assert counters.runs_replaced > 0  # the campaign had replacements to send ...
    assert lane["tasks"] > 0  # ... and the lane ran them, and only them
    assert 0 < lane["runs"] <= counters.runs_discarded + counters.runs_replaced


sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # the driver's slow back end too
SLOW = {**RAW, "scenario": {"name": "lead-follow", "sv_policy": "idm", "backend": "slow_backend:SlowBackend",
                            "slow_backend:SlowBackend": {"step_cost_s": 1.5e-4}}}  # a 30-state run: ~4.4 ms


def test_long_chunks_wait_with_the_driver_and_replacements_go_first(ray_local):
    """Chunks of ~0.28 s (64 runs of ~4.4 ms): one at a time per actor, the rest wait in the
    pool; the result is still the in-process one (the slow back end simulates the same
    runs as the numpy one: tests/benchmarks/test_slow_backend.py)."""
    local_hash, local_counters, _ = campaign(LocalExecutor)
    ray_hash, counters, (*lanes, pool) = campaign(lambda spec: RayExecutor(spec, 2).start(), SLOW)
    assert ray_hash == local_hash and counters.committed == local_counters.committed
    assert pool["held_back"] > 0  # chunks waited in the pool for an actor with room
    assert counters.runs_replaced > 0


SLOW_20MS = {**RAW, "farm": {**RAW["farm"], "workers": 8},
             "scenario": {"name": "lead-follow", "sv_policy": "idm", "backend": "slow_backend:SlowBackend",
                          "slow_backend:SlowBackend": {"step_cost_s": 7e-4}}}  # a 30-state run: ~20 ms


def _on_eight_slow_actors():
    """The campaign of ``SLOW_20MS`` on 8 Ray actors: (its driver, counters, result hash),
    and the in-process run's (result hash, counters)."""
    cfg = config_mod.normalize(SLOW_20MS)
    sim = build_simulator(spec_of(cfg))
    algo = build_algorithm(cfg, sim)
    executor = RayExecutor(spec_of(cfg), 8).start()
    try:
        ray_campaign = build_campaign(cfg, algo, sim, executor)
        counters = ray_campaign.run()
    finally:
        executor.close()
    local_hash, local_counters, _ = campaign(LocalExecutor)
    return (ray_campaign, counters, algo.result().result_hash), (local_hash, local_counters)


@pytest.mark.soak  # CI: the same contract on the virtual farm (tests/farm/test_virtual.py)
def test_runs_launched_while_a_change_waits_on_ray_give_the_in_process_result(ray_local):
    """8 actors of ~20 ms runs: the head passes replacements not back and waits for them at
    changes; meanwhile the runs each change will call for are launched, worked out on a
    copy of the algorithm (coordinator/driver/campaign.py ``LookAhead.past_holds``), and their
    chunks read ahead without waiting. The result is the in-process one."""
    (ray_campaign, counters, ray_hash), (local_hash, local_counters) = _on_eight_slow_actors()
    assert ray_campaign.look_ahead.launched_past_holds > 0
    assert ray_hash == local_hash and counters.committed == local_counters.committed


@pytest.mark.soak  # CI: the same contract on the virtual farm (tests/farm/test_virtual.py)
def test_changes_applied_past_holds_on_ray_give_the_in_process_result(ray_local, monkeypatch):
    """The same 8 actors, with changes applied past the holds before them (for runs of
    20 ms here; by default from 0.2 s, coordinator/driver/speculation.py): a change undone sends
    the actors the restored coverage whole, and the result is the in-process one."""
    import coordinator.driver.speculation as speculation_mod

    monkeypatch.setattr(speculation_mod, "RUN_S", 0.005)
    (ray_campaign, counters, ray_hash), (local_hash, local_counters) = _on_eight_slow_actors()
    assert ray_campaign.speculations.applied > 0
    assert ray_hash == local_hash and counters.committed == local_counters.committed
