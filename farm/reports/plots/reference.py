"""The comparison figure (``scenario-farm compare``): a set against its reference."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from coordinator.safe_set import SafeSet
from farm.reports.plots.layout import _label, _setting, _with_key

# agree safe, claimed but unsafe, safe but not claimed (agree unsafe stays white)
AGREE, OVERCLAIMED, MISSED = (0.75, 0.9, 0.75), (0.85, 0.1, 0.1), (0.2, 0.35, 0.9)


def draw_reference(path: Path, scenario, safe_set: SafeSet, x: int, y: int, varied: int | None, levels,
                   pixels: np.ndarray, truth: np.ndarray, res: int) -> None:
    """compare.png: slices (x, y) at ``levels`` of axis ``varied``, pixel by pixel
    (``pixels``, res x res per level) the set against the reference membership ``truth``
    (farm/reports/compare.py); the other axes at the pixels' own values (mid-range)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lo, hi = scenario.lower, scenario.upper
    pixels = pixels.reshape(len(levels), res * res, scenario.n)
    fig, axs = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 4.4), squeeze=False, layout="constrained")
    held = [a for a in range(scenario.n) if a not in (x, y, varied)]
    for ax, level, pts, ref in zip(axs[0], levels, pixels, truth.reshape(len(levels), res, res)):
        got = safe_set.contains(pts).reshape(res, res)
        img = np.zeros((res, res, 3)) + 1.0
        img[ref & got] = AGREE
        img[got & ~ref] = OVERCLAIMED
        img[ref & ~got] = MISSED
        ax.imshow(np.transpose(img, (1, 0, 2)), origin="lower", aspect="auto", extent=(lo[x], hi[x], lo[y], hi[y]))
        ax.set_xlabel(_label(scenario, x))
        ax.set_ylabel(_label(scenario, y))
        if varied is not None:
            ax.set_title(_setting(scenario, varied, level), fontsize=9)
    others = ", ".join(_setting(scenario, a, pixels[0, 0, a]) for a in held)
    fig.suptitle(_with_key(f"{scenario.name} / {scenario.sv_policy_name}: the quantified set ({len(safe_set)} boxes) "
                           f"against the reference" + (f"\nheld at {others}" if others else ""), scenario, fig),
                 fontsize=10)
    handles = [Patch(facecolor=AGREE, label="safe in both"), Patch(facecolor="white", edgecolor="0.6",
                                                                   label="unsafe in both"),
               Patch(facecolor=OVERCLAIMED, label="claimed, but unsafe in the reference"),
               Patch(facecolor=MISSED, label="safe in the reference, not claimed")]
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=9)
    fig.savefig(path, dpi=100)
    plt.close(fig)
