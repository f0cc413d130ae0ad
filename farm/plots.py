"""PNG figures of a quantified safe set (matplotlib, headless).

The union of boxes is rasterized with the spatial index (exact membership at each pixel).
lead-follow: the boundary surface "smallest safe p10 over (v0, v1)" in 3-D like the
paper's Fig. 2, and 2-D slices (v0, p10) at several lead speeds with the safe region
shaded. fleet3: the lead-side (v0, v1, p10) and rear-side (v0, v2, p20) views like the
paper's Fig. 4 (the other coordinates at mid-range), and slices. Other scenarios:
the first two coordinates.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from coordinator.spatial import PointIndex  # noqa: E402

RESOLUTION = 120


def _member(centres: np.ndarray, h: float, lower) -> callable:
    index = PointIndex(centres.shape[1], 2 * h, lower)
    if len(centres):
        index.insert(centres)
    return lambda pts: index.any_within(pts, h)


def _plane(scenario, x: int, y: int, fixed: dict[int, float], res=RESOLUTION):
    lo, hi = scenario.lower, scenario.upper
    xs = np.linspace(lo[x], hi[x], res)
    ys = np.linspace(lo[y], hi[y], res)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    pts = np.empty((gx.size, scenario.n))
    for axis in range(scenario.n):
        pts[:, axis] = fixed.get(axis, (lo[axis] + hi[axis]) / 2)
    pts[:, x], pts[:, y] = gx.ravel(), gy.ravel()
    return xs, ys, pts


def _surface(ax, scenario, member, axes, label, title):
    """Smallest safe value of the third axis over a grid of the first two (others mid)."""
    x, y, z = axes
    lo, hi = scenario.lower, scenario.upper
    xs = np.linspace(lo[x], hi[x], 41)
    ys = np.linspace(lo[y], hi[y], 41)
    zs = np.linspace(lo[z], hi[z], 141)
    gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
    pts = np.empty((gx.size, scenario.n))
    for axis in range(scenario.n):
        pts[:, axis] = (lo[axis] + hi[axis]) / 2
    pts[:, x], pts[:, y], pts[:, z] = gx.ravel(), gy.ravel(), gz.ravel()
    safe = member(pts).reshape(gx.shape)
    first = np.where(safe.any(axis=2), zs[np.argmax(safe, axis=2)], np.nan)
    ax.plot_surface(gx[:, :, 0], gy[:, :, 0], first, cmap="viridis", linewidth=0, antialiased=True, alpha=0.9)
    names = scenario.state_names
    ax.set_xlabel(names[x])
    ax.set_ylabel(names[y])
    ax.set_zlabel(f"smallest safe {names[z]}")
    ax.set_zlim(lo[z], hi[z])
    ax.set_title(f"{title}\n{label}", fontsize=9)


def _slice(ax, scenario, member, x, y, fixed):
    xs, ys, pts = _plane(scenario, x, y, fixed)
    safe = member(pts).reshape(len(xs), len(ys))
    ax.imshow(safe.T, origin="lower", aspect="auto", cmap="Greens", vmin=0, vmax=1.6,
              extent=(xs[0], xs[-1], ys[0], ys[-1]), interpolation="nearest")
    names = scenario.state_names
    ax.set_xlabel(names[x])
    ax.set_ylabel(names[y])
    ax.set_title(", ".join(f"{names[a]} = {v:.3g}" for a, v in fixed.items()) or "safe set", fontsize=9)


def draw(out_dir: Path, scenario, centres: np.ndarray, h: float, summary: dict) -> list[Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    member = _member(centres, h, scenario.lower)
    title = (f"{summary.get('scenario')} / {summary.get('sv_policy')} / {summary.get('algorithm')}: "
             f"{len(centres)} boxes, half-width {h:g}")
    written = []
    lo, hi = scenario.lower, scenario.upper
    if scenario.name == "fleet3":
        views = [((0, 1, 3), "lead side (v0, v1, p10)"), ((0, 2, 4), "rear side (v0, v2, p20)")]
        slices = [(0, 3, 1), (0, 4, 2)]  # (x, y, varied axis)
    elif scenario.n >= 3:
        views = [((0, 1, scenario.n - 1), "boundary of the safe set")]
        slices = [(0, scenario.n - 1, 1)]
    else:
        views, slices = [], []
    if views:
        fig = plt.figure(figsize=(6.5 * len(views), 5.5))
        for k, (axes, label) in enumerate(views):
            ax = fig.add_subplot(1, len(views), k + 1, projection="3d")
            if scenario.name == "fleet3" and axes[2] == 4:
                # rear side: the safe set lies *below* a largest p20 (follower behind)
                flipped = lambda pts, m=member: m(pts)  # noqa: E731
                _surface_rear(ax, scenario, flipped, axes, label, title)
            else:
                _surface(ax, scenario, member, axes, label, title)
        fig.tight_layout()
        path = out_dir / "safe_set_3d.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    if slices:
        fig, axs = plt.subplots(len(slices), 4, figsize=(16, 4 * len(slices)), squeeze=False)
        for row, (x, y, varied) in enumerate(slices):
            for ax, level in zip(axs[row], np.linspace(lo[varied], hi[varied], 4)):
                _slice(ax, scenario, member, x, y, {varied: float(level)})
    else:
        fig, ax = plt.subplots(figsize=(5.5, 5))
        _slice(ax, scenario, member, 0, 1, {})
        axs = np.array([[ax]])
    fig.suptitle(f"{title}\nsafe region shaded (other coordinates at mid-range)", fontsize=10)
    fig.tight_layout()
    path = out_dir / "safe_set_slices.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    written.append(path)
    return written


def _surface_rear(ax, scenario, member, axes, label, title):
    x, y, z = axes
    lo, hi = scenario.lower, scenario.upper
    xs, ys, zs = np.linspace(lo[x], hi[x], 41), np.linspace(lo[y], hi[y], 41), np.linspace(lo[z], hi[z], 141)
    gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
    pts = np.empty((gx.size, scenario.n))
    for axis in range(scenario.n):
        pts[:, axis] = (lo[axis] + hi[axis]) / 2
    pts[:, x], pts[:, y], pts[:, z] = gx.ravel(), gy.ravel(), gz.ravel()
    safe = member(pts).reshape(gx.shape)[:, :, ::-1]
    last = np.where(safe.any(axis=2), zs[::-1][np.argmax(safe, axis=2)], np.nan)
    ax.plot_surface(gx[:, :, 0], gy[:, :, 0], last, cmap="magma", linewidth=0, alpha=0.9)
    names = scenario.state_names
    ax.set_xlabel(names[x])
    ax.set_ylabel(names[y])
    ax.set_zlabel(f"largest safe {names[z]}")
    ax.set_title(f"{title}\n{label}", fontsize=9)
