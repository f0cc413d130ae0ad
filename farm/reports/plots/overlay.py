"""Several sets of one scenario on the same slices (``report DIR1 DIR2 --overlay``)."""

from __future__ import annotations

from pathlib import Path

from matplotlib.lines import Line2D

from farm.reports.plots.layout import _cuts, _with_key
from farm.reports.plots.membership import _set_member
from farm.reports.plots.slices import _extent, _frame, _paint, _panel_grid, _plane
from farm.reports.plots.style import OVERLAY_COLOURS, _save


def _stroke(k: int) -> tuple[str, float]:
    """Line style and width of set k: later sets thinner and dashed, so that outlines
    that coincide (a side set and the total often share a boundary) all stay visible."""
    return ("solid", "dashed", "dotted", "dashdot")[k % 4], max(1.2, 3.2 - 0.8 * k)


def _outline(ax, xs, ys, mask, colour, k) -> None:
    # a constant grid has no boundary inside the panel (contour would only warn)
    if mask.any() and not mask.all():
        style, width = _stroke(k)
        ax.contour(xs, ys, mask.T.astype(float), levels=[0.5], colors=[colour], linewidths=width,
                   linestyles=style)


def overlay_figure(scenario, sets, labels):
    """Figure of ``overlay`` (see draw_overlay)."""
    sets, labels = list(sets), [str(label) for label in labels]
    if not sets or len(sets) != len(labels):
        raise ValueError(f"overlay: {len(sets)} sets and {len(labels)} labels; need one label per set, at least one")
    colours = [OVERLAY_COLOURS[k % len(OVERLAY_COLOURS)] for k in range(len(sets))]
    members = [_set_member(scenario, s) for s in sets]
    rows = [_cuts(scenario, spec) for spec in scenario.slices()]
    fig, axs = _panel_grid(rows)
    for r, row in enumerate(rows):
        for ax, (x, y, held) in zip(axs[r], row):
            xs, ys = _plane(scenario, x, y)
            extent = _extent(scenario, x, y)
            for k, (member, colour) in enumerate(zip(members, colours)):
                mask = member.grid({x: xs, y: ys}, held)
                _paint(ax, mask, extent, colour, alpha=0.12)  # faint: overlaps stay readable
                _outline(ax, xs, ys, mask, colour, k)
            ax.set_xlim(extent[:2])
            ax.set_ylim(extent[2:])
            _frame(ax, scenario, x, y, held)
    handles = [Line2D([], [], color=c, linestyle=_stroke(k)[0], linewidth=_stroke(k)[1],
                      label=f"{label} ({len(s)} boxes)")
               for k, (c, label, s) in enumerate(zip(colours, labels, sets))]
    fig.suptitle(_with_key(f"{scenario.name}: safe sets compared ({' vs '.join(labels)})\n"
                           "each set shaded and outlined in its colour", scenario, fig), fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), fontsize=9)
    return fig


def draw_overlay(path, scenario, sets, labels) -> Path:
    """Overlay quantified safe sets of one scenario on the same 2-D cuts (the scenario's
    Slices hints), like the paper's Fig. 2 comparing the brake and idm SV policies.

    ``sets``: a list of SafeSets (e.g. from two campaign directories); ``labels``: one name per set, shown in the legend. Each set is shaded
    translucently and outlined in its own colour. Writes the PNG at ``path`` (parent
    directories created); -> ``path``. Raises ValueError if labels and sets differ in
    number."""
    return _save(overlay_figure(scenario, sets, labels), path)
