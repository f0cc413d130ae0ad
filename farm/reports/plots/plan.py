"""The plan figure (``scenario-farm plan``): time to the result per worker count."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from farm.reports.plots.style import SAFE_COLOUR, _save


def draw_plan(path: Path, result: dict, near_best: float) -> Path:
    """plan.png: the virtual farm's time to the result against the workers (farm/jobs/planning.py)."""
    rows = result["rows"]
    w = [r["workers"] for r in rows]
    t = [r["virtual_elapsed_s"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.plot(w, [t[0] * w[0] / x for x in w], color="#999999", linestyle="--", label="every worker busy (ideal)")
    ax.plot(w, t, marker="o", color=SAFE_COLOUR, label="virtual farm")
    ax.axvline(result["recommended_workers"], color="#666666", linewidth=0.8,
               label=f"fewest within {near_best:g}x of the fastest: {result['recommended_workers']:,}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("workers")
    ax.set_ylabel("time to the result [s]")
    ax.set_title(f"Time to the result, a run of {result['run_time']:g} s")
    ax.legend()
    fig.tight_layout()
    return _save(fig, path)
