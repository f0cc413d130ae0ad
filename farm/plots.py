"""PNG figures of a quantified safe set (matplotlib, headless).

The safe set is a union of l-inf boxes (``centres`` (M, n), half-width ``h``); it is
rasterized with the spatial index (exact membership at each grid point). What is drawn
comes from the scenario's hints (``scenarios.base.View`` / ``Slices``):

- ``safe_set_3d.png``: per view, the boundary surface of the safe set (smallest safe z,
  or largest for a set that lies below it) over the plane (x, y), like the paper's
  Figs. 2 and 4;
- ``safe_set_slices.png``: 2-D cuts (x, y) at a few values of a third coordinate, in
  three classes: safe (in the quantified set), unsafe / pruned (explored by the campaign
  and not in the set: boxes of pruned vertices, of failing runs' starts, of every run's
  start at its round's delta), and never explored (covered by neither). What was
  explored is read from the campaign directory (``explored_boxes``: its ledger and
  checkpoint); without that record the cut tells only "in the set" from "not in it".

Coordinates a figure does not show are held fixed (the view's ``fixed`` or mid-range),
and the figure says which and at what value. A side campaign (fleet3's lead / rear side:
a scenario whose ``failure_facets`` is a subset) gets only the views and slices about its
own facets. ``draw_overlay`` compares sets of one scenario on the same slices;
``draw_failures`` draws failing runs over the safe set's projection.

The ``*_figure`` functions return matplotlib Figures (inspected by the tests); the
``draw*`` functions save them as PNG and close them.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from coordinator.spatial import TOLERANCE, PointIndex  # noqa: E402

RESOLUTION = 120  # grid points per axis of a slice
HIDDEN_SAMPLES = 27  # failure figures: samples of the coordinates a plane hides (in all)
SURFACE_GRID, SURFACE_DEPTH = 40, 141  # (x, y) grid and z samples of a 3-D boundary
# the camera stands at the corner of low x and high y: a boundary that rises toward high x
# and low y (lead-follow: fast follower, slow lead; fleet3's lead side) shows its whole slope
# instead of hiding behind the flat part (looked at on lead-follow and both fleet3 sides)
VIEW_ELEVATION, VIEW_AZIMUTH = 28, 135
LEVELS = 4  # slices per Slices hint (values of the varied coordinate, ends included)
# Okabe-Ito blue and vermillion: told apart with every common colour-vision deficiency
# (blue against a red-brown, and by lightness), neither near white
SAFE_COLOUR = "#0072B2"
PRUNED_COLOUR = "#D55E00"
NEVER_COLOUR, NEVER_HATCH, NEVER_HATCH_COLOUR = "#e4e4e4", "////", "#a6a6a6"  # light grey, hatched
OUTSIDE_COLOUR = "#f4c9c4"  # "not in the safe set" when there is no exploration record
OVERLAY_COLOURS = ("#1f5fbf", "#e8710a", "#7b3fb5", "#1a9e8f", "#c2185b", "#6d5d00")
SLICES_FILE, SURFACE_FILE = "safe_set_slices.png", "safe_set_3d.png"


# -- membership and grids -----------------------------------------------------------------
def _member(centres: np.ndarray, h: float, lower, upper=None) -> callable:
    """Membership in the union of boxes, (G, n) -> (G,) bool. With ``upper`` the index
    uses its dense fast path (Sigma as bounds)."""
    centres = np.asarray(centres, dtype=float).reshape(-1, len(lower))
    if not len(centres) or h <= 0:  # an empty set (a zero cell would break the index)
        return lambda pts: np.zeros(len(pts), dtype=bool)
    return _Membership(centres, h, lower, upper)


class _Membership:
    """Membership in a union of equal boxes, indexing only the boxes a query can meet.

    A figure's query holds some coordinates at one value (a slice holds all but two):
    only boxes within h of those values can contain its points, often a few percent of
    a large set. The index over them is built on first use and kept per held values;
    a full index (one over every box, ~130 bytes per box) is built only for a query that
    holds nothing. The answers are those of one index over all boxes."""

    def __init__(self, centres: np.ndarray, h: float, lower, upper=None, distinct: bool = False):
        self.centres, self.h, self.distinct = centres, float(h), distinct
        self.lower = np.asarray(lower, float)
        self.bounds = None if upper is None else (self.lower, np.asarray(upper, float))
        self._indexes: dict[tuple, PointIndex | None] = {}

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        pts = np.atleast_2d(np.asarray(pts, dtype=float))
        if not len(pts):
            return np.zeros(0, dtype=bool)
        first = pts[0]
        held = tuple((a, float(first[a])) for a in range(pts.shape[1])
                     if np.isfinite(first[a]) and (pts[:, a] == first[a]).all())
        if held not in self._indexes:
            self._indexes[held] = self._index(held)
        index = self._indexes[held]
        return index.any_within(pts, self.h) if index is not None else np.zeros(len(pts), dtype=bool)

    def _index(self, held: tuple) -> PointIndex | None:
        near = np.ones(len(self.centres), dtype=bool)
        for axis, value in held:
            near &= np.abs(self.centres[:, axis] - value) <= self.h + TOLERANCE
        group = self.centres if near.all() else self.centres[near]
        if self.distinct:
            group = _distinct_rows(group)
        if not len(group):
            return None
        index = PointIndex(group.shape[1], 2 * self.h, self.lower, capacity=len(group), bounds=self.bounds)
        index.insert(group)
        return index


def _points(scenario, grids: dict[int, np.ndarray], fixed: dict[int, float]) -> np.ndarray:
    """All combinations of ``grids`` (axis -> values, 'ij' order) as rows of states; the
    other coordinates at ``fixed`` (axis -> value)."""
    axes = list(grids)
    mesh = np.meshgrid(*(grids[a] for a in axes), indexing="ij")
    pts = np.full((mesh[0].size, scenario.n), np.nan)  # a coordinate left unset is in no box
    for axis, value in fixed.items():
        pts[:, axis] = value
    for axis, values in zip(axes, mesh):
        pts[:, axis] = values.ravel()
    return pts


def _held(scenario, shown, fixed: dict[int, float] | None = None) -> dict[int, float]:
    """The coordinates a figure does not show -> the value they are held at (``fixed``,
    else mid-range)."""
    fixed = fixed or {}
    mid = (np.asarray(scenario.lower) + np.asarray(scenario.upper)) / 2
    return {a: float(fixed.get(a, mid[a])) for a in range(scenario.n) if a not in shown}


def _samples(lo: float, hi: float, count: int) -> np.ndarray:
    """Pixel centres across [lo, hi]: an image's pixels then sit where they were
    sampled, and no sample lands exactly on a box face of a grid-aligned set (where
    neighbouring boxes touch and a single column would stick out)."""
    return lo + (np.arange(count) + 0.5) * ((hi - lo) / count)


def _axis(scenario, name: str) -> int:
    return list(scenario.state_names).index(name)


# -- what the campaign explored ------------------------------------------------------------
def explored_boxes(directory, state_names) -> tuple[np.ndarray, np.ndarray] | None:
    """The boxes a campaign explored, from its directory: ``(points (P, n), half_widths
    (P,))``, or None when the directory holds no record of it (no ledger, no checkpoint).

    - every committed run's start state (the ledger), at its round's delta: its box was
      in the covering when it was drawn;
    - the checkpoint's vertices, alive or pruned, at the final delta; SPE's first roots
      (the first block of graph roots: the tiling of Sigma it starts from) at delta0;
    - the checkpoint's failure points (PhiBar), at the final delta.

    Outside the safe set, these boxes are the states the campaign explored and pruned;
    the rest it never explored (for SPE, which starts from all of Sigma, nothing)."""
    directory = Path(directory)
    names = list(state_names)
    points, widths = [], []
    ledger = directory / "ledger"
    if any(ledger.glob("segment-*.parquet")):
        import pyarrow.dataset as ds

        table = ds.dataset(ledger, format="parquet").to_table(columns=["delta", *names])
        if table.num_rows:
            points.append(np.column_stack([table.column(c).to_numpy() for c in names]).astype(float))
            widths.append(table.column("delta").to_numpy().astype(float))
    if (directory / "checkpoint.npz").exists():
        from farm.journal import Journal

        state, _ = Journal(directory).read(["algo.scalars", "algo.vertices.points", "algo.graph.parent",
                                            "algo.failures.points"])
        delta = float(state["algo.scalars"][0]) if "algo.scalars" in state else 0.0
        vertices = state.get("algo.vertices.points", np.zeros((0, len(names))))
        if delta > 0 and len(vertices):
            wide = np.full(len(vertices), delta)
            parent = state.get("algo.graph.parent")
            if parent is not None and len(parent) and parent[0] == -1:
                first = int(np.argmax(parent != -1)) if (parent != -1).any() else len(parent)
                wide[:first] = max(delta, _delta0(directory, delta))
            points.append(vertices.reshape(-1, len(names)))
            widths.append(wide)
        failures = state.get("algo.failures.points")
        if delta > 0 and failures is not None and len(failures):
            points.append(failures.reshape(-1, len(names)))
            widths.append(np.full(len(failures), delta))
    if not points:
        return None
    return np.concatenate(points), np.concatenate(widths)


def _delta0(directory: Path, default: float) -> float:
    """quantify.delta0 of the campaign's frozen config (a side campaign: its parent's)."""
    import json

    for folder in (directory, *directory.parents[:3]):
        try:
            return float(json.loads((folder / "config.json").read_text())["config"]["quantify"]["delta0"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return default


def _campaign_of(out_dir: Path) -> Path | None:
    """The campaign directory whose figures go to ``out_dir``: DIR for DIR/plots, a side
    campaign DIR/sides/<label> for DIR/plots/<label>_side; None for any other place."""
    out_dir = Path(out_dir)
    if out_dir.name == "plots":
        return out_dir.parent
    if out_dir.parent.name == "plots" and out_dir.name.endswith("_side"):
        return out_dir.parent.parent / "sides" / out_dir.name[: -len("_side")]
    return None


def _distinct_rows(points: np.ndarray) -> np.ndarray:
    """The distinct rows of ``points`` (a campaign's starts repeat its vertices): sorted
    on one axis, then duplicates dropped where every coordinate equals the previous row's.
    ``np.unique(axis=0)`` takes 5 s on 3.6 M rows; this, a fraction of a second."""
    if len(points) < 2:
        return points
    points = points[np.lexsort(points.T[::-1])]
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = (points[1:] != points[:-1]).any(axis=1)
    return points[keep]


def _explored_member(explored, n: int) -> callable:
    """Membership in the union of boxes of varying half-width (one index per width).
    A campaign's starts repeat its vertices: duplicates are dropped before indexing."""
    points, widths = explored
    points = np.asarray(points, dtype=float).reshape(-1, n)
    widths = np.broadcast_to(np.asarray(widths, dtype=float), (len(points),))
    members = []
    for w in np.unique(widths[widths > 0]):
        group = points[widths == w]
        members.append(_Membership(group, float(w), group.min(axis=0), distinct=True))
    return lambda pts: np.logical_or.reduce([m(pts) for m in members] + [np.zeros(len(pts), dtype=bool)])


# -- words --------------------------------------------------------------------------------
def _label(scenario, axis: int) -> str:
    """Axis label with unit, "v0 [m/s]"."""
    name = scenario.state_names[axis]
    unit = getattr(scenario, "units", {}).get(name)
    return f"{name} [{unit}]" if unit else name


def _setting(scenario, axis: int, value: float) -> str:
    """A held coordinate in words, "v1 = 6.67 m/s"."""
    name = scenario.state_names[axis]
    unit = getattr(scenario, "units", {}).get(name)
    return f"{name} = {value:.3g}" + (f" {unit}" if unit else "")


def _settings(scenario, held: dict[int, float]) -> str:
    return ", ".join(_setting(scenario, a, v) for a, v in held.items())


def _title(scenario, centres, h, summary: dict) -> str:
    parts = [summary.get("scenario") or scenario.name,
             summary.get("sv_policy") or getattr(scenario, "sv_policy_name", None), summary.get("algorithm")]
    return f"{' / '.join(str(p) for p in parts if p)}: {len(centres)} boxes, half-width {h:g}"


# -- what to draw ---------------------------------------------------------------------------
def _own(items, scenario, names_of) -> list:
    """The hints about the scenario's failure facets (a side campaign counts only its
    own: fleet3's rear side has no business with the lead-side view); all if none is."""
    facets = set(getattr(scenario, "failure_facets", ()))
    own = [item for item in items if facets & set(names_of(item))]
    return own or list(items)


def _views(scenario) -> list:
    return _own(scenario.views(), scenario, lambda v: v.axes[2:])


def _slices(scenario) -> list:
    return _own(scenario.slices(), scenario, lambda s: (s.x, s.y))


def _cuts(scenario, spec) -> list[tuple[int, int, dict[int, float]]]:
    """A Slices hint -> panels (x, y, held coordinates): one per level of ``varied``."""
    x, y = _axis(scenario, spec.x), _axis(scenario, spec.y)
    if spec.varied is None:
        return [(x, y, _held(scenario, (x, y)))]
    v = _axis(scenario, spec.varied)
    # the varied coordinate first: it is what changes along a row, so it leads the title
    return [(x, y, {v: float(level), **_held(scenario, (x, y, v))})
            for level in np.linspace(scenario.lower[v], scenario.upper[v], LEVELS)]


def _panel_title(scenario, held: dict[int, float]) -> str:
    return _settings(scenario, held) if held else "the whole state plane"


# -- 3-D boundary surfaces -----------------------------------------------------------------
def _boundary(scenario, member, view):
    """Over the (x, y) grid, the smallest (safe_above) or largest safe z; NaN where no z
    is safe. -> xs, ys, z (len(xs), len(ys)), held coordinates."""
    x, y, z = (_axis(scenario, name) for name in view.axes)
    lo, hi = scenario.lower, scenario.upper
    held = _held(scenario, (x, y, z), {_axis(scenario, k): v for k, v in view.fixed})
    xs, ys = _samples(lo[x], hi[x], SURFACE_GRID), _samples(lo[y], hi[y], SURFACE_GRID)
    zs = np.linspace(lo[z], hi[z], SURFACE_DEPTH)  # ends included: a boundary on Sigma's face
    if not view.safe_above:
        zs = zs[::-1]  # the first safe sample along the column is then the largest
    safe = member(_points(scenario, {x: xs, y: ys, z: zs}, held)).reshape(len(xs), len(ys), len(zs))
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


def _draw_view(fig, ax, scenario, member, view) -> None:
    xs, ys, first, held = _boundary(scenario, member, view)
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


def surface_figure(scenario, centres, h, summary: dict, views=None):
    """The 3-D boundary surfaces of ``views`` (default: the scenario's own) in one
    Figure, or None when there is no view (a 2-D scenario)."""
    views = _views(scenario) if views is None else views
    if not views:
        return None
    member = _member(centres, h, scenario.lower, scenario.upper)
    fig = plt.figure(figsize=(7 * len(views), 6), layout="constrained")
    for k, view in enumerate(views):
        _draw_view(fig, fig.add_subplot(1, len(views), k + 1, projection="3d"), scenario, member, view)
    fig.suptitle(_title(scenario, centres, h, summary), fontsize=10)
    return fig


# -- 2-D slices -------------------------------------------------------------------------------
def _plane(scenario, x, y, held, res=RESOLUTION):
    lo, hi = scenario.lower, scenario.upper
    xs, ys = _samples(lo[x], hi[x], res), _samples(lo[y], hi[y], res)
    return xs, ys, _points(scenario, {x: xs, y: ys}, held)


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
    xs, ys, pts = _plane(scenario, x, y, held)
    safe = member(pts).reshape(len(xs), len(ys))
    extent = _extent(scenario, x, y)
    if explored_member is None:
        _paint(ax, safe, extent, SAFE_COLOUR, background=OUTSIDE_COLOUR)
    else:
        explored = explored_member(pts).reshape(len(xs), len(ys))
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


def slices_figure(scenario, centres, h, summary: dict, slices=None, explored=None):
    """2-D cuts of the safe set (default: the scenario's own Slices hints), one row per
    hint, as a Figure with a legend. ``explored``: the boxes the campaign explored
    (``(points (P, n), half_widths (P,))``, see ``explored_boxes``): the cuts then tell
    safe, unsafe (explored and pruned) and never explored apart; None: safe or not."""
    rows = [_cuts(scenario, spec) for spec in (_slices(scenario) if slices is None else slices)]
    member = _member(centres, h, scenario.lower, scenario.upper)
    explored_member = None if explored is None else _explored_member(explored, scenario.n)
    fig, axs = _panel_grid(rows)
    never = 0
    for r, row in enumerate(rows):
        for ax, (x, y, held) in zip(axs[r], row):
            never += _draw_slice(ax, scenario, member, x, y, held, explored_member)
    what = "safe, pruned and never-explored states" if explored is not None else "the safe set"
    fig.suptitle(f"{_title(scenario, centres, h, summary)}\n2-D cuts: {what}", fontsize=10)
    handles = _set_legend(explored is not None, never > 0)
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9)
    return fig


# -- campaign figures --------------------------------------------------------------------------
def _save(fig, path: Path, dpi=100) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)
    return path


def draw(out_dir: Path, scenario, centres: np.ndarray, h: float, summary: dict, explored=None) -> list[Path]:
    """Write safe_set_3d.png (if the scenario has 3-D views) and safe_set_slices.png in
    ``out_dir``; -> the files written.

    ``explored``: the boxes the campaign explored (``(points, half_widths)``, see
    ``explored_boxes``), so that the slices tell safe, pruned and never explored apart.
    None (the default): read them from the campaign directory ``out_dir`` belongs to
    (DIR/plots -> DIR, DIR/plots/<side>_side -> DIR/sides/<side>) if it holds a record;
    False: draw safe / not safe only."""
    out_dir = Path(out_dir)
    centres = np.asarray(centres, dtype=float).reshape(-1, scenario.n)
    written = []
    # one figure at a time, the exploration record read only for the slices: at 1.8 M
    # boxes each holds a few hundred MB that need not be held together
    surfaces = surface_figure(scenario, centres, h, summary)
    if surfaces is not None:
        written.append(_save(surfaces, out_dir / SURFACE_FILE, dpi=110))
    del surfaces
    if explored is None:
        campaign = _campaign_of(out_dir)
        explored = explored_boxes(campaign, scenario.state_names) if campaign is not None else None
    elif explored is False:
        explored = None
    written.append(_save(slices_figure(scenario, centres, h, summary, explored=explored), out_dir / SLICES_FILE))
    return written


# -- overlay of several sets ----------------------------------------------------------------------
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
    members = [_member(np.asarray(c, float).reshape(-1, scenario.n), h, scenario.lower, scenario.upper)
               for c, h in sets]
    rows = [_cuts(scenario, spec) for spec in scenario.slices()]
    fig, axs = _panel_grid(rows)
    for r, row in enumerate(rows):
        for ax, (x, y, held) in zip(axs[r], row):
            xs, ys, pts = _plane(scenario, x, y, held)
            extent = _extent(scenario, x, y)
            for k, (member, colour) in enumerate(zip(members, colours)):
                mask = member(pts).reshape(len(xs), len(ys))
                _paint(ax, mask, extent, colour, alpha=0.12)  # faint: overlaps stay readable
                _outline(ax, xs, ys, mask, colour, k)
            ax.set_xlim(extent[:2])
            ax.set_ylim(extent[2:])
            _frame(ax, scenario, x, y, held)
    handles = [Line2D([], [], color=c, linestyle=_stroke(k)[0], linewidth=_stroke(k)[1],
                      label=f"{label} ({len(np.atleast_2d(s[0]))} boxes)")
               for k, (c, label, s) in enumerate(zip(colours, labels, sets))]
    fig.suptitle(f"{scenario.name}: safe sets compared ({' vs '.join(labels)})\n"
                 "each set shaded and outlined in its colour", fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), fontsize=9)
    return fig


def draw_overlay(path, scenario, sets, labels) -> Path:
    """Overlay quantified safe sets of one scenario on the same 2-D cuts (the scenario's
    Slices hints), like the paper's Fig. 2 comparing the brake and idm SV policies.

    ``sets``: a list of ``(centres (M, n), h)``, one per set (e.g. from two campaign
    directories); ``labels``: one name per set, shown in the legend. Each set is shaded
    translucently and outlined in its own colour. Writes the PNG at ``path`` (parent
    directories created); -> ``path``. Raises ValueError if labels and sets differ in
    number."""
    return _save(overlay_figure(scenario, sets, labels), path)


# -- failing runs ------------------------------------------------------------------------------
def _planes(scenario) -> list[tuple[int, int]]:
    """The distinct (x, y) planes of the scenario's slices (fleet3: (v0, p10), (v0, p20))."""
    planes = []
    for spec in _slices(scenario):
        plane = (_axis(scenario, spec.x), _axis(scenario, spec.y))
        if plane not in planes:
            planes.append(plane)
    return planes


def _projection(scenario, centres, h, x, y):
    """The safe set's shadow on the plane (x, y) as a grid: a run's projected start lies
    in it whatever its other coordinates, which no single slice could promise."""
    flat = np.unique(centres[:, [x, y]], axis=0)
    lo, hi = scenario.lower[[x, y]], scenario.upper[[x, y]]
    member = _member(flat, h, lo, hi)
    xs, ys = _samples(lo[0], hi[0], RESOLUTION), _samples(lo[1], hi[1], RESOLUTION)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return xs, ys, member(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)


def _limits(lo, hi, trajectories, axis):
    """Sigma's range widened to the runs (a failing run leaves Sigma), with a margin."""
    values = [lo, hi] + [v for t in trajectories for v in (t[:, axis].min(), t[:, axis].max())]
    a, b = min(values), max(values)
    pad = 0.03 * (b - a or 1.0)
    return a - pad, b + pad


def _core(scenario, centres, h, x, y, xs, ys, samples: int = HIDDEN_SAMPLES):
    """Where on the grid (xs, ys) of the plane (x, y) every sampled value of the other
    coordinates is safe (``samples`` in all per hidden coordinate, Sigma's ends
    included): a state there is safe whatever its hidden coordinates."""
    hidden = [a for a in range(scenario.n) if a not in (x, y)]
    if not hidden:
        return None
    per_axis = max(2, int(round(samples ** (1 / len(hidden)))))
    grids = {x: xs, y: ys, **{a: np.linspace(scenario.lower[a], scenario.upper[a], per_axis) for a in hidden}}
    member = _member(centres, h, scenario.lower, scenario.upper)
    safe = member(_points(scenario, grids, {}))
    return safe.reshape(len(xs), len(ys), -1).all(axis=2)


def _draw_runs(ax, trajectories, labels, x, y) -> None:
    # up to 8 runs: Dark2's distinct colours; more: the warm end of turbo (adjacent runs
    # differ); neither is the safe set's blue
    many = len(trajectories) > 8
    colours = plt.get_cmap("turbo")(np.linspace(0.55, 1.0, len(trajectories))) if many else \
        [plt.get_cmap("Dark2")(k) for k in range(len(trajectories))]
    for t, colour, label in zip(trajectories, colours, labels):
        ax.plot(t[:, x], t[:, y], color=colour, linewidth=1.3, label=label)
        ax.plot(t[0, x], t[0, y], "o", color=colour, markeredgecolor="black", markersize=6)
        ax.plot(t[-1, x], t[-1, y], "X", color=colour, markeredgecolor="black", markersize=7)


def failures_figure(scenario, centres, h, trajectories, labels=None):
    """Figure of ``failures`` (see draw_failures)."""
    trajectories = [np.asarray(t, dtype=float) for t in trajectories]
    for k, t in enumerate(trajectories):
        if t.ndim != 2 or t.shape[1] != scenario.n or not len(t):
            raise ValueError(f"failures: trajectory {k} has shape {t.shape}; expected (T >= 1, {scenario.n})")
    if labels is not None and len(labels) != len(trajectories):
        raise ValueError(f"failures: {len(labels)} labels for {len(trajectories)} trajectories")
    named = labels is not None and len(trajectories) <= 10  # a longer legend would bury the plot
    labels = [str(s) for s in labels] if named else [None] * len(trajectories)
    centres = np.asarray(centres, dtype=float).reshape(-1, scenario.n)
    planes = _planes(scenario)
    fig, axs = plt.subplots(1, len(planes), figsize=(6 * len(planes) + 1.8, 5.2), squeeze=False, layout="constrained")
    for ax, (x, y) in zip(axs[0], planes):
        xs, ys, shadow = _projection(scenario, centres, h, x, y)
        _paint(ax, shadow, _extent(scenario, x, y), SAFE_COLOUR, alpha=0.25)
        core = _core(scenario, centres, h, x, y, xs, ys)
        if core is not None:
            _paint(ax, core, _extent(scenario, x, y), SAFE_COLOUR, alpha=0.7)
        lo, hi = scenario.lower, scenario.upper
        ax.add_patch(Rectangle((lo[x], lo[y]), hi[x] - lo[x], hi[y] - lo[y], fill=False, linestyle="--",
                               edgecolor="0.3"))
        _draw_runs(ax, trajectories, labels, x, y)
        ax.set_xlim(*_limits(lo[x], hi[x], trajectories, x))
        ax.set_ylim(*_limits(lo[y], hi[y], trajectories, y))
        ax.set_xlabel(_label(scenario, x))
        ax.set_ylabel(_label(scenario, y))
        others = [scenario.state_names[a] for a in range(scenario.n) if a not in (x, y)]
        ax.set_title(f"projection onto ({scenario.state_names[x]}, {scenario.state_names[y]})"
                     + (f" along {', '.join(others)}" if others else ""), fontsize=9)
    hidden = scenario.n > 2
    handles = [Patch(facecolor=SAFE_COLOUR, alpha=0.7, label="safe for every value\nof the other coordinates")
               if hidden else None,
               Patch(facecolor=SAFE_COLOUR, alpha=0.25, label="safe for some value\nof the other coordinates"
                     if hidden else "safe set"),
               Line2D([], [], color="0.3", linestyle="--", label="Sigma"),
               Line2D([], [], marker="o", linestyle="", color="0.5", markeredgecolor="black", label="start"),
               Line2D([], [], marker="X", linestyle="", color="0.5", markeredgecolor="black", label="last state")]
    handles = [h_ for h_ in handles if h_ is not None]
    handles += [Line2D([], [], color=line.get_color(), label=line.get_label())
                for line in axs[0, 0].get_lines() if named and not line.get_label().startswith("_")]
    name = " / ".join(str(p) for p in (scenario.name, getattr(scenario, "sv_policy_name", None)) if p)
    fig.suptitle(f"{name}: {len(trajectories)} failing run{'s' * (len(trajectories) != 1)} "
                 f"over the safe set ({len(centres)} boxes, half-width {h:g})", fontsize=10)
    fig.legend(handles=handles, loc="outside right center", fontsize=9)
    return fig


def draw_failures(path, scenario, centres, h, trajectories, labels=None) -> Path:
    """Failing runs drawn over the safe set (``centres`` (M, n), half-width ``h``).

    ``trajectories``: a list of (T, n) state arrays (e.g. the failing runs of a campaign
    recording, ``farm.recording.read_recording(...)["runs"][i]["trajectory"]``);
    ``labels``: optional names, one per run, listed in the legend (when there are at most
    10 runs). One panel per plane of the scenario's slices (fleet3: (v0, p10) and
    (v0, p20)), on which the safe set is shown as its projection (shadow) along the other
    coordinates, Sigma dashed, each run as a line from its start (circle) to its last
    state (cross). Writes the PNG at ``path`` (parent directories created); -> ``path``.
    Raises ValueError on a trajectory of the wrong shape or a label count mismatch."""
    return _save(failures_figure(scenario, centres, h, trajectories, labels), path)
