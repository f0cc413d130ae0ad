"""Boundary refinement end to end (issue 36): a band campaign exports a set of mixed box
sizes that validate certifies (VAL^delta and VAL^eps-delta at its finest half-width), as
accurate as the all-refined set against the model reference; refine = "all" is the
campaign as it was (same result_hash and config_hash)."""

import numpy as np
import pyarrow.parquet as pq

from coordinator.reference import compare_boxes
from farm import api
from scenarios.registry import make_backend

EXAMPLE = "examples/lead_follow_idm.toml"


def validate_set(path, algorithm, delta):
    return api.validate({"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "adversarial"},
                         "validate": {"algorithm": algorithm, "epsilon": 0.001, "beta": 0.01, "delta": delta,
                                      "horizon": 50, "domain_set": str(path)},
                         "farm": {"executor": "local", "seed": 0}})


def test_refine_all_is_the_campaign_as_it_was(tmp_path):
    """The main example refined everywhere gives the hash it gave before margin refinement
    became the deterministic default (README "Refinement: where the runs go")."""
    after = api.quantify(EXAMPLE, out=tmp_path / "all", farm__executor="local", quantify__refine="all").summary
    assert after["result_hash"] == "f7802109126e4ff7"
    default = api.quantify(EXAMPLE, out=tmp_path / "default", farm__executor="local").summary
    assert default["refine"] == "margin" and default["result_hash"] != after["result_hash"]


def test_a_band_campaign_exports_a_mixed_set_that_certifies(tmp_path):
    full = api.quantify(EXAMPLE, out=tmp_path / "all", farm__executor="local", quantify__refine="all")
    band = api.quantify(EXAMPLE, out=tmp_path / "band", farm__executor="local", quantify__refine="band")
    s = band.safe_set
    assert band.summary["converged"] and not s.is_uniform
    assert (s.finest, s.coarsest) == (1.0, 2.0)
    assert (band.summary["delta_final"], band.summary["half_width_max"]) == (1.0, 2.0)
    assert "near its boundary toward failure" in band.guarantee and "up to 2" in band.guarantee
    assert len(s) < len(full.safe_set) / 1.5
    assert band.summary["runs_committed"] < full.summary["runs_committed"]
    table = pq.read_table(tmp_path / "band" / "safe_set.parquet")
    assert sorted(set(table.column("half_width").to_pylist())) == [1.0, 2.0]
    # the same volume to within the finest boxes along the boundary, and as accurate
    assert abs(s.volume_union() - full.safe_set.volume_union()) < 0.01 * full.safe_set.volume_union()
    for algorithm in ("delta", "eps-delta"):
        cert = validate_set(tmp_path / "band" / "safe_set.parquet", algorithm, s.finest)
        assert cert.certified, (algorithm, cert.statement)
        assert "max(its half-width, delta = 1)" in cert.guarantee
    backend = make_backend({"name": "lead-follow", "sv_policy": "idm"})
    acc_band = compare_boxes(backend, s, grid_points_per_axis=60)
    acc_full = compare_boxes(backend, full.safe_set, grid_points_per_axis=60)
    assert acc_band["precision"] >= acc_full["precision"] - 0.005
    assert acc_band["iou"] >= acc_full["iou"] - 0.01
    assert np.isfinite(acc_band["iou"])
