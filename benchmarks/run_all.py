"""Run every benchmark in turn; each prints its own figure.

    python benchmarks/run_all.py
"""

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
BENCHMARKS = [["bench_numpy.py"], ["bench_coordinator.py"], ["bench_campaign.py"],
              ["bench_campaign.py", "--delta-min", "0.125", "--no-certify"], ["bench_ray.py"],
              ["bench_coordinator_cpu.py"], ["bench_scaling.py", "--no-write"], ["bench_sumo.py"], ["bench_sumo_ray.py"]]

if __name__ == "__main__":
    failed = []
    for name, *args in BENCHMARKS:
        path = os.path.join(HERE, name)
        if not os.path.exists(path):
            continue
        print(f"== {' '.join([name, *args])}", flush=True)
        if subprocess.run([sys.executable, path, *args]).returncode != 0:
            failed.append(name)
    sys.exit(1 if failed else 0)
