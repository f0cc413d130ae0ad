"""3-D boundary surfaces of a safe set (``safe_set_3d.png``, like the paper's Figs. 2 and 4)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from farm.reports.plots.layout import _label, _settings, _title, _views, _with_key, held_values
from farm.reports.plots.membership import _axis, _held, _samples, _set_member
from farm.reports.plots.style import SURFACE_DEPTH, SURFACE_GRID, VIEW_AZIMUTH, VIEW_ELEVATION


def _boundary(scenario, member, view, hold=None):
    """Over the (x, y) grid, the smallest (safe_above) or largest safe z; NaN where no z
    is safe. -> xs, ys, z (len(xs), len(ys)), held coordinates (``hold``, axis -> value,
    before the view's own ``fixed``, before mid-range)."""
    x, y, z = (_axis(scenario, name) for name in view.axes)
    lo, hi = scenario.lower, scenario.upper
    held = _held(scenario, (x, y, z), {**{_axis(scenario, k): v for k, v in view.fixed}, **(hold or {})})
    xs, ys = _samples(lo[x], hi[x], SURFACE_GRID), _samples(lo[y], hi[y], SURFACE_GRID)
    zs = np.linspace(lo[z], hi[z], SURFACE_DEPTH)  # ends included: a boundary on Sigma's face
    if not view.safe_above:
        zs = zs[::-1]  # the first safe sample along the column is then the largest
    safe = member.grid({x: xs, y: ys, z: zs}, held)
    first = np.where(safe.any(axis=2), zs[np.argmax(safe, axis=2)], np.nan)
    return xs, ys, first, held


def _zlim(scenario, view, values):
    """The surface's range with a margin, inside Sigma: the surface fills the box."""
    z = _axis(scenario, view.axes[2])
    lo, hi = float(scenario.lower[z]), float(scenario.upper[z])
    if not np.isfinite(values).any():
        return lo, hi
    pad = 0.05 * (hi - lo)
    zmin, zmax = max(lo, np.nanmin(values) - pad), min(hi, np.nanmax(values) + pad)
    return (zmin, zmax) if zmax > zmin else (lo, hi)


def _draw_view(fig, ax, scenario, member, view, hold=None) -> None:
    xs, ys, first, held = _boundary(scenario, member, view, hold)
    x, y, z = (_axis(scenario, name) for name in view.axes)
    zmin, zmax = _zlim(scenario, view, first)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    surface = ax.plot_surface(gx, gy, first, cmap="viridis" if view.safe_above else "magma",
                              vmin=zmin, vmax=zmax, linewidth=0, antialiased=True, alpha=0.95)
    which = "smallest" if view.safe_above else "largest"
    fig.colorbar(surface, ax=ax, shrink=0.6, pad=0.1, label=f"{which} safe {_label(scenario, z)}")
    ax.set_xlabel(_label(scenario, x))
    ax.set_ylabel(_label(scenario, y))
    ax.set_zlabel(_label(scenario, z))  # what the height means is on the colour bar
    ax.set_xlim(scenario.lower[x], scenario.upper[x])
    ax.set_ylim(scenario.lower[y], scenario.upper[y])
    ax.set_zlim(zmin, zmax)
    ax.view_init(elev=VIEW_ELEVATION, azim=VIEW_AZIMUTH)
    words = [f"{view.title} ({', '.join(view.axes)}): safe {'above' if view.safe_above else 'below'} the surface"]
    if held:
        words.append(f"held at {_settings(scenario, held)}")
    if not np.isfinite(first).any():
        words.append("no safe state in this view")
    ax.set_title("\n".join(words), fontsize=9)


def surface_figure(scenario, safe_set, summary=None, views=None, hold=None):
    """The 3-D boundary surfaces of ``safe_set`` in ``views`` (default: the scenario's
    own) in one Figure, or None when there is no view (a 2-D scenario). ``hold``: state
    name -> the value a view holds it at (default: the view's own, else mid-range)."""
    held = held_values(scenario, hold)
    views = _views(scenario) if views is None else views
    if not views:
        return None
    member = _set_member(scenario, safe_set)
    fig = plt.figure(figsize=(7 * len(views), 6), layout="constrained")
    for k, view in enumerate(views):
        _draw_view(fig, fig.add_subplot(1, len(views), k + 1, projection="3d"), scenario, member, view, held)
    fig.suptitle(_with_key(_title(scenario, safe_set, summary), scenario, fig), fontsize=10)
    return fig
