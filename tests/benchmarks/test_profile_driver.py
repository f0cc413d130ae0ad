"""benchmarks/profile_driver.py times the functions it names on the driver's main thread of a
real `quantify` process (a real subprocess, the in-process executor: nothing benchmarked)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from profile_driver import profile  # noqa: E402

CONFIG = """[scenario]
name = "lead-follow"
sv_policy = "idm"
[quantify]
delta0 = 2.0
delta_min = 2.0
epsilon = 0.01
beta = 0.1
horizon = 20
certify = false
[farm]
executor = "local"
seed = 0
"""


def test_the_named_functions_are_timed_on_the_main_thread_and_every_thread_is_read(tmp_path):
    config = tmp_path / "tiny.toml"
    config.write_text(CONFIG)
    # Campaign.run: once a campaign; SPE.apply: inside it, once a change
    functions = "coordinator.driver.campaign:Campaign.run,coordinator.spe:SPE.apply"
    row = profile(str(config), str(tmp_path / "out"), functions)
    assert row["committed"] > 0
    assert row["calls"]["Campaign.run"] == 1 and row["calls"]["SPE.apply"] > 0
    assert 0 < row["cpu"]["SPE.apply"] < row["cpu"]["Campaign.run"]  # nested: apply runs inside the loop
    assert row["threads"]["MainThread"] >= row["cpu"]["Campaign.run"]
