"""A campaign's figures, written into its directory."""

from __future__ import annotations

from pathlib import Path

from farm.reports.plots.explored import _campaign_of, explored_boxes
from farm.reports.plots.layout import held_values
from farm.reports.plots.projections import projections_figure
from farm.reports.plots.slices import slices_figure
from farm.reports.plots.style import PROJECTIONS_FILE, SLICES_FILE, SURFACE_FILE, _save
from farm.reports.plots.surface import surface_figure


def draw(out_dir: Path, scenario, safe_set, summary=None, explored=None, hold=None) -> list[Path]:
    """Write safe_set_3d.png (if the scenario has 3-D views), safe_set_slices.png and
    safe_set_projections.png (3 or more axes) of ``safe_set`` (a SafeSet) in
    ``out_dir``; -> the files written. ``summary`` (a farm.reports.summary.Summary,
    optional) names the campaign in the titles. ``hold``: state name -> the value the
    cuts and views hold that axis at (default: a view's own, else mid-range); ValueError
    naming the axis on an unknown name or a value outside Sigma, before anything is drawn.

    ``explored``: the boxes the campaign explored (``(points, half_widths)``, see
    ``explored_boxes``), so that the slices tell safe, pruned and never explored apart.
    None (the default): read them from the campaign directory ``out_dir`` belongs to
    (DIR/plots -> DIR, DIR/plots/<side>_side -> DIR/sides/<side>) if it holds a record;
    False: draw safe / not safe only."""
    out_dir = Path(out_dir)
    held_values(scenario, hold)  # a wrong axis or value: say so before any figure is drawn
    written = []
    # one figure at a time, the exploration record read only for the slices: at 1.8 M
    # boxes each holds a few hundred MB that need not be held together
    surfaces = surface_figure(scenario, safe_set, summary, hold=hold)
    if surfaces is not None:
        written.append(_save(surfaces, out_dir / SURFACE_FILE, dpi=110))
    del surfaces
    if explored is None:
        campaign = _campaign_of(out_dir)
        explored = explored_boxes(campaign, scenario.state_names) if campaign is not None else None
    elif explored is False:
        explored = None
    written.append(_save(slices_figure(scenario, safe_set, summary, explored=explored, hold=hold),
                         out_dir / SLICES_FILE))
    projections = projections_figure(scenario, safe_set, summary)
    if projections is not None:
        written.append(_save(projections, out_dir / PROJECTIONS_FILE))
    return written
