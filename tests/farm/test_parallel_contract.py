"""The parallel contract (shared/spec/algorithms.md) with real Ray actors."""

import os
import signal
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from coordinator.certification import TOLERANCE
from coordinator.sample_size import n_eps, n_eps_attempt
from farm import config as config_mod
from farm.jobs.quantification import run


def contract_config(executor="local", workers=2, **quantify):
    raw = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
           "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "beta": 0.1, "horizon": 30, **quantify},
           "farm": {"executor": executor, "workers": workers, "batch_size": 128, "pipeline_depth": 3, "seed": 11}}
    return config_mod.normalize(raw)


@pytest.fixture(autouse=True)
def chunk_per_worker(monkeypatch):
    """Cut batches into a chunk per worker whatever the run time (the numpy back end is
    fast enough for one chunk per batch): with 4 workers and 3 batches in flight these
    campaigns' 128-run batches then arrive in 4 chunks each, 12 chunks over 4 workers,
    out of order, which is what the index-order commit must get right."""
    from farm.execution.chunking import ChunkSizer

    monkeypatch.setattr(ChunkSizer, "size", lambda self, runs, urgent=False, lanes=0: max(1, -(-runs // self.workers)))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    return run(contract_config(), tmp_path_factory.mktemp("ref") / "c", resume=False)


@pytest.mark.parametrize("workers", [pytest.param(1, marks=pytest.mark.soak), 2, 4])  # CI: 2, and 4 on 2 CPUs
def test_ray_gives_the_in_process_result_bit_for_bit(ray_local, reference, tmp_path, workers):
    summary = run(contract_config("ray", workers), tmp_path / "c", resume=False)
    assert summary["result_hash"] == reference["result_hash"]
    assert summary["runs_committed"] == reference["runs_committed"]
    assert summary["runs_simulated"] >= summary["runs_committed"]


def test_any_chunking_gives_the_same_result(ray_local, reference, tmp_path, monkeypatch):
    """Chunk sizes drawn at random for every batch, 1 run up (a seeded generator of the
    test's own): the committed sequence is the in-process one all the same."""
    from farm.execution.chunking import ChunkSizer

    rng = np.random.default_rng(3)
    sizes = []

    def any_size(self, runs, urgent=False, lanes=0):
        sizes.append(int(rng.integers(1, runs + 1)))
        return sizes[-1]

    monkeypatch.setattr(ChunkSizer, "size", any_size)
    summary = run(contract_config("ray", 3), tmp_path / "c", resume=False)
    assert min(sizes) < 8 and max(sizes) > 64  # thin and thick chunks were both cut
    assert summary["result_hash"] == reference["result_hash"]


def test_change_blocks_put_in_the_object_store_give_the_same_result(ray_local, reference, tmp_path, monkeypatch):
    """Small change blocks travel inside the task call; large ones are put in the object
    store once. Every block put there: the same result."""
    from farm.ray_runtime import mirror

    monkeypatch.setattr(mirror, "INLINE_BYTES", -1)
    puts = []
    original = mirror.Mirrors.message

    def counting(self, actor, screen, fresh=False):
        message = original(self, actor, screen, fresh)
        kind, blocks, _ = message
        if kind == "changes":
            puts.extend(b for b in blocks if not isinstance(b, list))
        return message

    monkeypatch.setattr(mirror.Mirrors, "message", counting)
    summary = run(contract_config("ray", 2), tmp_path / "c", resume=False)
    assert puts  # the object-store path was taken
    assert summary["result_hash"] == reference["result_hash"]


def test_n_eps_rule_is_exact_in_the_committed_record(reference, tmp_path):
    out = tmp_path / "c"
    summary = run(contract_config(), out, resume=False)
    ledger = pq.read_table(out / "ledger").to_pandas()
    discarded = ledger[ledger["discarded"]]
    ledger = ledger[~ledger["discarded"]].sort_values("sample_index")
    idx = ledger["sample_index"].to_numpy()
    np.testing.assert_array_equal(idx, np.arange(len(idx)))  # none missing, none twice
    assert len(idx) == summary["runs_committed"]
    # coupled counting: a run whose start its stream no longer draws is discarded unseen
    # (never counted, never a change) and its index re-run from the current draw
    assert not discarded["counted"].any() and not discarded["changed"].any()
    assert sorted(discarded["sample_index"]) == sorted(ledger.loc[ledger["replacement"], "sample_index"])
    changed = ledger["changed"].to_numpy()
    counted = ledger["counted"].to_numpy()
    # every round ends after N_eps quiet runs; the certification round (the last) after
    # the N its last check needs (beta split over the checks, at most quantify.certify_tolerance
    # violations among them: counted, never a change)
    assert summary["certification_attempts"] >= 1
    needs = [n_eps(0.005, 0.1)] * (len(summary["round_ends"]) - 1)
    needs.append(n_eps_attempt(0.005, 0.1, summary["certification_attempts"], TOLERANCE))
    assert summary["certification_check_violations"] <= TOLERANCE
    assert needs[-1] == summary["n_eps_final"]
    for k, (end, need) in enumerate(zip(summary["round_ends"], needs)):
        tail = slice(end - need, end)
        assert counted[tail].all() and not changed[tail].any()  # N_eps quiet, current-state runs
        if k < len(needs) - 1:  # ... and not one more (a check starts right after a closing round's quiet runs)
            assert changed[end - need - 1] or not counted[end - need - 1]
    # runs drawn before a change count when their draw is what the changed set draws:
    # the streak starts right after the change, not a window later
    assert counted[np.nonzero(changed)[0] + 1].any()
    # runs dropped at round ends were simulated and are accounted
    assert summary["runs_simulated"] == summary["runs_committed"] + summary["runs_replaced"] + summary["runs_dropped"]


@pytest.mark.soak  # CI: tests/conformance/test_executors.py kills a Ray worker mid-campaign
def test_a_killed_worker_costs_time_not_results(ray_local, reference, tmp_path, monkeypatch):
    from farm.jobs import side_campaign

    killed = []
    make = side_campaign.make_executor

    def make_and_arm(*a, **k):
        ex = make(*a, **k)
        pids = ex.pids()
        result = ex.result

        def result_then_kill(handle):
            batch = result(handle)
            if not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
            return batch

        ex.result = result_then_kill
        return ex

    monkeypatch.setattr(side_campaign, "make_executor", make_and_arm)
    summary = run(contract_config("ray", 2), tmp_path / "c", resume=False)
    assert killed
    assert summary["result_hash"] == reference["result_hash"]


def test_an_exception_in_a_scenario_names_the_sample_and_does_not_hang(ray_local, tmp_path):
    from farm.ray_runtime.executor import RayExecutor
    from scenarios.errors import ScenarioError
    from scenarios.simulator import SimSpec

    spec = SimSpec({"name": "user_scenarios:Raising", "sv_policy": "none"}, {"mode": "uniform"}, 10, 0)
    ex = RayExecutor(spec, 2, "local", max_retries=1).start()
    try:
        starts = np.tile([[0.2, 0.2]], (64, 1))
        starts[37] = [0.9, 0.9]
        with pytest.raises(ScenarioError, match=r"ValueError: boom.*sample index 1037 \(start state \[0.9, 0.9\]\)"):
            for handle in ex.submit(1000, starts):
                ex.result(handle)
    finally:
        ex.close()


def test_batches_are_cut_by_the_measured_run_time(ray_local, monkeypatch):
    """The first batch starts with a one-run chunk that measures the run time; the rest is
    cut by it (farm/execution/chunking.py): a share of each batch per worker, at most about a second
    of simulation a chunk, at least what the driver can afford. The sleeping back end
    (benchmarks/slow_backend.py at 20 ms a run) makes chunks of about 50 runs."""
    from farm.ray_runtime.executor import RayExecutor

    monkeypatch.undo()  # the real rule, not the autouse fixture's
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    monkeypatch.setattr(sys, "path", sys.path)
    cfg = config_mod.normalize({**contract_config("ray", 2).model_dump(),
                                "scenario": {"name": "lead-follow", "sv_policy": "idm",
                                             "backend": "slow_backend:SlowBackend",
                                             "slow_backend:SlowBackend": {"step_cost_s": 4e-4}}})
    from farm.execution.process import spec_of

    ex = RayExecutor(spec_of(cfg), 2, pipeline_depth=2).start()
    try:
        starts = np.tile([10.0, 10.0, 40.0], (400, 1))  # a quiet run: every step of the horizon
        chunks = [ex.result(h) for h in ex.submit(0, starts)]
        assert len(chunks[0]) == 1  # the probe
        run_s = ex.sizer.run_s
        assert 0.0116 < run_s < 0.2, run_s  # 29 steps of 0.4 ms, measured (the worker's CPU on top)
        assert sum(len(c) for c in chunks) == 400
        assert [c.first_index for c in chunks] == sorted(c.first_index for c in chunks)
        assert max(len(c) for c in chunks[1:]) * run_s < 2.0  # cut by the probe's time, not 200 a worker
        chunks = [ex.result(h) for h in ex.submit(400, starts)]
        assert all(len(c) * ex.sizer.run_s < 2.0 for c in chunks)  # about a second a chunk, not 400 runs
        assert len(chunks) >= 4 and ex.busy_at_most(400) == 2
    finally:
        ex.close()


def test_change_log_is_trimmed_when_only_some_workers_are_used(ray_local, monkeypatch):
    """One chunk in flight on 4 workers: only the first actor is ever used. The
    coordinator still forgets the changes it has applied (the unused actors would get a
    snapshot), and each screening is made at the coverage as it was submitted."""
    from coordinator.coverage import Coverage, Insert
    from farm.execution.process import spec_of
    from farm.ray_runtime.executor import RayExecutor

    from farm.execution.chunking import ChunkSizer

    monkeypatch.setattr(ChunkSizer, "size", lambda self, runs, urgent=False, lanes=0: runs)  # 20 runs: one chunk
    cfg = contract_config("ray", 4)
    lower, upper = np.array([0.0, 0.0, 0.0]), np.array([100.0, 30.0, 30.0])
    cov = Coverage(3, 2.0, lower, bounds=(lower, upper))
    rng = np.random.default_rng(0)
    ex = RayExecutor(spec_of(cfg), 4).start()
    ex.sizer.ran(20, 0.001)  # as if measured: no one-run probe first
    try:
        for step in range(8):
            for _ in range(3):  # a few changes between chunks
                cov.apply(Insert(rng.uniform(lower, upper, size=(5, 3))), cov.version + 1)
            (handle,) = ex.submit(100 * step, np.tile([10.0, 10.0, 40.0], (20, 1)), screen=cov)
            chunk = ex.result(handle)
            assert chunk.screening.seq == cov.seq  # screened at the coverage as submitted
        assert [s["tasks"] for s in ex.worker_stats()] == [8, 0, 0, 0]
        # not all 24 changes are kept: the log is trimmed about once a wave of messages (4 actors)
        assert len(cov.changes_since(-1)) <= 3 * 4 < 24
    finally:
        ex.close()


@pytest.mark.soak  # three Ray campaigns for one line of output
def test_workers_that_cannot_be_kept_busy_are_announced(ray_local, tmp_path):
    """Chunks of one run up keep every worker busy, unless there are more workers than runs
    in flight: 2 x 1 runs on 3 workers. Under deferred counting the campaign says so (the
    window is result-relevant, so it is not changed); under sequential counting (the
    default) the batch follows the workers and nothing is said."""
    import io

    from farm.reports.progress import Progress

    log = io.StringIO()
    raw = contract_config("ray", 3).model_dump()
    raw["farm"].update(batch_size=2, pipeline_depth=1, counting="deferred")
    raw["quantify"]["budget"] = 40
    run(config_mod.normalize(raw), tmp_path / "c", resume=False, progress=Progress(stream=log))
    assert "keep at most 2 of the 3 workers busy" in log.getvalue()
    log = io.StringIO()
    raw["farm"]["counting"] = "sequential"
    run(config_mod.normalize(raw), tmp_path / "s", resume=False, progress=Progress(stream=log))
    assert "workers busy" not in log.getvalue()
    log = io.StringIO()
    run(contract_config("ray", 4, budget=40), tmp_path / "d", resume=False, progress=Progress(stream=log))
    assert "Ray (local) up with 4 workers" in log.getvalue() and "workers busy" not in log.getvalue()


def test_a_dropped_chunk_is_left_to_finish_and_the_actor_goes_on(ray_local):
    """``cancel`` drops a chunk without ``ray.cancel``: cancelling a queued actor task can
    leave a gap in the actor's sequence numbers that stalls its next tasks for Ray's 30 s
    reorder timeout. A chunk queued behind a running one is dropped; it still runs (the
    actor counts 3 tasks, 2 had it been cancelled), and the next chunk comes back."""
    from farm.execution.process import spec_of
    from farm.ray_runtime.executor import RayExecutor

    ex = RayExecutor(spec_of(contract_config("ray", 1)), 1).start()
    ex.sizer.ran(20_000, 0.02)  # as if measured: each batch one chunk, no one-run probe first
    try:
        starts = np.tile([10.0, 10.0, 40.0], (20_000, 1))
        running = ex.submit(0, starts)
        queued = ex.submit(20_000, starts[:500])
        for handle in queued:
            ex.cancel(handle)
        after = ex.submit(20_500, starts[:300])
        assert len(ex.result(running[0])) == 20_000
        assert [len(ex.result(h)) for h in after] == [300]
        assert ex.worker_stats()[0]["tasks"] == 3
    finally:
        ex.close()
