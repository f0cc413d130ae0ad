"""The custom-scenario guide (docs/custom_scenario.md) as a user runs it: its example
file quantifies from the console script on the Ray executor and from Python, with no
PYTHONPATH; a broken scenario is a one-line error, never a traceback."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "custom"


def clean_env():
    return {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


@pytest.fixture
def workdir(tmp_path):
    for name in ("approach.py", "approach.toml"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    return tmp_path


def one_line_error(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr)
    errors = [line for line in r.stderr.splitlines() if not line.startswith("scenario-farm: ") or "error" in line]
    assert len(errors) == 1 and "Traceback" not in r.stderr, r.stderr  # progress lines aside
    for w in words:
        assert w in r.stderr, r.stderr


def test_the_guide_example_quantifies_from_the_console_script_on_ray_and_from_python(workdir):
    cli = shutil.which("scenario-farm")
    assert cli, "the console script is installed with the package"
    r = subprocess.run([cli, "quantify", "approach.toml", "--out", "runs/ray"], cwd=workdir, env=clean_env(),
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    ray_summary = json.loads((workdir / "runs" / "ray" / "summary.json").read_text())
    code = ("from farm import api; r = api.quantify('approach.toml', out='runs/py', farm__executor='local'); "
            "print(r.result_hash, r.summary['boxes'], bool(r.contains([[0.0, 60.0]])[0]), "
            "bool(r.contains([[20.0, 3.0]])[0]))")
    r = subprocess.run([sys.executable, "-c", code], cwd=workdir, env=clean_env(), capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    result_hash, boxes, standing_far, fast_close = r.stdout.split()
    assert result_hash == ray_summary["result_hash"]  # Ray workers imported the same file
    assert int(boxes) == ray_summary["boxes"] > 100
    assert standing_far == "True" and fast_close == "False"  # at rest 60 m away: safe; 20 m/s at 3 m: not
    r = subprocess.run([cli, "report", "runs/py"], cwd=workdir, env=clean_env(), capture_output=True, text=True)
    assert r.returncode == 0 and "approach" in r.stdout, r.stderr


BROKEN = {
    "needs_an_argument": ("class Broken(Approach):\n    def __init__(self, wheelbase):\n        super().__init__()\n",
                          ["scenario.name", "could not be constructed", "sv_policy"]),
    "wrong_step_bound": ("class Broken(Approach):\n    def step_bound(self):\n        return 0.01\n",
                         ["scenario 'broken:Broken': step_bound() = 0.01", "Assumption 1"]),
    "not_a_scenario": ("class Broken:\n    pass\n", ["scenario.name", "Scenario"]),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_broken_scenario_is_a_one_line_error(workdir, case):
    body, words = BROKEN[case]
    (workdir / "broken.py").write_text("from approach import Approach\n\n" + body)
    (workdir / "b.toml").write_text((workdir / "approach.toml").read_text()
                                    .replace('"approach:Approach"', '"broken:Broken"')
                                    .replace('executor = "ray"', 'executor = "local"'))
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", "b.toml", "--out", "out"], cwd=workdir,
                       env=clean_env(), capture_output=True, text=True, timeout=120)
    one_line_error(r, *words)


def test_compare_on_a_scenario_it_cannot_model_is_a_one_line_error(workdir):
    (workdir / "u.toml").write_text((workdir / "approach.toml").read_text()
                                    .replace('mode = "adversarial"', 'mode = "uniform"')
                                    .replace('executor = "ray"', 'executor = "local"')
                                    .replace("delta_min = 0.5", "delta_min = 2.0"))
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", "u.toml", "--out", "out"], cwd=workdir,
                       env=clean_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "farm", "compare", "out"], cwd=workdir, env=clean_env(),
                       capture_output=True, text=True, timeout=120)
    one_line_error(r, "no reference safe set")
