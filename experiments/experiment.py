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


def main(run: Callable[[list[str]], None], render: Callable[[], object]) -> None:
    """``script.py --render``: the docs from the JSON only; ``script.py [args]``: ``run(args)``."""
    if sys.argv[1:] == ["--render"]:
        print(render())
    else:
        run(sys.argv[1:])
