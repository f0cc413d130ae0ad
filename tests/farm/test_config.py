import subprocess
import sys

import pytest

from farm import config as config_mod
from farm.config import ConfigError


def test_defaults_and_hash_ignore_fields_that_cannot_change_the_result():
    sc = {"name": "lead-follow"}
    a = config_mod.normalize({"scenario": sc})
    b = config_mod.normalize({"scenario": sc, "farm": {"workers": 16, "executor": "ray", "address": "auto"}})
    assert config_mod.config_hash(a) == config_mod.config_hash(b)
    c = config_mod.normalize({"scenario": sc, "farm": {"seed": 1}})
    assert config_mod.config_hash(a) != config_mod.config_hash(c)
    assert config_mod.changed_fields(a, c) == ["farm.seed"]


@pytest.mark.parametrize("raw, message", [
    ({"validate": {"epsilon": 1.5}}, "validate.epsilon: 1.5 is out of range; allowed [1e-09, 1)"),
    ({"validate": {"beta": 0}}, "validate.beta: 0.0 is out of range; allowed [1e-100, 1)"),
    ({"validate": {"horizon": 1}}, "validate.horizon: 1 is out of range; allowed [2, 100000]"),
    ({"validate": {"delta": -1}}, "validate.delta: -1.0 is out of range; allowed (0, inf]"),
    ({"validate": {"epsilon": float("nan")}}, "validate.epsilon: nan is out of range"),
    ({"quantify": {"algoritm": "spe"}}, "quantify.algoritm: unknown key; did you mean 'algorithm'?"),
    ({"quantfy": {}}, "unknown section [quantfy]; did you mean 'quantify'?"),
    ({"quantify": {"algorithm": "rrt"}}, "quantify.algorithm: 'rrt' is not allowed; allowed: spe, ae, delta-pruning, vs"),
    ({"farm": {"workers": "two"}}, "farm.workers: expected an integer, got str 'two'"),
    ({"quantify": {"delta0": 0.5, "delta_min": 1.0}}, "quantify.delta_min: 1.0 exceeds quantify.delta0"),
])
def test_bad_values_name_the_field_and_the_allowed_range(raw, message):
    with pytest.raises(ConfigError) as err:
        config_mod.normalize({"scenario": {"name": "lead-follow"}, **raw})
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "farm", *args], capture_output=True, text=True)


@pytest.mark.parametrize("body, field", [
    ('[validate]\nepsilon = 2.0\n', "validate.epsilon"),
    ('[validate]\ndomain = { p10 = [30.0, 90.0] }\n', "validate.domain.p10"),
    ('[validate]\ndomain = { p11 = [30.0, 60.0] }\n', "validate.domain.p11"),
    ('[scenario]\nname = "lead-follow"\nsv_policy = "aggressive"\n', "scenario.sv_policy"),
    ("", "scenario.name: required"),
    ('[actions]\nmode = "constant"\nvalue = [9.0]\n', "actions.value"),
    ('[scenario]\nname = "nosuch.module:Thing"\n', "scenario.name"),
])
def test_cli_bad_input_is_one_line_exit_2_no_traceback(tmp_path, body, field):
    cfg = tmp_path / "c.toml"
    cfg.write_text(body if not body or body.startswith("[scenario]") else '[scenario]\nname = "lead-follow"\n' + body)
    r = run_cli("validate", str(cfg))
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and field in r.stderr and "Traceback" not in r.stderr
    assert r.stdout == ""


def test_cli_missing_config_file(tmp_path):
    r = run_cli("validate", str(tmp_path / "nope.toml"))
    assert r.returncode == 2 and "no such config file" in r.stderr
