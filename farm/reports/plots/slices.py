"""2-D cuts of a safe set: safe, unsafe / pruned and never explored (``safe_set_slices.png``)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PatchCollection
from matplotlib.colors import to_rgba
from matplotlib.patches import Patch, Rectangle

from farm.reports.plots.layout import _cuts, _label, _panel_title, _slices, _title, _with_key, held_values
from farm.reports.plots.membership import Boxes, _samples, _set_member
from farm.reports.plots.style import (NEVER_COLOUR, NEVER_HATCH, NEVER_HATCH_COLOUR, OUTSIDE_COLOUR, PRUNED_COLOUR,
                              RESOLUTION, SAFE_COLOUR)


def _plane(scenario, x, y, res=RESOLUTION):
    """A cut's pixel centres on its two axes."""
    lo, hi = scenario.lower, scenario.upper
    return _samples(lo[x], hi[x], res), _samples(lo[y], hi[y], res)


def _frame(ax, scenario, x, y, held) -> None:
    ax.set_xlabel(_label(scenario, x))
    ax.set_ylabel(_label(scenario, y))
    ax.set_title(_panel_title(scenario, held), fontsize=9)


def _extent(scenario, x, y) -> tuple:
    return (scenario.lower[x], scenario.upper[x], scenario.lower[y], scenario.upper[y])


def _paint(ax, mask: np.ndarray, extent, colour, alpha=1.0, background=None) -> None:
    """A boolean (x, y) grid as an image: ``colour`` where True, ``background`` (or
    transparent) elsewhere. Colours are explicit RGBA, so no colormap can wash them out."""
    img = np.zeros(mask.T.shape + (4,))
    if background is not None:
        img[~mask.T] = to_rgba(background)
    img[mask.T] = to_rgba(colour, alpha)
    ax.imshow(img, origin="lower", aspect="auto", extent=extent, interpolation="nearest")


def _hatch(ax, xs, ys, mask) -> None:
    """Hatch the True cells of ``mask`` (the never-explored states), cell for cell: one
    rectangle per run of True cells along x in each row of the grid."""
    if not mask.any():
        return
    dx, dy = xs[1] - xs[0] if len(xs) > 1 else 1.0, ys[1] - ys[0] if len(ys) > 1 else 1.0
    rects = []
    for j in range(mask.shape[1]):
        edges = np.diff(np.concatenate([[0], mask[:, j].astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            rects.append(Rectangle((xs[a] - dx / 2, ys[j] - dy / 2), (b - a) * dx, dy))
    with plt.rc_context({"hatch.color": NEVER_HATCH_COLOUR, "hatch.linewidth": 0.8}):
        ax.add_collection(PatchCollection(rects, facecolor="none", edgecolor="none", hatch=NEVER_HATCH,
                                          linewidth=0))


def _draw_slice(ax, scenario, member, x, y, held, explored_member=None) -> int:
    """Paint one cut; -> how many of its grid points were never explored."""
    xs, ys = _plane(scenario, x, y)
    safe = member.grid({x: xs, y: ys}, held)
    extent = _extent(scenario, x, y)
    if explored_member is None:
        _paint(ax, safe, extent, SAFE_COLOUR, background=OUTSIDE_COLOUR)
    else:
        explored = explored_member.grid({x: xs, y: ys}, held)
        _paint(ax, safe | explored, extent, PRUNED_COLOUR, background=NEVER_COLOUR)
        _paint(ax, safe, extent, SAFE_COLOUR)
        never = ~(safe | explored)
        _hatch(ax, xs, ys, never)
        ax.set_xlim(extent[:2])
        ax.set_ylim(extent[2:])
        _frame(ax, scenario, x, y, held)
        return int(never.sum())
    _frame(ax, scenario, x, y, held)
    return 0


def _set_legend(classes: bool = False, never: bool = True):
    if not classes:
        return [Patch(facecolor=SAFE_COLOUR, label="in the safe set"),
                Patch(facecolor=OUTSIDE_COLOUR, edgecolor="0.6", label="not in the safe set")]
    return [Patch(facecolor=SAFE_COLOUR, label="safe (in the quantified set)"),
            Patch(facecolor=PRUNED_COLOUR, label="unsafe: explored and pruned"),
            Patch(facecolor=NEVER_COLOUR, edgecolor=NEVER_HATCH_COLOUR, hatch=NEVER_HATCH,
                  label="never explored" if never else "never explored (none in these cuts)")]


def _panel_grid(rows: list[list], width=4.2, height=3.8):
    ncols = max(len(r) for r in rows)
    fig, axs = plt.subplots(len(rows), ncols, figsize=(width * ncols, height * len(rows) + 0.9),
                            squeeze=False, layout="constrained")
    for r, row in enumerate(rows):
        for ax in axs[r, len(row):]:
            ax.set_visible(False)
    return fig, axs


def slices_figure(scenario, safe_set, summary=None, slices=None, explored=None, hold=None):
    """2-D cuts of ``safe_set`` (default: the scenario's own Slices hints), one row per
    hint, as a Figure with a legend. ``explored``: the boxes the campaign explored
    (``(points (P, n), half_widths (P,))``, see ``explored_boxes``): the cuts then tell
    safe, unsafe (explored and pruned) and never explored apart; None: safe or not.
    ``hold``: state name -> the value the cuts hold it at (default mid-range)."""
    held = held_values(scenario, hold)
    rows = [_cuts(scenario, spec, held) for spec in (_slices(scenario) if slices is None else slices)]
    member = _set_member(scenario, safe_set)
    explored_member = None if explored is None else Boxes(*explored, scenario.n)  # a box twice is painted once
    fig, axs = _panel_grid(rows)
    never = 0
    for r, row in enumerate(rows):
        for ax, (x, y, held) in zip(axs[r], row):
            never += _draw_slice(ax, scenario, member, x, y, held, explored_member)
    what = "safe, pruned and never-explored states" if explored is not None else "the safe set"
    fig.suptitle(_with_key(f"{_title(scenario, safe_set, summary)}\n2-D cuts: {what}", scenario, fig), fontsize=10)
    handles = _set_legend(explored is not None, never > 0)
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9)
    return fig
