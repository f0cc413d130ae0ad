"""Every budget from 1 up: a campaign stopped by its budget committed exactly that many
runs, and they are the first rows of the unlimited campaign's ledger (the committed
sequence does not depend on where the budget cuts it), on both executors. The rows
compared are the runs used; which in-flight runs were discarded unseen (and replaced)
depends on the window, which on Ray follows the measured run time."""

import subprocess
import sys

import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from farm.api import quantify
from small_campaign import lead_follow_toml


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
    ("local", [1, 256, 257, 1025]),  # the edges of chunks of 256 (CI)
    pytest.param("local", [2, 255, 1000, 1024], marks=pytest.mark.soak),  # and beside them (each budget a campaign)
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


def test_a_used_up_budget_says_so_at_the_end_and_certifies_nothing(tmp_path):
    """The CLI's end lines name the budget and what was used, and say the set is not
    certified (exit 0: the campaign finished, README's exit table)."""
    toml = lead_follow_toml().replace("horizon = 30", "horizon = 30\nbudget = 300\nholdout_runs = 0")
    (tmp_path / "c.toml").write_text(toml)
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / "c.toml"), "--out",
                        str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    used_up = "quantify.budget of 300 runs used up (300 committed"
    assert used_up in r.stderr and "all runs done" not in r.stderr  # the progress's end line
    assert f"budget: {used_up}" in r.stdout and "the set is NOT certified" in r.stdout
    assert "guarantee: No guarantee" in r.stdout
