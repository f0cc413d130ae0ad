"""The virtual farm (farm.executor = "virtual"): the real coordinator on a simulated clock.
Its results are a real run's (the same result_hash and committed runs as in-process and
on Ray), only time is modelled; summary.json then says the simulated time to the result
and the workers' utilisation."""

import json

import pytest

from farm import quantify
from small_campaign import lead_follow_toml


def _run(tmp_path, name: str, executor: str, farm_extra: str = "", **overrides):
    result = quantify(lead_follow_toml(executor=executor, farm_extra=farm_extra), out=tmp_path / name, force=True,
                      **overrides)
    return json.loads((tmp_path / name / "summary.json").read_text()), result


def test_the_virtual_farm_commits_what_a_real_run_commits(tmp_path, ray_local):
    local, _ = _run(tmp_path, "local", "local")
    ray, _ = _run(tmp_path, "ray", "ray", "workers = 2")
    virtual, _ = _run(tmp_path, "virtual", "virtual", "workers = 300\n[farm.virtual]\nrun_time = 2.0\njitter = 0.5")
    for key in ("result_hash", "runs_committed", "boxes", "rounds", "certification_attempts"):
        assert local[key] == ray[key] == virtual[key], key
    # what the window costs (runs discarded unseen and replaced) follows the workers: 300
    # virtual workers keep more in flight than 2
    assert virtual["runs_replaced"] >= local["runs_replaced"]
    assert "virtual_elapsed_s" not in local and "utilisation" not in ray  # only a virtual farm has a clock
    assert 0 < virtual["utilisation"] <= 1
    # every committed run took its worker some of the 2 s a full run takes: the clock is
    # no shorter than the runs' time spread over all 300 workers
    assert virtual["virtual_elapsed_s"] >= 2.0 * 0.02 * virtual["runs_committed"] / 300


def test_more_virtual_workers_reach_the_result_sooner(tmp_path):
    times = {}
    for workers in (1, 16):
        summary, _ = _run(tmp_path, f"w{workers}", "virtual", f"workers = {workers}\n[farm.virtual]\nrun_time = 1.0")
        times[workers] = summary["virtual_elapsed_s"], summary["result_hash"], summary["utilisation"]
    assert times[1][1] == times[16][1]  # the worker count never changes a result
    assert times[1][2] > 0.9  # one worker of 1 s runs is almost never idle
    assert times[1][0] / times[16][0] > 8  # 16 workers of 1 s runs: most of them busy


@pytest.mark.parametrize("field,value", [("run_time", 0.0), ("jitter", -1.0), ("call_cost", -0.1)])
def test_a_bad_virtual_setting_is_named(tmp_path, field, value):
    from farm.config import ConfigError

    with pytest.raises(ConfigError, match=f"farm.virtual.{field}"):
        quantify(lead_follow_toml(executor="virtual", farm_extra=f"[farm.virtual]\n{field} = {value}"),
                 out=tmp_path / "bad", force=True)


def _virtual_campaign(workers: int, run_time: float):
    """A two-round campaign on ``workers`` virtual workers: (config, algorithm, executor, campaign)."""
    from farm.campaign_setup import build_algorithm, build_campaign, spec_of
    from farm.config import parse
    from farm.executors import make_executor
    from farm.simulators import build_simulator

    cfg = parse(lead_follow_toml(executor="virtual", delta_min=1.0,
                                 farm_extra=f"workers = {workers}\n[farm.virtual]\nrun_time = {run_time}"))
    simulator = build_simulator(spec_of(cfg))
    algorithm = build_algorithm(cfg, simulator)
    executor = make_executor(cfg.farm, spec_of(cfg))
    return cfg, algorithm, executor, build_campaign(cfg, algorithm, simulator, executor)


def test_the_virtual_farm_says_what_the_head_waited_for():
    # on many workers of slow runs a run that changes the set waits for the replacements
    # held before it (sequential counting): the clock keeps that share of the waits apart
    _, _, executor, campaign = _virtual_campaign(300, 1.0)
    counters = campaign.run()
    assert counters.runs_replaced > 0
    assert 0 < executor.waited_replacements_s < executor.waited_s < executor.clock


def test_many_workers_keep_no_more_in_flight_than_a_rounds_quiet_runs():
    # 1,000 workers of short runs would each take a chunk of every batch: batches of tens of
    # thousands of runs, most dropped at the round's end or moved by a change and replaced
    # (docs/benchmarks.md, "2026-11-26, morning")
    cfg, algorithm, executor, campaign = _virtual_campaign(1000, 0.1)
    batches, wanted = [], []
    submit = executor.submit

    def recorded(first_index, starts, screen=None, actions=None, indices=None):
        if indices is None and not algorithm.enumerates:  # a batch, not replacements
            batches.append((len(starts), campaign.quiet_needed()))
            wanted.append(executor.batch_size(cfg.farm.batch_size))
        return submit(first_index, starts, screen, actions, indices)

    executor.submit = recorded
    campaign.run()
    assert all(size <= max(cfg.farm.batch_size, quiet) for size, quiet in batches), batches
    assert max(wanted) > max(quiet for _, quiet in batches)  # the workers alone would have asked for more


def test_runs_launched_for_a_change_waiting_for_holds_change_no_result(monkeypatch):
    # at a change the head waits for the replacements it passed; the runs the change will
    # call for are launched meanwhile, worked out on a copy of the algorithm: a run is used
    # only if its stream draws its start when the head needs it, so the committed sequence
    # is the same with or without them (coordinator/campaign.py ``_launch_past_holds``)
    import coordinator.campaign as campaign_mod

    _, algorithm, _, campaign = _virtual_campaign(300, 1.0)
    with_them = campaign.run()
    assert campaign.launched_past_holds > 0
    monkeypatch.setattr(campaign_mod, "WHAT_IF", False)
    _, algorithm_without, _, campaign_without = _virtual_campaign(300, 1.0)
    without = campaign_without.run()
    assert campaign_without.launched_past_holds == 0
    assert algorithm.result().result_hash == algorithm_without.result().result_hash
    assert (with_them.committed, with_them.changes) == (without.committed, without.changes)
