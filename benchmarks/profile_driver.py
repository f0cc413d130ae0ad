"""Where the driver's CPU goes, function by function: the bench case of
bench_coordinator_cpu.py (issue 54 point 2) and its tiny run, each a whole `quantify`
process, with thread-CPU timers on the driver's main thread around named functions and
the CPU of every thread of the process. The case less the tiny run is the marginal cost
the bar is about; this prints it per function and per thread (a profile, not a target:
nested functions overlap, e.g. ``Campaign._commit`` holds ``SPE.apply``).

    python benchmarks/profile_driver.py [--functions module:Class.method,...] [--keep DIR]

Timers cost ~1 us a call: the process runs a little slower than unprofiled. A sampling
profiler (py-spy) counts threads blocked in Ray's C++ as busy; these timers do not.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from bench_coordinator_cpu import CASE, checkout_env, quantify_child  # noqa: E402

FUNCTIONS = ("coordinator.driver.campaign:Campaign.run,coordinator.driver.campaign:Campaign._commit,"
             "coordinator.driver.campaign:Campaign._fill,coordinator.driver.campaign:Campaign._settle,"
             "coordinator.driver.campaign:Campaign._use_replacement,coordinator.spe:SPE.apply,"
             "coordinator.spe_certification:SPECertification._edge_mask,coordinator.rescreen:Rescreen.next_event,"
             "coordinator.rescreen:Rescreen._changes,coordinator.stable_sampler:StableSampler.moved,"
             "coordinator.stable_sampler:StableSampler.draw,coordinator.driver.replacements:ReplacementQueue.send,"
             "coordinator.driver.replacements:ReplacementQueue.fetch,"
             "farm.ray_runtime.executor:RayExecutor.submit,farm.ray_runtime.executor:RayExecutor.result")

# the child: timers patched in before the CLI is imported, then the CLI's own entry; every
# thread's CPU read from /proc while it runs (threads may end before the process does)
_CHILD = r"""
import collections, functools, importlib, json, os, resource, sys, threading, time
started = time.monotonic()
specs, argv = sys.argv[1].split(","), sys.argv[2:]
main_thread = threading.main_thread()
cpu, calls = collections.Counter(), collections.Counter()

def timed(owner, name, label):
    f = getattr(owner, name)
    @functools.wraps(f)
    def wrapper(*a, **k):
        if threading.current_thread() is not main_thread:
            return f(*a, **k)
        t = time.thread_time()
        try:
            return f(*a, **k)
        finally:
            cpu[label] += time.thread_time() - t
            calls[label] += 1
    setattr(owner, name, wrapper)

for spec in specs:
    module, _, path = spec.partition(":")
    owner = importlib.import_module(module)
    *outer, name = path.split(".")
    for part in outer:
        owner = getattr(owner, part)
    timed(owner, name, path)

threads = {}
tick = os.sysconf("SC_CLK_TCK")
def read_threads():
    named = {t.native_id: t.name for t in threading.enumerate()}  # the OS names every Python thread "python"
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            with open(f"/proc/self/task/{tid}/comm") as f:
                name = f.read().strip()
        except OSError:
            continue
        threads[tid] = (named.get(int(tid), name), (int(fields[11]) + int(fields[12])) / tick)
def poll():
    while True:
        read_threads()
        time.sleep(0.5)
threading.Thread(target=poll, name="profile-poll", daemon=True).start()

from farm.cli.commands import main
code = main(argv)
read_threads()
per_thread = collections.Counter()
for name, seconds in threads.values():
    per_thread[name] += seconds
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"code": code, "cpu": cpu, "calls": calls, "threads": per_thread, "wall_s": time.monotonic() - started,
                  "cpu_s": usage.ru_utime + usage.ru_stime, "system_s": usage.ru_stime,
                  "max_rss_mb": usage.ru_maxrss / 1024}))
"""


def profile(config: str, out: str, functions: str, checkout: str | None = None, who: str = "profile_driver") -> dict:
    """One profiled `quantify` of ``config`` into ``out``: per function its main-thread CPU
    ("cpu") and calls, per thread its CPU ("threads"), the process's wall, CPU and peak
    memory, and the committed runs (``checkout``: its packages first on the path)."""
    return quantify_child(_CHILD, config, out, who, first_args=(functions,), env=checkout_env(checkout), cwd=checkout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--functions", default=FUNCTIONS, help="module:Class.method,... (the driver's main thread)")
    ap.add_argument("--keep", help="write the configs and campaigns here (default: a temporary directory)")
    args = ap.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="profile_driver_")
    os.makedirs(work, exist_ok=True)
    rows = {}
    for name, delta_min in (("tiny", 2.0), ("case", 0.5)):
        config = os.path.join(work, f"{name}.toml")
        with open(config, "w") as f:
            f.write(CASE.format(delta_min=delta_min))
        rows[name] = profile(config, os.path.join(work, name), args.functions)
    tiny, case = rows["tiny"], rows["case"]
    runs = case["committed"] - tiny["committed"]
    print(f"the bench case less its tiny run: {runs:,} committed runs (machine: {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.1f})")
    print(f"{'function (main thread)':<44} {'calls':>8} {'case CPU-s':>10} {'tiny':>6} {'marginal':>8}")
    for label in sorted(case["cpu"], key=lambda k: -(case["cpu"][k] - tiny["cpu"].get(k, 0.0))):
        c, t = case["cpu"][label], tiny["cpu"].get(label, 0.0)
        print(f"{label:<44} {case['calls'][label]:>8,} {c:>10.2f} {t:>6.2f} {c - t:>8.2f}")
    print(f"{'thread':<44} {'':>8} {'case CPU-s':>10} {'tiny':>6} {'marginal':>8}")
    for name in sorted(case["threads"], key=lambda k: -(case["threads"][k] - tiny["threads"].get(k, 0.0))):
        c, t = case["threads"][name], tiny["threads"].get(name, 0.0)
        if c >= 0.05:
            print(f"{name:<44} {'':>8} {c:>10.2f} {t:>6.2f} {c - t:>8.2f}")


if __name__ == "__main__":
    main()
