"""A benchmark's targets, in one place: each target line says met or MISSED, and a
benchmark that missed one exits 1 naming them (``finish``), so that
benchmarks/run_all.py, and whoever runs it, sees a missed target without reading the lines."""

from __future__ import annotations

import sys

_missed: list[str] = []


def check(what: str, met: bool) -> str:
    """Record target ``what`` (e.g. "numpy uniform >= 3e+07 steps/s"); -> "met" or
    "MISSED", for the benchmark's own line."""
    if not met:
        _missed.append(what)
    return "met" if met else "MISSED"


def finish() -> None:
    """The benchmark's end: exit 1 with one line naming every missed target, if any."""
    if _missed:
        sys.exit(f"{sys.argv[0]}: target{'s' * (len(_missed) != 1)} missed: {'; '.join(_missed)}")
