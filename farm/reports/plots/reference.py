"""The comparison figure (``scenario-farm compare``): a set against its reference."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from coordinator.safe_set import SafeSet


def draw_reference(path: Path, scenario, safe_set: SafeSet, x: int, y: int, varied: int | None, levels,
                   pixels: np.ndarray, truth: np.ndarray, res: int) -> None:
    """compare.png: slices (x, y) at ``levels`` of axis ``varied``, pixel by pixel
    (``pixels``, res x res per level) the set against the reference membership ``truth``
    (farm/reports/compare.py)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lo, hi = scenario.lower, scenario.upper
    pixels = pixels.reshape(len(levels), res * res, scenario.n)
    fig, axs = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 4), squeeze=False)
    for ax, level, pts, ref in zip(axs[0], levels, pixels, truth.reshape(len(levels), res, res)):
        got = safe_set.contains(pts).reshape(res, res)
        img = np.zeros((res, res, 3)) + 1.0
        img[ref & got] = (0.75, 0.9, 0.75)
        img[got & ~ref] = (0.85, 0.1, 0.1)
        img[ref & ~got] = (0.2, 0.35, 0.9)
        ax.imshow(np.transpose(img, (1, 0, 2)), origin="lower", aspect="auto", extent=(lo[x], hi[x], lo[y], hi[y]))
        ax.set_xlabel(scenario.state_names[x])
        ax.set_ylabel(scenario.state_names[y])
        if varied is not None:
            ax.set_title(f"{scenario.state_names[varied]} = {level:.3g}", fontsize=9)
    fig.suptitle(f"{scenario.name} / {scenario.sv_policy_name}: green agree, red claimed but unsafe, "
                 f"blue safe but not claimed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
