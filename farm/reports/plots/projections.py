"""Projections of a safe set onto the planes of its slices (``safe_set_projections.png``).

A cut shows the set at one value of every other axis; in 7 or 9 dimensions that is a
thin sample of it. A projection shows, at each point of a plane (x, y), what share of
the other axes' range (their volume in Sigma) is in the set: 1 where every value of the
hidden coordinates is safe, 0 where none is. It is a sum over the boxes, each adding
its share of the hidden volume over the pixels it covers in (x, y) (a 2-D difference
array), so it costs one pass over the boxes in any dimension. The sum is exact for a set
whose boxes meet only on faces (margin refinement's); for overlapping boxes it counts an
overlap twice, so it is an upper bound, capped at 1, and the figure says so.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from farm.reports.plots.layout import _label, _planes, _title, _with_key
from farm.reports.plots.membership import _covered, _samples
from farm.reports.plots.style import RESOLUTION


def projected_share(scenario, safe_set, x: int, y: int, res: int = RESOLUTION):
    """-> xs, ys, share (len(xs), len(ys)): at each pixel centre of the plane (x, y), the
    share of the hidden axes' volume in the set (see the module's docstring)."""
    lo, hi = np.asarray(scenario.lower, dtype=float), np.asarray(scenario.upper, dtype=float)
    xs, ys = _samples(lo[x], hi[x], res), _samples(lo[y], hi[y], res)
    centres, widths = safe_set.centres, safe_set.axis_half_widths
    hidden = [a for a in range(scenario.n) if a not in (x, y)]
    weight = np.ones(len(centres))
    for a in hidden:
        low = np.maximum(centres[:, a] - widths[:, a], lo[a])
        high = np.minimum(centres[:, a] + widths[:, a], hi[a])
        weight *= np.clip(high - low, 0.0, None) / (hi[a] - lo[a])
    x0, x1 = _covered(xs, centres[:, x], widths[:, x])
    y0, y1 = _covered(ys, centres[:, y], widths[:, y])
    keep = (x0 < x1) & (y0 < y1) & (weight > 0)
    x0, x1, y0, y1, weight = x0[keep], x1[keep], y0[keep], y1[keep], weight[keep]
    size = (res + 1) * (res + 1)
    acc = np.zeros(size)
    for xi, yi, sign in ((x0, y0, 1), (x1, y0, -1), (x0, y1, -1), (x1, y1, 1)):
        acc += sign * np.bincount(xi * (res + 1) + yi, weights=weight, minlength=size)
    share = acc.reshape(res + 1, res + 1).cumsum(axis=0).cumsum(axis=1)[:res, :res]
    return xs, ys, np.clip(share, 0.0, 1.0)


def projections_figure(scenario, safe_set, summary=None):
    """One panel per plane of the scenario's slices, the set's share of the hidden axes
    as a colour; None for a 2-D scenario (nothing is hidden: the slices show it all)."""
    if scenario.n < 3:
        return None
    planes = _planes(scenario)
    fig, axs = plt.subplots(1, len(planes), figsize=(5.4 * len(planes), 4.6), squeeze=False, layout="constrained")
    exact = safe_set.disjoint or len(safe_set) <= 1
    for ax, (x, y) in zip(axs[0], planes):
        xs, ys, share = projected_share(scenario, safe_set, x, y)
        image = ax.imshow(share.T, origin="lower", aspect="auto", cmap="Blues", vmin=0.0, vmax=1.0,
                          extent=(scenario.lower[x], scenario.upper[x], scenario.lower[y], scenario.upper[y]),
                          interpolation="nearest")
        others = [scenario.state_names[a] for a in range(scenario.n) if a not in (x, y)]
        ax.set_xlabel(_label(scenario, x))
        ax.set_ylabel(_label(scenario, y))
        ax.set_title(f"onto ({scenario.state_names[x]}, {scenario.state_names[y]}) along {', '.join(others)}",
                     fontsize=9)
        fig.colorbar(image, ax=ax, shrink=0.85,
                     label="share of the other axes' range in the set" + ("" if exact else " (at most)"))
    how = "" if exact else "; overlapping boxes: an upper bound"
    fig.suptitle(_with_key(f"{_title(scenario, safe_set, summary)}\nprojections: 1 = safe for every value of the "
                           f"other axes, 0 = for none{how}", scenario, fig), fontsize=10)
    return fig
