"""Every budget from 1 up: a campaign stopped by its budget committed exactly that many
runs, and they are the first rows of the unlimited campaign's ledger (the committed
sequence does not depend on where the budget cuts it), on both executors. The rows
compared are the runs used; which in-flight runs were discarded unseen (and replaced)
depends on the window, which on Ray follows the measured run time."""

import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from farm.api import quantify


def config(executor, budget):
    return {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
            "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.005, "horizon": 40, "budget": budget},
            "farm": {"executor": executor, "workers": 2, "batch_size": 256, "pipeline_depth": 2, "seed": 5}}


@pytest.fixture(scope="module")
def unlimited(tmp_path_factory):
    out = tmp_path_factory.mktemp("unlimited") / "out"
    result = quantify(config("local", 10**7), out=out)
    assert result.summary["converged"]
    return used_runs(out)


def used_runs(out):
    table = pq.read_table(out / "ledger")
    return table.filter(pc.invert(table.column("discarded"))).drop_columns(["replacement"]).sort_by("sample_index")


@pytest.mark.parametrize("executor, budgets", [
    ("local", [1, 2, 255, 256, 257, 1000, 1024, 1025]),  # the edges of chunks of 256
    pytest.param("ray", [1, 257], marks=pytest.mark.soak),  # CI: Ray commits the in-process sequence elsewhere
])
def test_every_budget_commits_exactly_the_first_runs(tmp_path, unlimited, executor, budgets, request):
    if executor == "ray":
        request.getfixturevalue("ray_local")  # the session's Ray, not one of this test's own
    budgets.append(unlimited.num_rows - 1)  # stops one run before the N_eps rule would
    for budget in budgets:
        out = tmp_path / f"b{budget}"
        summary = quantify(config(executor, budget), out=out).summary
        assert summary["runs_committed"] == budget and not summary["converged"], budget
        assert used_runs(out).equals(unlimited.slice(0, budget)), budget
