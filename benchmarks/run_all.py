"""Run every benchmark in turn; each prints its own figure, and its targets met or
MISSED (benchmarks/targets.py). Exit 1 if a benchmark failed or missed a target, naming them.

    python benchmarks/run_all.py
    python benchmarks/run_all.py --list    # what it would run, and nothing else
"""

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
BENCHMARKS = [["bench_numpy.py"], ["bench_coordinator.py"], ["bench_campaign.py"],
              ["bench_campaign.py", "--delta-min", "0.125", "--no-certify"], ["bench_ray.py"],
              ["bench_coordinator_cpu.py"], ["bench_scaling.py", "--no-write"], ["bench_virtual.py", "--no-write"],
              ["bench_sumo.py"], ["bench_sumo_ray.py"], ["bench_validate_set.py"], ["bench_high_dimension.py"],
              ["bench_result_phase.py"]]

if __name__ == "__main__":
    if sys.argv[1:] == ["--list"]:
        print("\n".join(" ".join(["python", os.path.join("benchmarks", name), *args]) for name, *args in BENCHMARKS))
        sys.exit(0)
    failed = []
    for name, *args in BENCHMARKS:  # every one is there: a missing one fails, not skipped in silence
        command = " ".join([name, *args])
        print(f"== {command}", flush=True)
        if subprocess.run([sys.executable, os.path.join(HERE, name), *args]).returncode != 0:
            failed.append(command)
    if failed:
        sys.exit(f"run_all: {len(failed)} of {len(BENCHMARKS)} benchmarks failed or missed a target: {', '.join(failed)}")
