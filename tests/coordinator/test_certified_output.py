"""Certified output: the set quantify exports passes validate, and the guarantee reads
in plain words built from the config's own values."""

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from coordinator.reference import reference_safe
from farm import api
from scenarios.registry import make_backend

LF_IDM = {"name": "lead-follow", "sv_policy": "idm"}
GAMMA_STAR = {"mode": "adversarial"}


def validate_set(path, algorithm, delta, seed=0, eps=0.001, beta=0.01):
    return api.validate({"scenario": LF_IDM, "actions": GAMMA_STAR,
                         "validate": {"algorithm": algorithm, "epsilon": eps, "beta": beta, "delta": delta,
                                      "horizon": 50, "domain_set": str(path)},
                         "farm": {"executor": "local", "seed": seed}})


# CI: seed 0 and seed 2 (the regression); the soak tests all five
@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.soak), 2, pytest.param(3, marks=pytest.mark.soak),
                                  pytest.param(4, marks=pytest.mark.soak)])
def test_the_exported_set_certifies_with_delta_and_eps_delta(tmp_path, seed):
    # the README's example (Gamma*, delta 2 -> 1); seed 2 once exported a set that
    # VAL^delta refuted, through a certificate missing the witness of a re-decided state;
    # refined everywhere, as it was then (margin sets: tests/farm/test_margin_campaign.py)
    result = api.quantify("examples/lead_follow_idm.toml", out=tmp_path / "q", farm__executor="local",
                          farm__seed=seed, quantify__refine="all")
    assert result.summary["converged"] and "each centre was simulated" in result.guarantee
    for algorithm in ("delta", "eps-delta"):
        cert = validate_set(tmp_path / "q" / "safe_set.parquet", algorithm, result.half_width, seed=seed)
        assert cert.certified, (algorithm, cert.statement)
    assert cert["n_run"] == 4603


def test_a_box_union_that_no_run_leaves_is_certified_at_delta_1(tmp_path):
    # boxes of half-width 0.25 centred on the true idm safe set under Gamma*: its runs
    # stay in the true safe set, within a box of it; Definition 1 only asks that *some*
    # delta-covering works, and validation uses the set's own centres
    backend = make_backend(LF_IDM)
    sc = backend.scenario
    axes = [np.arange(lo + 0.25, hi, 0.5) for lo, hi in zip(sc.lower, sc.upper)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, sc.n)
    safe = grid[reference_safe(backend, grid)]
    assert 10_000 < len(safe) < len(grid)
    table = {name: safe[:, i] for i, name in enumerate(sc.state_names)}
    pq.write_table(pa.table({**table, "half_width": np.full(len(safe), 0.25)}), tmp_path / "truth.parquet")
    for algorithm in ("eps-delta", "delta"):
        cert = validate_set(tmp_path / "truth.parquet", algorithm, 1.0)
        assert cert.certified, (algorithm, cert.statement)


def test_the_guarantee_in_plain_words_carries_the_config_values(tmp_path):
    cfg = {"scenario": LF_IDM, "actions": {"mode": "uniform"},
           "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.01, "beta": 0.05, "horizon": 30},
           "farm": {"executor": "local", "batch_size": 256}}
    summary = api.quantify(cfg, out=tmp_path / "q").summary
    plain, formal = summary["guarantee"], summary["guarantee_formal"]
    for words in ("With 95% confidence", "at most 1% of scenarios", "drawn uniformly", "[-5, 3] m/s^2",
                  "collide", "within 3 s", "delta = 2"):
        assert words in plain, (words, plain)
    assert "(0.01, 2)-almost robustly controlled forward invariant w.r.t. Gamma" in formal
    assert "confidence 0.95" in formal and "beta_i = 6 beta / (pi^2 i^2)" in formal


def test_a_certificate_lists_only_the_parameters_its_algorithm_used():
    section = {"domain": {"p10": [40.0, 70.0]}, "horizon": 20}
    base = {"scenario": {"name": "lead-follow", "sv_policy": "brake"}, "farm": {"executor": "local"}}
    eps = api.validate({**base, "validate": {**section, "algorithm": "eps", "epsilon": 0.01}})
    assert "delta" not in eps.data and eps["epsilon"] == 0.01 and "beta" in eps.data
    det = api.validate({**base, "actions": GAMMA_STAR, "validate": {**section, "algorithm": "delta"}})
    assert "epsilon" not in det.data and "beta" not in det.data and det["delta"] == 1.0
    for cert in (eps, det):
        assert cert.guarantee and cert.statement and cert.guarantee != cert.statement
