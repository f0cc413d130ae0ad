"""compare says up front how many runs its reference takes and how long, and lets the
user choose the grid (--grid per axis, --grid-total in all, --estimate to stop there)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from coordinator.reference import falsified, falsify
from farm.reports.compare import points_per_axis, sample_count
from scenarios.lead_follow import LeadFollow


def cli(*args):
    return subprocess.run([sys.executable, "-m", "farm", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("cmp")
    (d / "c.toml").write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[actions]\nmode = "uniform"\n'
                              '[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nepsilon = 0.01\nhorizon = 30\n'
                              '[farm]\nexecutor = "local"\nbatch_size = 256\n')
    assert cli("quantify", d / "c.toml", "--out", d / "out", "--quiet").returncode == 0
    return d / "out"


def test_points_per_axis():
    assert points_per_axis(3, grid=10) == 10
    assert points_per_axis(3, grid_total=8000) == 20 and points_per_axis(3, grid_total=7999) == 19
    assert points_per_axis(3) == 114  # ~1.5e6 for a model reference, as before
    assert points_per_axis(3, simulated=True) == 24 and points_per_axis(5, simulated=True) == 6  # 24^3 in all
    for kwargs, field in [({"grid": 1}, "--grid"), ({"grid_total": 7}, "--grid-total"),
                          ({"grid": 10, "grid_total": 1000}, "not both")]:
        with pytest.raises(ValueError, match=field):
            points_per_axis(3, **kwargs)


def test_the_plan_and_estimate_come_first_and_the_grid_total_is_the_grid(campaign):
    r = cli("compare", campaign, "--grid-total", 8000, "--estimate")
    assert r.returncode == 0, r.stderr
    assert "8,000 runs (20 grid points per axis)" in r.stdout and "about" in r.stdout
    assert not (campaign / "compare.json").exists()  # an estimate writes nothing
    r = cli("compare", campaign, "--grid-total", 8000, "--verbose")
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    plan = next(i for i, line in enumerate(lines) if "8,000 grid points (20 per axis) + 90,000 for the figure" in line)
    estimate = next(i for i, line in enumerate(lines) if "for the rest (a shared machine" in line)
    done = next(i for i, line in enumerate(lines) if "reference done" in line)
    assert plan < estimate < done
    by_total = json.loads((campaign / "compare.json").read_text())
    runs = by_total.pop("runs")
    assert runs["reference_runs"] == 8000 and runs["figure_runs"] == 4 * 150 * 150
    assert runs["estimated_s"] > 0 and runs["elapsed_s"] > 0
    assert runs["falsification_runs"] == 4 * by_total["falsified_reference_points"][1]
    assert "runs: 8,000 for the reference" in r.stdout
    assert cli("compare", campaign, "--grid", 20, "--quiet").returncode == 0
    by_axis = json.loads((campaign / "compare.json").read_text())
    by_axis.pop("runs")
    assert by_axis == by_total


def test_compare_on_uniform_points_gives_intervals(campaign):
    r = cli("compare", campaign, "--points", 5000, "--quiet")
    assert r.returncode == 0, r.stderr
    metrics = json.loads((campaign / "compare.json").read_text())
    assert metrics["sample_points"] == 5000 and metrics["runs"]["reference_runs"] == 5000
    low, high = metrics["iou_interval"]
    assert 0 <= low <= metrics["iou"] <= high <= 1
    assert "points uniform in Sigma (exact 95 % intervals)" in r.stdout


def test_sample_count_default_is_points_above_five_axes_only():
    assert sample_count(5, None, None, None) is None and sample_count(7, None, None, None) == 200_000
    assert sample_count(7, 4, None, None) is None  # a grid asked for is a grid
    assert sample_count(3, None, None, 5000) == 5000


def test_bad_grids_are_one_line_errors(campaign):
    for args, word in [(("--grid-total", 5), "--grid-total"), (("--grid", 10, "--grid-total", 1000), "not both"),
                       (("--points", 10), "--points"), (("--points", 5000, "--grid", 10), "not both")]:
        r = cli("compare", campaign, *args)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and word in r.stderr, r.stderr


def test_falsification_split_in_parts_is_the_whole():
    """compare times a first part of the falsification runs: the same stream keys, so
    the count is the one of a single call."""
    sc = LeadFollow("idm")
    points = np.random.default_rng(0).uniform(sc.lower, sc.upper, (300, 3))
    whole = falsified(sc, points, slice(None), tries=2, horizon=60)
    first = np.sort(np.random.default_rng(1).choice(300, 70, replace=False))
    rest = np.setdiff1d(np.arange(300), first)
    parts = np.empty(300, dtype=bool)
    parts[first] = falsified(sc, points, first, tries=2, horizon=60)
    parts[rest] = falsified(sc, points, rest, tries=2, horizon=60)
    np.testing.assert_array_equal(parts, whole)
    assert whole.any() and not whole.all()
    assert falsify(sc, points, tries=2, horizon=60) == whole.sum()
