"""Coupled counting end to end (shared/spec/algorithms.md point 3, farm.counting): under
"sequential" the committed sequence is the one-run-at-a-time campaign's at any window;
under both modes certification and the adversary search run, and the ledger accounts for
every discarded run with its replacement."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from farm import quantify
from farm.reports.html import rounds_table
from small_campaign import lead_follow_toml

WINDOWS = [(16, 1), (256, 2), (2048, 4)]


def _campaign(tmp_path, name, batch, depth, counting, mode="uniform"):
    toml = lead_follow_toml(farm_extra=f"pipeline_depth = {depth}\ncounting = \"{counting}\"\nseed = 3")
    toml = toml.replace("batch_size = 256", f"batch_size = {batch}").replace('mode = "uniform"', f'mode = "{mode}"')
    toml = toml.replace("[quantify]\n", '[quantify]\nrefine = "all"\n')  # SPE's rounds and certification throughout
    quantify(toml, out=tmp_path / name, force=True)
    summary = json.loads((tmp_path / name / "summary.json").read_text())
    ledger = pq.read_table(tmp_path / name / "ledger").to_pandas()
    # the HTML report's Rounds table counts the runs used and those discarded apart
    rounds = rounds_table(tmp_path / name)
    assert sum(r["committed"] for r in rounds) == int((~ledger.discarded).sum())
    assert sum(r["discarded"] for r in rounds) == int(ledger.discarded.sum())
    if counting == "sequential":  # every discarded index replaced: the runs used are the committed ones
        assert sum(r["committed"] for r in rounds) == summary["runs_committed"]
    return summary, ledger


def _check_ledger(summary, ledger, sequential=True):
    """Every index once among the runs used or discarded; a replacement only of a discarded
    index. Sequential: each discarded run replaced (at its own index); deferred: a
    replacement still pending at a round end is dropped with the round's other runs in
    flight, so its index stays discarded."""
    used = ledger[~ledger.discarded]
    discarded = np.sort(ledger[ledger.discarded].sample_index.to_numpy())
    replaced = np.sort(ledger[ledger.replacement].sample_index.to_numpy())
    assert used.sample_index.is_unique
    assert np.isin(replaced, discarded).all()
    every = np.union1d(used.sample_index.to_numpy(), discarded)
    np.testing.assert_array_equal(every, np.arange(len(every)))
    assert not ledger[ledger.discarded].counted.any() and not ledger[ledger.discarded].changed.any()
    assert len(replaced) == summary["runs_replaced"]
    # runs_discarded also counts replacements that the set moved away from in turn (replaced
    # again, never a ledger row of their own)
    assert len(discarded) <= summary["runs_discarded"]
    if sequential:
        np.testing.assert_array_equal(discarded, replaced)


@pytest.mark.parametrize("mode", ["uniform", "adversarial", pytest.param("search", marks=pytest.mark.soak)])
def test_sequential_counting_commits_the_same_runs_at_any_window(tmp_path, mode):
    """Adversarial: a deterministic system, whose certification runs every centre once,
    handed out batch by batch (fixed batches: coordinator/driver/pipeline.py ENUMERATION_BATCH)."""
    got = {}
    for batch, depth in WINDOWS:
        summary, ledger = _campaign(tmp_path, f"{mode}-{batch}x{depth}", batch, depth, "sequential", mode)
        _check_ledger(summary, ledger)
        used = ledger[~ledger.discarded].sort_values("sample_index")
        got[batch, depth] = summary, used.drop(columns=["replacement"]).reset_index(drop=True)
        assert summary["counting"] == "sequential" and summary["runs_certification"] > 0
        # a sampled certification's checks; a deterministic one (adversarial) runs every centre once, no check
        assert (summary["certification_attempts"] >= 1) == (mode != "adversarial")
    (s0, l0), *rest = got.values()
    for s, table in rest:
        assert s["result_hash"] == s0["result_hash"] and s["runs_committed"] == s0["runs_committed"]
        assert table.equals(l0)  # run for run: start, outcome, steps, changed, counted
    # a wider window mispredicts more: the price is simulated runs, not committed ones
    assert got[WINDOWS[-1]][0]["runs_discarded"] > got[WINDOWS[0]][0]["runs_discarded"]


@pytest.mark.parametrize("mode", ["uniform", "search"])
def test_deferred_counting_certifies_and_searches(tmp_path, mode):
    summary, ledger = _campaign(tmp_path, f"deferred-{mode}", 1024, 2, "deferred", mode)
    _check_ledger(summary, ledger, sequential=False)
    assert summary["counting"] == "deferred" and summary["converged"]
    assert summary["certification_attempts"] >= 1 and summary["runs_replaced"] > 0
    if mode == "search":
        assert (tmp_path / f"deferred-{mode}" / "adversary.json").exists()
