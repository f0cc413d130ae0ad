"""The virtual farm (farm.executor = "virtual"): the real coordinator on a simulated clock.
Its results are a real run's (the same result_hash and committed runs as in-process and
on Ray), only time is modelled; summary.json then says the simulated time to the result
and the workers' utilisation."""

import dataclasses
import json

import numpy as np

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
    # where the simulated time went: the head's waits for runs and the coordinator's own CPU
    assert 0 < virtual["virtual_waiting_s"] < virtual["virtual_elapsed_s"]
    assert 0 < virtual["virtual_coordinator_s"] < virtual["virtual_elapsed_s"] - virtual["virtual_waiting_s"]
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


def _virtual_campaign(workers: int, run_time: float, **switches):
    """A two-round campaign on ``workers`` virtual workers: (config, algorithm, executor,
    campaign); ``switches``: CampaignSettings' result-neutral ones (look_ahead, speculate)."""
    from coordinator.driver import Campaign
    from farm.jobs.campaign_setup import build_algorithm, campaign_settings
    from farm.execution.process import build_simulator, spec_of
    from farm.config import parse
    from farm.execution.factory import make_executor

    cfg = parse(lead_follow_toml(executor="virtual", delta_min=1.0,
                                 farm_extra=f"workers = {workers}\n[farm.virtual]\nrun_time = {run_time}"))
    simulator = build_simulator(spec_of(cfg))
    algorithm = build_algorithm(cfg, simulator)
    executor = make_executor(cfg.farm, spec_of(cfg))
    settings = dataclasses.replace(campaign_settings(cfg), **switches)
    return cfg, algorithm, executor, Campaign(algorithm, executor, settings)


def test_the_virtual_farm_says_what_the_head_waited_for():
    # on many workers of slow runs a run that changes the set waits for the replacements
    # held before it (sequential counting): the clock keeps that share of the waits apart
    _, _, executor, campaign = _virtual_campaign(300, 1.0)
    counters = campaign.run()
    assert counters.runs_replaced > 0
    assert 0 < executor.waited_replacements_s < executor.waited_s < executor.clock


def test_a_free_coordinator_charges_the_clock_nothing_and_changes_no_result():
    # benchmarks/bench_virtual.py --free-coordinator: what the counting rule allows, the
    # coordinator's CPU and calls costing no simulated time
    _, paid_algorithm, paid, paid_campaign = _virtual_campaign(300, 1.0)
    paid_campaign.run()
    _, free_algorithm, free, free_campaign = _virtual_campaign(300, 1.0)
    free.charge_coordinator, free.call_cost = False, 0.0
    free_campaign.run()
    assert free_algorithm.result().result_hash == paid_algorithm.result().result_hash
    assert free.coordinator_s == 0 < paid.coordinator_s
    # with the coordinator free every simulated second is a wait of the head for runs (but
    # the workers' screening of stored runs for experience replay, microseconds here)
    assert free.waited_s == pytest.approx(free.clock, rel=1e-4)
    assert paid.waited_s < paid.clock


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


def test_runs_launched_before_the_head_asks_change_no_result():
    # at a change the head waits for the replacements it passed; the runs the change will
    # call for are launched meanwhile, worked out on a copy of the algorithm, and draws in
    # flight that a change moved are replaced before the head gets there: a run is used
    # only if its stream draws its start when the head needs it, so the committed sequence
    # is the same with or without them (coordinator/driver/lookahead.py)
    _, algorithm, _, campaign = _virtual_campaign(300, 1.0, speculate=False)  # changes wait for their holds
    with_them = campaign.run()
    assert campaign.look_ahead.launched_past_holds > 0
    _, algorithm_without, _, campaign_without = _virtual_campaign(300, 1.0, speculate=False, look_ahead=False)
    without = campaign_without.run()
    assert campaign_without.look_ahead.launched_past_holds == 0
    assert algorithm.result().result_hash == algorithm_without.result().result_hash
    assert (with_them.committed, with_them.changes) == (without.committed, without.changes)


def _used_rows(log) -> dict:
    """The ledger's rows of the runs used (the committed sequence), column by column."""
    rows = log.take()
    used = rows["kind"] != log.DISCARDED
    return {name: column[used] for name, column in rows.items()}


def test_changes_applied_past_holds_change_no_result():
    # with slow runs a change does not wait for the holds before it: it is applied on a
    # copy's promise, and undone if a hold, judged at the state the head passed it,
    # changes the state (coordinator/driver/speculation.py). The committed sequence, ledger row
    # by row, is the one of changes that wait
    _, algorithm, executor, campaign = _virtual_campaign(300, 1.0)
    ahead = campaign.run()
    assert campaign.speculations.applied > 0 and campaign.speculations.restored > 0  # both ways taken
    _, algorithm_waiting, executor_waiting, waiting = _virtual_campaign(300, 1.0, speculate=False)
    waited = waiting.run()
    assert waiting.speculations.applied == 0
    assert algorithm.result().result_hash == algorithm_waiting.result().result_hash
    assert (ahead.committed, ahead.changes, ahead.quiet) == (waited.committed, waited.changes, waited.quiet)
    mine, theirs = _used_rows(campaign.log), _used_rows(waiting.log)
    for name in mine.keys() - {"kind"}:  # (a run or its replacement: that depends on the timing)
        assert np.array_equal(mine[name], theirs[name]), name
    assert executor.clock < executor_waiting.clock  # the point of it


def test_a_campaign_stopped_while_changes_are_applied_past_holds_resumes_to_the_same_result(tmp_path, monkeypatch):
    # a checkpoint taken while changes are applied past holds keeps the state as the head
    # passed the first hold (the copy before the first such change): resumed, the campaign
    # reaches the result of one never stopped
    from farm.directory import checkpoint
    from farm.config import parse
    from farm.jobs.side_campaign import SideCampaign, Stopped
    from farm.jobs.quantification import run

    cfg = parse(lead_follow_toml(executor="virtual", delta_min=1.0,
                                 farm_extra="workers = 300\n[farm.virtual]\nrun_time = 1.0"))
    whole = run(cfg, tmp_path / "whole")
    observer = SideCampaign._observer
    stopped_past_holds = []

    def stop_past_holds(self, progress, status):
        observe = observer(self, progress, status)

        def then_stop(campaign):
            observe(campaign)
            if campaign.speculations and not stopped_past_holds:
                stopped_past_holds.append(campaign.counters.committed)
                self.save()  # a checkpoint now, and the one the stop takes
                campaign.stop()

        return then_stop

    save = checkpoint.save
    saved_past_holds = []

    def save_and_say(campaign, *args):
        saved_past_holds.append(bool(campaign.speculations))
        save(campaign, *args)

    monkeypatch.setattr(SideCampaign, "_observer", stop_past_holds)
    monkeypatch.setattr(checkpoint, "save", save_and_say)
    with pytest.raises(Stopped):
        run(cfg, tmp_path / "stopped")
    assert stopped_past_holds and saved_past_holds[-1]  # the checkpoint kept is one taken past holds
    monkeypatch.setattr(checkpoint, "save", save)
    monkeypatch.setattr(SideCampaign, "_observer", observer)
    resumed = run(cfg, tmp_path / "stopped", resume=True)
    for key in ("result_hash", "runs_committed", "boxes", "rounds"):
        assert resumed[key] == whole[key], key
    # and the ledger: the committed sequence, run by run (which changed the state, which counted)
    import pyarrow.dataset as ds

    from farm.directory.storage import read_ledger

    columns = ["sample_index", "v0", "v1", "p10", "outcome", "changed", "counted"]
    used = [read_ledger(tmp_path / name, columns, filter=~ds.field("discarded")).sort_by("sample_index")
            for name in ("stopped", "whole")]  # (not the runs discarded unseen: their timing is the executor's)
    for name in columns:
        assert used[0].column(name).to_pylist() == used[1].column(name).to_pylist(), name


def test_a_concurrent_executor_gets_a_passs_replacements_in_one_call():
    # a misprediction's replacement is not sent at once on an executor whose workers run
    # apart from the driver (Executor.concurrent): a Ray call per misprediction cost the
    # driver more than its runs (docs/benchmarks.md). Which call carries a replacement
    # changes no result
    def replacement_calls(concurrent: bool):
        _, algorithm, executor, campaign = _virtual_campaign(8, 0.01)
        executor.concurrent = concurrent
        calls, submit = [], executor.submit

        def recorded(first_index, starts, screen=None, actions=None, indices=None):
            if indices is not None:
                calls.append(len(indices))
            return submit(first_index, starts, screen, actions, indices)

        executor.submit = recorded
        counters = campaign.run()
        return calls, counters, algorithm.result().result_hash, _used_rows(campaign.log)

    batched, counters, result, rows = replacement_calls(True)
    each, counters_each, result_each, rows_each = replacement_calls(False)
    assert counters.runs_replaced > 20
    assert sum(batched) >= sum(each) * 0.9 and len(batched) < len(each), (len(batched), len(each))
    assert result == result_each and counters.committed == counters_each.committed
    for name in rows.keys() - {"kind"}:
        assert np.array_equal(rows[name], rows_each[name]), name


def test_fast_runs_draw_batches_no_earlier_than_the_head_needs_them():
    # runs of microseconds: the driver bounds the farm, the head seldom waits for a worker,
    # and every run in flight is a draw a change may move
    # (coordinator/driver/lead.py): the lead shrinks, fewer runs are replaced, and the
    # committed sequence is the same as with the full pipeline
    shares = []
    _, algorithm, _, campaign = _virtual_campaign(8, 1e-5)
    reached = campaign.pipeline.lead.reached

    def recorded(ahead):
        reached(ahead)
        shares.append(campaign.pipeline.lead.share)

    campaign.pipeline.lead.reached = recorded
    led = campaign.run()
    _, algorithm_full, _, campaign_full = _virtual_campaign(8, 1e-5)
    campaign_full.pipeline.lead.adaptive = False
    full = campaign_full.run()
    assert algorithm.result().result_hash == algorithm_full.result().result_hash
    assert (led.committed, led.changes) == (full.committed, full.changes)
    assert min(shares) < 0.75
    assert led.runs_replaced < full.runs_replaced


def test_slow_runs_keep_the_full_pipeline():
    # a batch the head waits for costs it a run's seconds while workers idle: slow runs
    # draw as far ahead as pipeline_depth says, whatever the lead learnt
    _, _, executor, campaign = _virtual_campaign(300, 1.0)
    campaign.run()
    assert executor.run_seconds() >= 1e-3
    assert campaign.pipeline.lead.runs(1024, 2, executor.run_seconds()) == float("inf")
