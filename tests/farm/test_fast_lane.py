"""The Ray executor's fast lane: replacements, which the sequential commit head waits
for, go to an actor that takes nothing else, so they never queue behind a worker's
chunks; the result is the in-process one."""

from farm import config as config_mod
from farm.campaign_setup import build_algorithm, build_campaign, spec_of
from farm.local_executor import LocalExecutor
from farm.ray_executor import RayExecutor
from farm.ray_pool import ActorPool, Call, Slot
from farm.simulators import build_simulator

RAW = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
       "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30},
       "farm": {"workers": 2, "batch_size": 128, "pipeline_depth": 3, "seed": 11}}


def campaign(make_executor):
    """The result hash, the counters and the stats of the fast lane (if any) of a campaign
    on the executor ``make_executor(spec)`` builds."""
    import ray

    cfg = config_mod.normalize(RAW)
    sim = build_simulator(spec_of(cfg))
    algo = build_algorithm(cfg, sim)
    executor = make_executor(spec_of(cfg))
    try:
        counters = build_campaign(cfg, algo, sim, executor).run()
        lanes = [s.handle for s in executor.pool.slots if s.lane] if isinstance(executor, RayExecutor) else []
        stats = ray.get([lane.stats.remote() for lane in lanes])
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
    ray_hash, counters, (lane,) = campaign(lambda spec: RayExecutor(spec, 2))
    assert ray_hash == local_hash
    assert counters.runs_replaced > 0  # the campaign had replacements to send ...
    assert lane["tasks"] > 0  # ... and the lane ran them, and only them
    assert 0 < lane["runs"] <= counters.runs_discarded + counters.runs_replaced
