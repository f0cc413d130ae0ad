"""certificate.json through farm.reports.certificate.Certificate: real validations write only the
parameters their algorithm used, read back key for key and write back byte for byte; an
older file (``statement`` without ``guarantee_formal``, unknown keys) still reads; replay
reads the counterexample through it; and a set of mixed box sizes validates."""

import json

import numpy as np
import pytest

from coordinator.safe_set import SafeSet
from farm import api
from farm.reports.certificate import Certificate
from farm.jobs.rerun import replay
from farm.directory.storage import CampaignError
from scenarios.toy import Toy

TOY = {"name": "toy", "sv_policy": "none"}


def validate_toy(out, algorithm, section, delta=0.25):
    return api.validate({"scenario": TOY, "actions": {"mode": "uniform"},
                         "validate": {**section, "algorithm": algorithm, "epsilon": 0.01, "beta": 0.1,
                                      "delta": delta, "horizon": 20},
                         "farm": {"executor": "local", "seed": 0}}, out=out)


@pytest.mark.parametrize("algorithm,parameters", [("eps", ["epsilon", "beta"]),
                                                  ("eps-delta", ["epsilon", "beta", "delta"])])
def test_a_real_certificate_reads_back_key_for_key_and_writes_back_byte_for_byte(tmp_path, algorithm, parameters):
    cert = validate_toy(tmp_path / "v", algorithm, {"domain": {"x": [1.0, 4.0]}})
    text = (tmp_path / "v" / "certificate.json").read_text()
    data = json.loads(text)
    assert cert.certified and cert.counterexample is None
    assert list(data)[:5] == ["verdict", "guarantee", "guarantee_formal", "statement", "algorithm"]
    assert list(data)[5 : 5 + len(parameters)] == parameters and ("delta" in data) == ("delta" in parameters)
    back = Certificate.read(tmp_path / "v")
    assert back == cert and list(back.to_json().items()) == list(data.items())
    assert back.statement == back.guarantee_formal == data["statement"]
    back.write(tmp_path)
    assert (tmp_path / "certificate.json").read_text() == text
    assert cert["n_run"] == cert.n_run == cert.n_required  # the JSON key, for code written against the dict


def test_an_older_certificate_reads_and_replay_takes_the_counterexample_through_it(tmp_path):
    cert = validate_toy(tmp_path / "v", "eps", {"domain": {"x": [4.0, 6.0]}})
    assert not cert.certified and cert.counterexample["sample_index"] == cert.n_run - 1
    ok, finding, text = replay(tmp_path / "v", cert.n_run - 1)
    assert ok and finding and "replay reproduces the counterexample" in text  # a finding: exit 1
    data = json.loads((tmp_path / "v" / "certificate.json").read_text())
    del data["guarantee_formal"]  # before it had its own key, the formal words were only "statement"
    data["reviewed_by"] = "someone"
    (tmp_path / "v" / "certificate.json").write_text(json.dumps(data))
    older = Certificate.read(tmp_path / "v")
    assert older.guarantee_formal == cert.guarantee_formal and older.extra == {"reviewed_by": "someone"}
    assert older.counterexample == cert.counterexample
    assert replay(tmp_path / "v", cert.n_run - 1)[0]


def test_a_certificate_that_lies_is_a_one_line_error(tmp_path):
    validate_toy(tmp_path, "eps", {"domain": {"x": [1.0, 4.0]}})
    data = json.loads((tmp_path / "certificate.json").read_text())
    (tmp_path / "certificate.json").write_text(json.dumps({**data, "n_run": "all"}))
    with pytest.raises(CampaignError, match="certificate.json: n_run is 'all'; expected int"):
        Certificate.read(tmp_path)
    del data["verdict"]
    (tmp_path / "certificate.json").write_text(json.dumps(data))
    with pytest.raises(CampaignError, match="certificate.json: lacks verdict"):
        Certificate.read(tmp_path)


@pytest.mark.skip(reason="superseded by boundary refinement: a mixed set validates as its own covering "
                         "(tests/farm/test_band_campaign.py)")
def test_a_set_of_mixed_box_sizes_validates(tmp_path):
    # the well x in [1, 4] (invariant) as boxes of half-width 0.5 and, on its right, 0.25
    coarse = np.array([[x, y] for x in (1.5, 2.5) for y in np.arange(0.5, 10.0, 1.0)])
    fine = np.array([[x, y] for x in (3.25, 3.75) for y in np.arange(0.25, 10.0, 0.5)])
    safe_set = SafeSet(np.vstack([coarse, fine]), np.r_[np.full(len(coarse), 0.5), np.full(len(fine), 0.25)],
                       Toy.state_names)
    safe_set.to_parquet(tmp_path / "mixed.parquet")
    section = {"domain_set": str(tmp_path / "mixed.parquet")}
    for algorithm in ("eps", "eps-delta"):
        cert = validate_toy(None, algorithm, section, delta=0.5)
        assert cert.certified and "union of 60 boxes of half-widths 0.25 to 0.5" in cert.domain, cert.guarantee
    with pytest.raises(ValueError, match="below the set's largest box half-width 0.5"):
        validate_toy(None, "eps-delta", section, delta=0.25)
