"""What the experiment scripts share: the stamp of the machine their JSON was made on, and
their command line (run and write the JSON, or ``--render`` the docs from it alone)."""

from __future__ import annotations

import os
import platform
import sys
import time
from typing import Callable

import numpy as np


def machine_stamp(**extra) -> dict:
    """Date, machine, Python and numpy versions (and ``extra``) for an experiment's JSON."""
    return {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.machine()}, {os.cpu_count()} cores",
            "python": platform.python_version(), "numpy": np.__version__, **extra}


def write_doc(path, lines: list[str]):
    """A rendered doc: ``lines`` joined, one newline at the end. Returns ``path``."""
    path.write_text("\n".join(lines) + "\n")
    return path


def main(run: Callable[[list[str]], None], render: Callable[[], object]) -> None:
    """``script.py --render``: the docs from the JSON only; ``script.py [args]``: ``run(args)``."""
    if sys.argv[1:] == ["--render"]:
        print(render())
    else:
        run(sys.argv[1:])


def run_in_process(cfg):
    """One campaign of ``cfg`` on the in-process executor (the committed sequence does not
    depend on the executor): -> its counters, algorithm, back end and seconds."""
    from farm.jobs.campaign_setup import build_algorithm, build_campaign
    from farm.execution.process import spec_of
    from farm.execution.local import LocalExecutor

    executor = LocalExecutor(spec_of(cfg))
    algo = build_algorithm(cfg, executor.simulator)
    t0 = time.perf_counter()
    counters = build_campaign(cfg, algo, executor.simulator, executor).run()
    return counters, algo, executor.simulator.backend, time.perf_counter() - t0
