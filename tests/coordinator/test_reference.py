import json
import subprocess
import sys
from functools import partial

import numpy as np
import pytest

from coordinator.reference import (NoReference, compare_boxes, compare_sampled, falsify, grid, reference_safe,
                                  uniform_points)
from coordinator.safe_set import SafeSet
from invariant_sets import min_future_gap_brake
from scenarios import NumpyBackend, make_scenario
from scenarios.worst_case_rollout import safe_until_standstill
from scenarios.toy import Toy


def test_toy_reference_is_its_closed_form():
    sc = make_scenario("toy", sv_policy="none")
    pts = grid(sc, 101)
    np.testing.assert_array_equal(reference_safe(NumpyBackend(sc), pts), Toy.safe(pts))


def test_brake_reference_is_the_min_future_gap_set_and_survives_falsification():
    sc = make_scenario("lead-follow", sv_policy="brake")
    pts = sc.lower + (sc.upper - sc.lower) * np.random.default_rng(0).random((20000, 3))
    safe = safe_until_standstill(sc, pts)
    np.testing.assert_array_equal(safe, min_future_gap_brake(pts) >= -1e-9)
    assert safe_until_standstill(sc, np.array([[0.0, 0.0, 0.5], [20.0, 0.0, 1.0]])).tolist() == [True, False]
    assert falsify(NumpyBackend(sc), pts[safe][:3000]) == 0  # Gamma* is the worst case for brake


def test_a_scenario_without_a_model_or_settling_adversary_has_no_reference():
    sc = make_scenario("user_scenarios:NaNScenario")
    with pytest.raises(NoReference, match="scenario 'nan' has no reference safe set"):
        reference_safe(NumpyBackend(sc), np.zeros((3, 2)))


def test_compare_scores_a_perfect_and_a_shifted_set():
    sc = NumpyBackend(make_scenario("toy", sv_policy="none"))
    xs = np.concatenate([np.arange(1.25, 4.0, 0.5), np.arange(6.25, 9.0, 0.5)])
    centres = np.stack(np.meshgrid(xs, np.arange(0.25, 10.0, 0.5), indexing="ij"), -1).reshape(-1, 2)
    boxes = partial(SafeSet.uniform, half_width=0.25, state_names=("x", "y"))
    perfect = compare_boxes(sc, boxes(centres), grid_points_per_axis=200)
    assert perfect["iou"] == 1.0 and perfect["hausdorff"] < 0.1
    assert perfect["missed_depth_boxes"] == perfect["overclaimed_depth_boxes"] == 0.0
    assert perfect["grid_cell_boxes"] == pytest.approx(0.1)  # cells of 0.05, boxes 0.5 wide
    one_well = compare_boxes(sc, boxes(centres[centres[:, 0] < 5]), grid_points_per_axis=200)
    assert one_well["precision"] == 1.0 and 0.45 < one_well["iou"] < 0.55
    assert abs(one_well["hausdorff"] - 5.0) < 0.1  # the missed well is 5 away from the found one
    # the missed well (x in [6, 9]) reaches 1.5 = 3 box widths into the safe region
    assert one_well["missed_depth_boxes"] == pytest.approx(3.0) and one_well["overclaimed_depth_boxes"] == 0.0
    shifted = compare_boxes(sc, boxes(centres + [0.5, 0.0]), grid_points_per_axis=200)
    assert shifted["iou"] < perfect["iou"] and shifted["precision"] < 1.0
    # a band one box (0.5) wide missed at each well's left edge, claimed at its right
    assert shifted["missed_depth_boxes"] == pytest.approx(1.0)
    assert shifted["overclaimed_depth_boxes"] == pytest.approx(1.0)


def test_sampled_comparison_brackets_the_grid_value_and_is_reproducible():
    toy = make_scenario("toy", sv_policy="none")
    sc = NumpyBackend(toy)
    xs = np.concatenate([np.arange(1.25, 4.0, 0.5), np.arange(6.25, 9.0, 0.5)])
    centres = np.stack(np.meshgrid(xs, np.arange(0.25, 10.0, 0.5), indexing="ij"), -1).reshape(-1, 2)
    one_well = SafeSet.uniform(centres[centres[:, 0] < 5], 0.25, ("x", "y"))
    exact = compare_boxes(sc, one_well, grid_points_per_axis=400)
    points = uniform_points(toy, 20000, seed=3)
    assert np.array_equal(points, uniform_points(toy, 20000, seed=3))
    assert ((points >= toy.lower) & (points <= toy.upper)).all()
    sampled = compare_sampled(one_well, points, reference_safe(sc, points))
    assert sampled["sample_points"] == 20000 and "hausdorff" not in sampled
    for name in ("iou", "precision", "recall"):
        low, high = sampled[f"{name}_interval"]
        assert low <= sampled[name] <= high and high - low < 0.05
        assert low - 0.01 <= exact[name] <= high + 0.01  # the grid's value (itself a fine quadrature) inside


def test_compare_cli_on_a_campaign(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "brake"\n[actions]\nmode = "adversarial"\n'
                   '[quantify]\ndelta0 = 2.0\ndelta_min = 1.0\n[farm]\nexecutor = "local"\n')
    out = tmp_path / "q"
    assert subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(out)],
                          capture_output=True).returncode == 0
    r = subprocess.run([sys.executable, "-m", "farm", "compare", str(out), "--grid", "60"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    metrics = json.loads((out / "compare.json").read_text())
    assert metrics["precision"] >= 0.98 and metrics["iou"] >= 0.95
    assert (out / "plots" / "compare.png").exists()
