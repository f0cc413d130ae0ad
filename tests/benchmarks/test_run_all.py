"""benchmarks/run_all.py runs every benchmark the README says it runs, and a missed target
fails it (benchmarks/targets.py): real subprocesses, nothing benchmarked."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_run_all_lists_every_benchmark_the_readme_names_and_each_exists():
    r = subprocess.run([sys.executable, "benchmarks/run_all.py", "--list"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    listed = set(re.findall(r"benchmarks/(bench_\w+\.py)", r.stdout))
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Benchmarks and evidence"):readme.index("## Exit codes and errors")]
    assert set(re.findall(r"benchmarks/(bench_\w+\.py)", section)) <= listed
    assert "bench_virtual.py" in listed and all((ROOT / "benchmarks" / name).exists() for name in listed)


def test_a_missed_target_exits_1_naming_it_and_met_ones_exit_0():
    code = "import targets, sys; targets.check('met one', True); targets.check(sys.argv[1], sys.argv[1] == 'x'); " \
           "targets.finish()"
    missed = subprocess.run([sys.executable, "-c", code, "runs/s >= 5"], cwd=ROOT / "benchmarks", capture_output=True,
                            text=True)
    assert missed.returncode == 1 and "target missed: runs/s >= 5" in missed.stderr and "met one" not in missed.stderr
    met = subprocess.run([sys.executable, "-c", code, "x"], cwd=ROOT / "benchmarks", capture_output=True, text=True)
    assert met.returncode == 0 and met.stderr == ""
