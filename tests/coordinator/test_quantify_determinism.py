import json
import subprocess
import sys

from farm import config as config_mod
from farm.jobs.quantification import run


def small_config(**quantify):
    raw = {"scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
           "quantify": {"delta0": 4.0, "delta_min": 2.0, "epsilon": 0.01, "beta": 0.1, "horizon": 30, **quantify},
           "farm": {"executor": "local", "batch_size": 256, "seed": 3}}
    return config_mod.normalize(raw)


def test_same_config_and_seed_give_the_same_result_hash(tmp_path):
    a = run(small_config(), tmp_path / "a", resume=False)
    b = run(small_config(), tmp_path / "b", resume=False)
    assert a["result_hash"] == b["result_hash"] and a["runs_committed"] == b["runs_committed"]
    cfg = small_config().with_overrides({"farm.seed": 4})
    assert run(cfg, tmp_path / "c", resume=False)["result_hash"] != a["result_hash"]


def test_same_result_in_a_fresh_process(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[actions]\nmode = "uniform"\n'
                   '[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nepsilon = 0.01\nhorizon = 30\n'
                   '[farm]\nexecutor = "local"\nbatch_size = 256\nseed = 3\n')
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(cfg), "--out", str(tmp_path / "p")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    here = run(small_config(), tmp_path / "q", resume=False)
    assert json.loads((tmp_path / "p" / "summary.json").read_text())["result_hash"] == here["result_hash"]
