"""benchmarks/ray_call_floor.py: Ray's cost per actor call as the driver process pays it,
measured in a process of its own (it starts and stops its own Ray)."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_floor_is_measured_every_way_and_priced_for_the_bench_case():
    r = subprocess.run([sys.executable, "benchmarks/ray_call_floor.py", "--calls", "40", "--repeat", "1"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = re.findall(r"^(one at a time|pipelined|compiled|plain, 5 ms run|compiled, 5 ms run)\s+([\d.]+)\s+([\d.]+)$",
                      r.stdout, re.M)
    assert [mode for mode, *_ in rows] == ["one at a time", "pipelined", "compiled", "plain, 5 ms run",
                                           "compiled, 5 ms run"]
    # a call costs the process something, and its main thread no more than the whole process
    assert all(0 < float(main) <= float(process) + 0.05 for _, process, main in rows)
    assert re.search(r"1,300 calls at the one-at-a-time median: [\d.]+ CPU-s of the 2.5", r.stdout)
