"""PNG figures of a quantified safe set (matplotlib, headless).

lead-follow: a 3-D view of the boxes in (v0, v1, p10) like the paper's Fig. 2, and 2-D
slices with the safe region shaded. fleet3: the lead-side (v0, v1, p10) and rear-side
(v0, v2, p20) views like the paper's Fig. 4. Other scenarios: pairwise projections.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MAX_3D_POINTS = 20000


def _scatter3d(ax, centres, axes, names, colour, title):
    pts = centres[:, axes]
    if len(pts) > MAX_3D_POINTS:  # thin for drawing only: every box still counts elsewhere
        pts = pts[np.linspace(0, len(pts) - 1, MAX_3D_POINTS).astype(int)]
    ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=2, c=pts[:, 2], cmap=colour, alpha=0.5, linewidths=0)
    ax.set_xlabel(names[axes[0]])
    ax.set_ylabel(names[axes[1]])
    ax.set_zlabel(names[axes[2]])
    ax.set_title(title, fontsize=10)


def _slice(ax, centres, h, lower, upper, names, x, y, fixed: dict[int, float]):
    """Shade the boxes whose extent contains the fixed coordinates, in the (x, y) plane."""
    mask = np.ones(len(centres), dtype=bool)
    for axis, value in fixed.items():
        mask &= np.abs(centres[:, axis] - value) <= h + 1e-9
    sel = centres[mask]
    ax.set_xlim(lower[x], upper[x])
    ax.set_ylim(lower[y], upper[y])
    for c in sel:
        ax.add_patch(plt.Rectangle((c[x] - h, c[y] - h), 2 * h, 2 * h, color="tab:green", alpha=0.35, lw=0))
    label = ", ".join(f"{names[a]} = {v:g}" for a, v in fixed.items())
    ax.set_title(f"safe region at {label}", fontsize=9)
    ax.set_xlabel(names[x])
    ax.set_ylabel(names[y])


def draw(out_dir: Path, scenario, centres: np.ndarray, h: float, summary: dict) -> list[Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(scenario.state_names)
    written = []
    title = f"{summary.get('scenario')} / {summary.get('sv_policy')} / {summary.get('algorithm')}"
    if scenario.name == "fleet3":
        views = [((0, 1, 3), "lead side (v0, v1, p10)"), ((0, 2, 4), "rear side (v0, v2, p20)")]
    elif scenario.n >= 3:
        views = [((0, 1, 2), f"safe set ({', '.join(names[:3])})")]
    else:
        views = []
    if views:
        fig = plt.figure(figsize=(6 * len(views), 5))
        for k, (axes, label) in enumerate(views):
            ax = fig.add_subplot(1, len(views), k + 1, projection="3d")
            _scatter3d(ax, centres, axes, names, "viridis", f"{title}\n{label}: {len(centres)} boxes, h = {h:g}")
        path = out_dir / "safe_set_3d.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    # 2-D slices: the last axis (a gap) against the first (SV speed), at a few values of
    # the others; for 2-D scenarios the whole plane.
    lower, upper = scenario.lower, scenario.upper
    if scenario.n == 2:
        fig, ax = plt.subplots(figsize=(5, 5))
        _slice(ax, centres, h, lower, upper, names, 0, 1, {})
        ax.set_title(f"{title}: safe set", fontsize=9)
        panels = [fig]
    else:
        x, y = 0, (3 if scenario.name == "fleet3" else scenario.n - 1)
        others = [a for a in range(scenario.n) if a not in (x, y)]
        levels = np.linspace(lower[others[0]], upper[others[0]], 4)
        fig, axs = plt.subplots(1, 4, figsize=(16, 4))
        for ax, level in zip(axs, levels):
            fixed = {others[0]: float(level)}
            for a in others[1:]:
                fixed[a] = float((lower[a] + upper[a]) / 2)
            _slice(ax, centres, h, lower, upper, names, x, y, fixed)
        fig.suptitle(f"{title}: 2-D slices of the safe set (shaded)", fontsize=10)
        panels = [fig]
    path = out_dir / "safe_set_slices.png"
    panels[0].tight_layout()
    panels[0].savefig(path, dpi=100)
    plt.close(panels[0])
    written.append(path)
    return written
