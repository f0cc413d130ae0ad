"""Where an estimate's failures fell (``DIR/estimates/<name>/failures.png``): the runs'
starts on the planes of pairs of state variables, failures in red over the others, and
per stratum its mass under D, its share of the runs and its share of the failure rate.

The starts are drawn per stratum (Neyman allocation), not from D: the strata along the
set's boundary are sampled far more densely than their mass; the bars say by how much.
"""

from __future__ import annotations

import textwrap
from itertools import combinations
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless, before pyplot

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from farm.directory.files import atomic_write  # noqa: E402

SHOWN = 20_000  # runs drawn at most (failures first): a scatter of millions says no more
PLANES = 3  # pairs of state variables at most
LABEL_CHARS = 38  # an axis label's line on a 4.6-inch panel


def estimate_figure(state_names, labels: dict, starts: np.ndarray, failed: np.ndarray, report):
    """The figure: ``starts`` (R, n) of the committed runs, ``failed`` (R,) bool, and the
    estimate's ``report`` (its strata and interval); ``labels``: state name -> its axis
    label (``Scenario.label``: what it is and its unit)."""
    n = len(state_names)
    planes = list(combinations(range(n), 2))[:PLANES] if n > 1 else [(0, 0)]
    fig, axes = plt.subplots(1, len(planes) + 1, figsize=(4.6 * (len(planes) + 1), 4.2))
    order = np.concatenate([np.flatnonzero(failed), np.flatnonzero(~failed)])[:SHOWN]
    shown_ok, shown_bad = order[~failed[order]], order[failed[order]]
    for ax, (x, y) in zip(axes, planes):
        ax.scatter(starts[shown_ok, x], starts[shown_ok, y], s=2, c="#b0b0b0", label="no failure", rasterized=True)
        ax.scatter(starts[shown_bad, x], starts[shown_bad, y], s=3, c="#d62728", label="failure", rasterized=True)
        ax.set_xlabel(_label(state_names[x], labels))
        ax.set_ylabel(_label(state_names[y], labels))
    axes[0].legend(loc="best", fontsize=8, markerscale=4)
    strata = report.strata
    runs = np.array([s["runs"] for s in strata], dtype=float)
    mass = np.array([s["mass"] for s in strata])
    share = np.array([s["contribution"] for s in strata]) / max(report.estimate, 1e-300)
    pos = np.arange(len(strata))
    bars = axes[-1]
    bars.barh(pos - 0.27, mass, 0.27, label="mass under D", color="#4c72b0")
    bars.barh(pos, runs / max(runs.sum(), 1), 0.27, label="share of runs", color="#999999")
    bars.barh(pos + 0.27, share, 0.27, label="share of P(failure)", color="#d62728")
    bars.set_yticks(pos, [s["name"] for s in strata], fontsize=7)
    bars.invert_yaxis()
    bars.set_xlim(0, 1)
    bars.legend(loc="lower right", fontsize=7)
    fig.suptitle(f"P(failure) = {report.estimate:.4g}, {report.confidence:.0%} interval [{report.interval[0]:.4g}, "
                 f"{report.interval[1]:.4g}], {report.runs:,} runs ({len(shown_bad):,} failures shown)", fontsize=10)
    fig.tight_layout()
    return fig


def _label(name: str, labels: dict) -> str:
    return "\n".join(textwrap.wrap(labels.get(name, name), LABEL_CHARS))


def draw_estimate(path: Path, state_names, labels: dict, starts, failed, report) -> Path:
    fig = estimate_figure(state_names, labels, starts, failed, report)
    try:
        atomic_write(Path(path), lambda fh: fig.savefig(fh, format="png", dpi=110))
    finally:
        plt.close(fig)
    return Path(path)
