"""Recordings are real MCAP files: read back by the plain mcap reader."""

import json
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader

from farm.directory.recording import read_recording, write_recording


def test_round_trip_and_plain_reader(tmp_path):
    runs = [{"sample_index": i, "trajectory": np.random.default_rng(i).random((n, 3)) * 10, "outcome": o}
            for i, n, o in [(3, 5, "failure"), (9, 2, "horizon"), (40, 7, "truncated")]]
    path = tmp_path / "r.mcap"
    write_recording(path, scenario_name="lead-follow", state_names=["v0", "v1", "p10"], dt=0.1, runs=runs,
                    metadata={"config_hash": "abc", "seed": "7"})
    back = read_recording(path)
    for run in runs:
        np.testing.assert_array_equal(back["runs"][run["sample_index"]]["trajectory"], run["trajectory"])
        assert back["runs"][run["sample_index"]]["outcome"] == run["outcome"]
    assert back["metadata"] == {"config_hash": "abc", "seed": "7"}
    assert back["runs"][3]["metadata"] == {"sample_index": "3", "outcome": "failure", "length": "5", "seed": "7",
                                           "config_hash": "abc"}
    with open(path, "rb") as fh:
        messages = list(make_reader(fh).iter_messages())
    assert len(messages) == 14
    schema, channel, message = messages[0]
    assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
    # one topic per run, every run from log time 0: Foxglove overlays them
    assert {m[1].topic for m in messages} == {f"/scenario/lead-follow/run/{i}" for i in (3, 9, 40)}
    assert [m[2].log_time for m in messages if m[1].topic.endswith("/40")] == [k * 100_000_000 for k in range(7)]
    assert set(json.loads(schema.data)["properties"]) == {"sample_index", "step", "time", "v0", "v1", "p10", "outcome"}
    times = [m[2].log_time for m in messages]
    assert times == sorted(times)  # written in log-time order
    layout = json.loads(path.with_suffix(".layout.json").read_text())
    series = [p["value"] for panel in layout["configById"].values() for p in panel["paths"]]
    assert len(series) == 3 * 3 and {v.rsplit(".", 1)[0] for v in series} == {m[1].topic for m in messages}


def test_damaged_recording_is_a_clear_error(tmp_path):
    path = tmp_path / "r.mcap"
    write_recording(path, scenario_name="toy", state_names=["x", "y"], dt=0.1,
                    runs=[{"sample_index": 0, "trajectory": np.zeros((4, 2)), "outcome": "horizon"}], metadata={})
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(ValueError, match="not a Scenario Farm recording"):
        read_recording(path)


def test_counterexample_recording_and_replay(tmp_path):
    cfg = tmp_path / "v.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "brake"\n[actions]\nmode = "uniform"\n'
                   '[validate]\nalgorithm = "eps"\n[farm]\nseed = 4\n')
    out = tmp_path / "v"
    r = subprocess.run([sys.executable, "-m", "farm", "validate", str(cfg), "--out", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 1, r.stderr
    cert = json.loads((out / "certificate.json").read_text())
    rec = read_recording(out / "counterexample.mcap")
    index = cert["counterexample"]["sample_index"]
    np.testing.assert_array_equal(rec["runs"][index]["trajectory"], np.array(cert["counterexample"]["trajectory"]))
    r = subprocess.run([sys.executable, "-m", "farm", "replay", str(out), "--sample", str(index)],
                       capture_output=True, text=True)
    # a reproduced counterexample is a finding: exit 1, as README's table says (issue 54: it was 0)
    assert r.returncode == 1 and "replay reproduces the counterexample" in r.stdout, r.stdout + r.stderr


def test_quantification_recording_matches_ledger_and_replay(tmp_path):
    cfg = tmp_path / "q.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[actions]\nmode = "uniform"\n'
                   '[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nepsilon = 0.01\n[farm]\nexecutor = "local"\n'
                   '[record]\nquantify_runs = 5\n')
    out = tmp_path / "q"
    assert subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(out)]).returncode == 0
    recorded = {}
    for path in (out / "recordings").glob("*.mcap"):
        recorded.update(read_recording(path)["runs"])
    assert len(recorded) == 5 and all(r["outcome"] == "failure" for r in recorded.values())
    index = sorted(recorded)[2]
    r = subprocess.run([sys.executable, "-m", "farm", "replay", str(out), "--sample", str(index)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "identical to runs-" in r.stdout and "replay matches the record" in r.stdout
