"""PNG figures of a quantified safe set (matplotlib, headless).

The safe set is a ``coordinator.safe_set.SafeSet`` (a union of l-inf boxes); it is
rasterized box by box onto each figure's grid of pixel centres (``membership.Boxes``: the
membership the spatial index decides, at every grid point). What is drawn
comes from the scenario's hints (``scenarios.base.View`` / ``Slices``):

- ``safe_set_3d.png``: per view, the boundary surface of the safe set (smallest safe z,
  or largest for a set that lies below it) over the plane (x, y), like the paper's
  Figs. 2 and 4;
- ``safe_set_slices.png``: 2-D cuts (x, y) at a few values of a third coordinate, in
  three classes: safe (in the quantified set), unsafe / pruned (explored by the campaign
  and not in the set: boxes of pruned vertices, of failing runs' starts, of every run's
  start at its round's delta), and never explored (covered by neither). What was
  explored is read from the campaign directory (``explored_boxes``: its ledger and
  checkpoint); without that record the cut tells only "in the set" from "not in it";
- ``safe_set_projections.png`` (3 or more axes): per plane of the slices, the share of the
  other axes' range in the set at each point (projections.py).

Coordinates a figure does not show are held fixed (the user's ``hold``, else the view's
``fixed``, else mid-range), and the figure says which and at what value. A side campaign (fleet3's lead / rear side:
a scenario whose ``failure_facets`` is a subset) gets only the views and slices about its
own facets. ``draw_overlay`` compares sets of one scenario on the same slices;
``draw_failures`` draws failing runs over the safe set's projection.

The ``*_figure`` functions return matplotlib Figures (inspected by the tests); the
``draw*`` functions save them as PNG and close them. One module per figure kind
(surface, slices, overlay, failures), over what they share: membership (rasterizing the
boxes), explored (the campaign's record), layout (what is shown and said) and style.
"""

import matplotlib

matplotlib.use("Agg")  # headless; set here, before any module of the package imports pyplot

from farm.reports.plots.campaign import draw  # noqa: E402
from farm.reports.plots.explored import explored_boxes  # noqa: E402
from farm.reports.plots.failures import draw_failures, failures_figure  # noqa: E402
from farm.reports.plots.overlay import draw_overlay, overlay_figure  # noqa: E402
from farm.reports.plots.plan import draw_plan  # noqa: E402
from farm.reports.plots.projections import projected_share, projections_figure  # noqa: E402
from farm.reports.plots.reference import draw_reference  # noqa: E402
from farm.reports.plots.slices import slices_figure  # noqa: E402
from farm.reports.plots.style import NEVER_COLOUR, OUTSIDE_COLOUR, PRUNED_COLOUR, SAFE_COLOUR  # noqa: E402
from farm.reports.plots.surface import surface_figure  # noqa: E402

__all__ = ["draw", "draw_failures", "draw_overlay", "draw_plan", "draw_reference", "explored_boxes", "failures_figure", "overlay_figure",
           "projected_share", "projections_figure",
           "slices_figure", "surface_figure", "NEVER_COLOUR", "OUTSIDE_COLOUR", "PRUNED_COLOUR", "SAFE_COLOUR"]
