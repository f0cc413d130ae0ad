"""Figures of a safe set: the files quantification writes, and what the figures say.

Synthetic sets (grid-aligned boxes inside Sigma, with a known boundary) instead of
campaigns, so that every test takes a second or two; the figure-building functions
return matplotlib Figures, inspected here before anything is saved."""

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.text import Text

from coordinator.safe_set import SafeSet
from farm.reports import plots
from farm.reports.plots.layout import _key
from farm.reports.plots.membership import Boxes
from farm.reports.summary import Summary
from scenarios.base import Slices
from scenarios.fleet3 import Fleet3
from scenarios.lead_follow import LeadFollow
from scenarios.toy import Toy

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def grid_centres(scenario, h, keep):
    """Centres of the boxes of half-width h tiling Sigma, those where ``keep`` holds."""
    axes = [np.arange(lo + h, hi, 2 * h) for lo, hi in zip(scenario.lower, scenario.upper)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, scenario.n)
    return centres[keep(centres)]


def uniform_set(sc, centres, h):
    return SafeSet.uniform(centres, h, sc.state_names)


def named(scenario, algorithm, sv_policy=""):
    """A summary that names a campaign (all the figures read of it)."""
    return Summary(scenario=scenario, sv_policy=sv_policy, algorithm=algorithm, boxes=0, result_hash="",
                   guarantee="")


def lead_follow_set():
    # safe when the gap is at least 2 * (v0 - v1): boundary from 0 m up to 40 m of 70 m
    sc = LeadFollow("idm")
    return sc, uniform_set(sc, grid_centres(sc, 1.0, lambda c: c[:, 2] + 1 >= 2 * (c[:, 0] - c[:, 1])), 1.0)


def fleet3_set(failure_facets=None):
    # lead side: p10 large enough when v0 > v1; rear side: p20 small enough when v2 > v0
    sc = Fleet3("idm", failure_facets=failure_facets)
    facets = set(sc.failure_facets)

    def keep(c):
        ok = np.ones(len(c), dtype=bool)
        if "p10" in facets:
            ok &= (c[:, 3] >= 8) | (c[:, 0] <= c[:, 1])
        if "p20" in facets:
            ok &= (c[:, 4] <= -8) | (c[:, 2] <= c[:, 0])
        return ok

    return sc, uniform_set(sc, grid_centres(sc, 1.5, keep), 1.5)


def texts(fig):
    return [t.get_text() for t in fig.findobj(Text) if t.get_text()]


def flat(text):
    """An axis label as one line (labels are wrapped to a panel's width)."""
    return " ".join(text.split())


def visible_axes(fig, projection=None):
    return [ax for ax in fig.axes if ax.get_visible() and (projection is None or ax.name == projection)]


def legend_texts(fig):
    return [t.get_text() for legend in fig.legends for t in legend.get_texts()]


def assert_png(path):
    assert path.exists() and path.stat().st_size > 5000
    assert path.read_bytes()[:8] == PNG


def test_draw_writes_the_public_files_for_lead_follow(tmp_path):
    sc, safe_set = lead_follow_set()
    written = plots.draw(tmp_path / "plots", sc, safe_set, named("lead-follow", "spe"))
    assert written == [tmp_path / "plots" / "safe_set_3d.png", tmp_path / "plots" / "safe_set_slices.png",
                       tmp_path / "plots" / "safe_set_projections.png"]
    for path in written:
        assert_png(path)


def test_draw_writes_the_files_of_fleet3_total_and_sides(tmp_path):
    # as farm.jobs.quantification calls it: the total, then one directory per side
    sc, safe_set = fleet3_set()
    plots.draw(tmp_path / "plots", sc, safe_set, named("fleet3", "spe", "idm"))
    for label, facet in [("lead", "p10"), ("rear", "p20")]:
        side, side_set = fleet3_set((facet,))
        plots.draw(tmp_path / "plots" / f"{label}_side", side, side_set, named("fleet3", f"{label} side", "idm"))
    for folder in ("", "lead_side", "rear_side"):
        for name in ("safe_set_3d.png", "safe_set_slices.png", "safe_set_projections.png"):
            assert_png(tmp_path / "plots" / folder / name)


def test_3d_axes_carry_units_a_colour_bar_and_limits_that_fit_the_surface():
    sc, safe_set = lead_follow_set()
    fig = plots.surface_figure(sc, safe_set)
    (ax,) = visible_axes(fig, "3d")
    assert [flat(t) for t in (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel())] == [
        "v0 (the SV's speed, m/s)", "v1 (the lead's speed, m/s)", "p10 (the gap from the SV's front to the lead's rear, m)"]
    colour_bars = [a for a in fig.axes if a is not ax]
    assert len(colour_bars) == 1 and flat(colour_bars[0].get_ylabel()) == f"smallest safe {sc.label('p10')}"
    assert ax.get_xlim() == (0.0, 20.0) and ax.get_ylim() == (0.0, 20.0)
    zmin, zmax = ax.get_zlim()
    # the boundary runs from 0 m (v0 <= v1) to 34 m (the box at v0 = 19, v1 = 1): the z axis
    # spans that, not all of Sigma's 70 m
    assert zmin == pytest.approx(0.0) and 34 <= zmax <= 40
    assert "mid-range" not in " ".join(texts(fig)) and "held at" not in " ".join(texts(fig))


def test_slices_without_an_exploration_record_have_a_legend_units_and_two_distinct_non_white_colours():
    sc, safe_set = lead_follow_set()
    fig = plots.slices_figure(sc, safe_set)
    panels = visible_axes(fig)
    assert len(panels) == 4
    for ax in panels:
        assert (flat(ax.get_xlabel()), flat(ax.get_ylabel())) == (sc.label("v0"), sc.label("p10"))
    assert legend_texts(fig) == ["in the safe set", "not in the safe set"]
    safe, outside = (np.array(to_rgba(c)[:3]) for c in (plots.SAFE_COLOUR, plots.OUTSIDE_COLOUR))
    assert np.abs(safe - outside).max() > 0.4  # told apart at a glance
    assert np.abs(outside - 1.0).max() > 0.15  # not paper white
    # the first panel is v1 = 0: (v0 = 2, p10 = 60) is safe, (v0 = 18, p10 = 5) is not
    image = panels[0].images[0].get_array()  # (y, x, RGBA), origin lower, extent = Sigma
    row, col = lambda p10: int(p10 / 70 * image.shape[0]), lambda v0: int(v0 / 20 * image.shape[1])
    np.testing.assert_allclose(image[row(60), col(2), :3], safe)
    np.testing.assert_allclose(image[row(5), col(18), :3], outside)


def explored_below_v0(sc, v0):
    """Exploration record of a synthetic campaign: every box of Sigma with v0 < ``v0``
    (centres, half-width 1): outside the safe set there, pruned; elsewhere never explored."""
    boxes = grid_centres(sc, 1.0, lambda c: c[:, 0] < v0)
    return boxes, np.full(len(boxes), 1.0)


def pixel(ax, x, y):
    """The colour shown at (x, y) of a slice panel: the top image that paints it."""
    x0, x1, y0, y1 = ax.images[0].get_extent()
    for image in reversed(ax.images):
        rgba = image.get_array()  # (y, x, RGBA), origin lower
        r = int((y - y0) / (y1 - y0) * rgba.shape[0])
        c = int((x - x0) / (x1 - x0) * rgba.shape[1])
        if rgba[r, c, 3] > 0:
            return np.asarray(rgba[r, c, :3])
    return np.ones(3)


def test_slices_tell_safe_pruned_and_never_explored_apart():
    sc, safe_set = lead_follow_set()
    fig = plots.slices_figure(sc, safe_set, explored=explored_below_v0(sc, 12))
    assert legend_texts(fig) == ["safe (in the quantified set)", "unsafe: explored and pruned", "never explored"]
    safe, pruned, never = (np.array(to_rgba(c)[:3]) for c in (plots.SAFE_COLOUR, plots.PRUNED_COLOUR,
                                                               plots.NEVER_COLOUR))
    for a, b in [(safe, pruned), (safe, never), (pruned, never)]:
        assert np.abs(a - b).max() > 0.3  # told apart at a glance
    assert np.abs(pruned - 1.0).max() > 0.5  # unsafe is nowhere near paper white
    # the panel v1 = 0: safe above p10 = 2 (v0 - v1); unsafe below it, explored up to v0 = 12
    ax = visible_axes(fig)[0]
    np.testing.assert_allclose(pixel(ax, 2.0, 60.0), safe)
    np.testing.assert_allclose(pixel(ax, 10.0, 5.0), pruned)  # explored, outside the set
    np.testing.assert_allclose(pixel(ax, 18.0, 5.0), never)  # outside the set, never explored
    # the never-explored cells are hatched, and only those: one hatched collection
    hatched = [c for c in ax.collections if c.get_hatch()]
    assert len(hatched) == 1
    corners = np.concatenate([p.vertices for p in hatched[0].get_paths()])
    assert corners[:, 0].min() == pytest.approx(12.0, abs=0.2) and corners[:, 1].max() < 36


def test_draw_reads_what_the_campaign_explored_from_its_directory(tmp_path):
    # a ledger of one segment, as the campaign writes it: starts at v0 < 12 with their delta
    import pyarrow as pa
    import pyarrow.parquet as pq

    sc, safe_set = lead_follow_set()
    boxes, widths = explored_below_v0(sc, 12)
    (tmp_path / "ledger").mkdir()
    pq.write_table(pa.table({"sample_index": np.arange(len(boxes)), "round": np.zeros(len(boxes), int),
                             "delta": widths, **{name: boxes[:, i] for i, name in enumerate(sc.state_names)}}),
                   tmp_path / "ledger" / "segment-000000.parquet")
    points, half_widths = plots.explored_boxes(tmp_path, sc.state_names)
    np.testing.assert_allclose(points, boxes)
    assert plots.explored_boxes(tmp_path / "elsewhere", sc.state_names) is None
    # the same classes as with the record passed in: pruned and never-explored pixels
    plots.draw(tmp_path / "plots", sc, safe_set)
    from matplotlib.image import imread

    image = imread(tmp_path / "plots" / "safe_set_slices.png")[..., :3]
    pruned, never = (np.array(to_rgba(c)[:3]) for c in (plots.PRUNED_COLOUR, plots.NEVER_COLOUR))
    assert (np.abs(image - pruned).max(axis=2) < 0.02).sum() > 500
    assert (np.abs(image - never).max(axis=2) < 0.02).sum() > 500
    # explored=False: safe or not, as without a record
    plots.draw(tmp_path / "plots", sc, safe_set, explored=False)
    image = imread(tmp_path / "plots" / "safe_set_slices.png")[..., :3]
    assert (np.abs(image - pruned).max(axis=2) < 0.02).sum() == 0


def test_a_slice_of_a_three_state_scenario_names_its_fixed_coordinate_not_mid_range():
    sc, safe_set = lead_follow_set()
    fig = plots.slices_figure(sc, safe_set)
    words = texts(fig)
    assert not any("mid-range" in w or "other coordinates" in w for w in words)
    assert [ax.get_title() for ax in visible_axes(fig)] == ["v1 = 0 m/s", "v1 = 6.67 m/s", "v1 = 13.3 m/s",
                                                           "v1 = 20 m/s"]


def test_fleet3_slices_and_views_say_where_the_hidden_coordinates_are_held():
    sc, safe_set = fleet3_set()
    slices = plots.slices_figure(sc, safe_set)
    titles = [ax.get_title() for ax in visible_axes(slices)]
    assert titles[0] == "v1 = 0 m/s, v2 = 3 m/s, p20 = -15 m"
    assert titles[4] == "v2 = 0 m/s, v1 = 3 m/s, p10 = 15 m"
    surfaces = plots.surface_figure(sc, safe_set)
    lead, rear = (ax.get_title() for ax in visible_axes(surfaces, "3d"))
    assert lead.startswith("lead side (v0, v1, p10)") and "held at v2 = 3 m/s, p20 = -15 m" in lead
    assert rear.startswith("rear side (v0, v2, p20)") and "held at v1 = 3 m/s, p10 = 15 m" in rear


def test_the_rear_side_figures_show_the_rear_side_only():
    sc, safe_set = fleet3_set(("p20",))
    summary = named("fleet3", "rear side")
    surfaces = plots.surface_figure(sc, safe_set, summary)
    (ax,) = visible_axes(surfaces, "3d")
    assert "rear" in ax.get_title() and "lead" not in ax.get_title()
    assert flat(ax.get_zlabel()) == sc.label("p20") == "p20 (follower minus SV position (front to front), m)"
    assert [flat(a.get_ylabel()) for a in surfaces.axes if a is not ax] == [f"largest safe {sc.label('p20')}"]
    assert "rear side" in surfaces._suptitle.get_text()
    slices = plots.slices_figure(sc, safe_set, summary)
    assert {flat(a.get_ylabel()) for a in visible_axes(slices)} == {sc.label("p20")}
    key = _key(sc)  # what v1 and p10 are, said of every state: the rest is about the rear side only
    lines = [flat(w) for w in texts(surfaces) + texts(slices)]  # titles are wrapped to the figure
    assert not any("lead" in w.replace(key, "") for w in lines)


def test_a_two_state_scenario_gets_slices_only_and_no_held_coordinates(tmp_path):
    sc = Toy()
    safe_set = uniform_set(sc, grid_centres(sc, 0.5, lambda c: (c[:, 0] > 1) & (c[:, 0] < 4)), 0.5)
    assert plots.draw(tmp_path, sc, safe_set) == [tmp_path / "safe_set_slices.png"]
    fig = plots.slices_figure(sc, safe_set)
    (ax,) = visible_axes(fig)
    assert ax.get_title() == "the whole state plane" and (ax.get_xlabel(), ax.get_ylabel()) == ("x", "y")


def test_an_empty_set_is_drawn_and_says_so(tmp_path):
    sc = LeadFollow("idm")
    empty = uniform_set(sc, np.zeros((0, 3)), 1.0)
    written = plots.draw(tmp_path, sc, empty)
    assert len(written) == 3
    fig = plots.surface_figure(sc, empty)
    assert "no safe state in this view" in visible_axes(fig, "3d")[0].get_title()


def test_overlay_writes_a_png_whose_legend_lists_every_set(tmp_path):
    sc, safe_set = lead_follow_set()
    wider = uniform_set(sc, grid_centres(sc, 1.0, lambda c: c[:, 2] + 1 >= (c[:, 0] - c[:, 1])), 1.0)
    path = plots.draw_overlay(tmp_path / "cmp" / "overlay.png", sc, [safe_set, wider], ["brake", "idm"])
    assert path == tmp_path / "cmp" / "overlay.png"
    assert_png(path)
    fig = plots.overlay_figure(sc, [safe_set, wider], ["brake", "idm"])
    assert legend_texts(fig) == [f"brake ({len(safe_set)} boxes)", f"idm ({len(wider)} boxes)"]
    panels = visible_axes(fig)
    assert len(panels) == 4 and all(flat(ax.get_ylabel()) == sc.label("p10") for ax in panels)
    # each set is outlined in its own colour where its boundary crosses the panel
    outline_colours = {tuple(np.round(c.get_edgecolor()[0][:3], 3)) for c in panels[0].collections}
    assert len(outline_colours) == 2
    with pytest.raises(ValueError, match="one label per set"):
        plots.overlay_figure(sc, [safe_set], ["a", "b"])


def test_failures_writes_a_png_with_runs_and_their_starts(tmp_path):
    sc, safe_set = lead_follow_set()
    runs = [np.column_stack([np.linspace(18, 12, 30), np.linspace(10, 0, 30), np.linspace(20, -1, 30)]),
            np.column_stack([np.linspace(15, 9, 20), np.full(20, 2.0), np.linspace(8, -0.5, 20)])]
    path = plots.draw_failures(tmp_path / "failures.png", sc, safe_set, runs, ["run 3", "run 9"])
    assert_png(path)
    fig = plots.failures_figure(sc, safe_set, runs, ["run 3", "run 9"])
    (ax,) = visible_axes(fig)
    assert (flat(ax.get_xlabel()), flat(ax.get_ylabel())) == (sc.label("v0"), sc.label("p10"))
    assert {"start", "last state", "run 3", "run 9"} <= set(legend_texts(fig))
    starts = [line.get_xydata()[0] for line in ax.get_lines() if line.get_marker() == "o"]
    np.testing.assert_allclose(starts, [[18, 20], [15, 8]])
    assert ax.get_ylim()[0] < -1  # a failing run leaves Sigma: the axes show where
    with pytest.raises(ValueError, match="trajectory 0"):
        plots.failures_figure(sc, safe_set, [np.zeros((5, 2))])


def test_failures_of_fleet3_get_one_panel_per_plane(tmp_path):
    sc, safe_set = fleet3_set()
    run = np.tile([4.5, 1.5, 1.5, 9.5, -15.0], (10, 1))
    run[:, 3] = np.linspace(9.5, 4.8, 10)
    fig = plots.failures_figure(sc, safe_set, [run])
    assert [(flat(ax.get_xlabel()), flat(ax.get_ylabel())) for ax in visible_axes(fig)] == [
        (sc.label("v0"), sc.label("p10")), (sc.label("v0"), sc.label("p20"))]
    assert_png(plots.draw_failures(tmp_path / "f.png", sc, safe_set, [run]))


def test_failures_too_many_to_name_still_key_their_colours():
    sc, safe_set = lead_follow_set()
    runs = [np.column_stack([np.linspace(18, 12, 10), np.full(10, 2.0), np.linspace(20 - k, -1, 10)]) for k in range(12)]
    fig = plots.failures_figure(sc, safe_set, runs, [f"sample {k}" for k in range(12)])
    (key,) = [t for t in legend_texts(fig) if "failing runs" in t]
    assert flat(key) == "12 failing runs, one colour each: sample 0 yellow-green to sample 11 dark red"
    assert not {"sample 0", "sample 11"} & set(legend_texts(fig))  # not one entry per run
    unnamed = plots.failures_figure(sc, safe_set, runs[:3])
    assert "3 failing runs, one colour each" in legend_texts(unnamed)


def _grid_points(grids: dict, fixed: dict, n: int) -> np.ndarray:
    """Every combination of ``grids`` (axis -> values, 'ij' order) as rows, the other
    coordinates at ``fixed``; a coordinate in neither is NaN (in no box)."""
    mesh = np.meshgrid(*grids.values(), indexing="ij")
    pts = np.full((mesh[0].size, n), np.nan)
    for axis, value in fixed.items():
        pts[:, axis] = value
    for axis, values in zip(grids, mesh):
        pts[:, axis] = values.ravel()
    return pts


def _indexed(centres, widths, n, pts):
    """The spatial index's membership (coordinator/spatial.py): one index per half-width."""
    from coordinator.spatial import PointIndex

    widths = np.broadcast_to(widths, (len(centres),))
    inside = np.zeros(len(pts), dtype=bool)
    with np.errstate(invalid="ignore"):  # NaN coordinates: in no box
        for w in np.unique(widths):
            index = PointIndex(n, 2 * w, centres.min(axis=0))
            index.insert(centres[widths == w])
            inside |= index.any_within(pts, w)
    return inside


def test_membership_painted_on_a_grid_answers_as_the_spatial_index():
    """The figures paint each box onto the pixel grid instead of querying every pixel:
    the decisions of the spatial index, on box faces and tolerances too (grid-aligned
    sets of mixed sizes, samples on the faces, an axis sampled downwards, a held value
    on a face, one held coordinate, two, none, and an unset one)."""
    rng = np.random.default_rng(5)
    cuts = [({0: np.linspace(0, 10, 81), 1: np.linspace(0, 10, 41)}, {2: 5.0}),
            ({0: np.linspace(0, 10, 41), 1: np.linspace(10, 0, 41), 2: np.linspace(0, 10, 21)}, {}),
            ({1: (np.arange(60) + 0.5) / 6, 2: np.linspace(0, 10, 41)}, {0: 3.25}),
            ({0: np.linspace(0, 10, 41), 1: np.linspace(0, 10, 41)}, {2: 5.25 + 1e-9}),
            ({0: np.linspace(0, 10, 60)}, {1: 3.1, 2: 7.0})]
    outside = 0
    for shift in (0.0, 0.1, 1e-10):
        widths = rng.choice([0.125, 0.25, 0.5, 1.0], 400)
        centres = np.round(rng.uniform(0, 10, (400, 3)) / (2 * widths[:, None])) * 2 * widths[:, None]
        centres += widths[:, None] + shift
        for w in (widths, 0.25):
            boxes = Boxes(centres, w, 3)
            for grids, held in cuts:
                expected = _indexed(centres, w, 3, _grid_points(grids, held, 3))
                expected = expected.reshape([len(v) for v in grids.values()])
                assert expected.any()
                outside += int((~expected).sum())
                assert np.array_equal(boxes.grid(grids, held), expected)
    assert outside > 1000  # the cuts cross the boxes' faces, not only their insides
    assert not Boxes(centres, widths, 3).grid({0: np.linspace(0, 10, 5)}, {2: 1.0}).any()  # axis 1 unset
    assert Boxes(np.zeros((0, 3)), 1.0, 3).grid({0: np.linspace(0, 10, 5)}, {1: 1.0, 2: 1.0}).shape == (5,)


def test_membership_on_a_grid_decides_samples_an_ulp_from_a_face_as_the_spatial_index():
    """Samples at c +- (h + TOLERANCE) as floats and their neighbours: a bisection on the
    rounded face lands a sample off for about a quarter of these boxes; the grid settles
    it by the point test."""
    from coordinator.spatial import TOLERANCE

    rng = np.random.default_rng(1)
    centres, h = rng.uniform(0, 10, (2000, 1)), 0.3
    faces = np.concatenate([centres[:, 0] + (h + TOLERANCE), centres[:, 0] - (h + TOLERANCE)])
    xs = np.unique(np.concatenate([faces, np.nextafter(faces, np.inf), np.nextafter(faces, -np.inf)]))
    for k in range(0, 2000, 100):  # a box at a time: every sample's answer is that box's
        box = centres[k:k + 1]
        assert np.array_equal(Boxes(box, h, 1).grid({0: xs}, {}), _indexed(box, h, 1, xs[:, None]))
        assert np.array_equal(Boxes(box, h, 1).grid({0: xs[::-1]}, {}), _indexed(box, h, 1, xs[::-1, None]))


def test_the_failures_figures_core_is_where_every_hidden_sample_is_in_the_set():
    """failures.png's dark core, cut by cut over the hidden samples, against the set's own
    membership of every (pixel, hidden sample) point: fleet3 (3 hidden axes, 3 samples
    each, Sigma's ends among them, where the boxes' faces lie) with mixed box sizes."""
    from farm.reports.plots.failures import _core
    from farm.reports.plots.membership import _samples

    sc, safe_set = fleet3_set()
    mixed = SafeSet(safe_set.centres, np.where(np.arange(len(safe_set)) % 3 == 0, 2.0, 1.0) * safe_set.finest,
                    sc.state_names)
    cores = shadows_only = 0
    for s in (safe_set, mixed):
        for x, y in ((0, 3), (2, 4)):
            xs = _samples(sc.lower[x], sc.upper[x], 40)
            ys = _samples(sc.lower[y], sc.upper[y], 30)
            hidden = [a for a in range(sc.n) if a not in (x, y)]
            grids = {x: xs, y: ys, **{a: np.linspace(sc.lower[a], sc.upper[a], 3) for a in hidden}}
            inside = s.contains(_grid_points(grids, {}, sc.n)).reshape(40, 30, -1)
            core = _core(sc, s, x, y, xs, ys)
            assert np.array_equal(core, inside.all(axis=2))
            cores += int(core.sum())
            shadows_only += int((inside.any(axis=2) & ~core).sum())
    assert cores > 0 and shadows_only > 0  # safe everywhere somewhere, and only for some hidden values elsewhere


def test_held_values_chosen_by_the_user_set_the_cuts_and_views_and_wrong_ones_are_named():
    sc, safe_set = fleet3_set()
    slices = plots.slices_figure(sc, safe_set, hold={"v2": 1.0, "p20": -20.0})
    titles = [ax.get_title() for ax in visible_axes(slices)]
    assert titles[0] == "v1 = 0 m/s, v2 = 1 m/s, p20 = -20 m"
    assert titles[4] == "v2 = 0 m/s, v1 = 3 m/s, p10 = 15 m"  # v2 varies in that row: its levels win
    surfaces = plots.surface_figure(sc, safe_set, hold={"p20": -20.0})
    assert "p20 = -20 m" in visible_axes(surfaces, "3d")[0].get_title()
    with pytest.raises(ValueError, match="unknown axis 'v9'; the axes are v0, v1, v2, p10, p20"):
        plots.slices_figure(sc, safe_set, hold={"v9": 1.0})
    with pytest.raises(ValueError, match=r"p20 = 3 is out of range; allowed \[-25, -5\]"):
        plots.surface_figure(sc, safe_set, hold={"p20": 3.0})


def test_a_held_value_changes_what_the_cut_shows(tmp_path):
    # fleet3's lead side is unsafe at small p10 only when v0 > v1: holding v1 high clears it
    sc, safe_set = fleet3_set()
    low = plots.slices_figure(sc, safe_set, slices=[Slices("v0", "p10")], hold={"v1": 0.5})
    high = plots.slices_figure(sc, safe_set, slices=[Slices("v0", "p10")], hold={"v1": 5.5})
    assert not np.allclose(pixel(visible_axes(low)[0], 5.0, 6.0), pixel(visible_axes(high)[0], 5.0, 6.0))


def test_projection_shares_are_exact_for_disjoint_boxes_and_said_to_be_bounds_otherwise():
    sc = LeadFollow("idm")
    # two disjoint boxes over the same (v0, p10) square, covering v1 in [0, 5] and [5, 10]
    centres = np.array([[5.0, 2.5, 35.0], [5.0, 7.5, 35.0]])
    widths = np.array([[5.0, 2.5, 35.0], [5.0, 2.5, 35.0]])
    disjoint = SafeSet(centres, widths, sc.state_names, disjoint=True)
    xs, ys, share = plots.projected_share(sc, disjoint, 0, 2, res=40)
    inside = xs < 10
    assert np.allclose(share[inside], 0.5) and np.allclose(share[~inside], 0.0)
    fig = plots.projections_figure(sc, disjoint)
    assert "(at most)" not in " ".join(a.get_ylabel() for a in fig.axes)
    overlapping = SafeSet(centres, widths + [[0, 1.0, 0], [0, 1.0, 0]], sc.state_names)
    fig = plots.projections_figure(sc, overlapping)
    assert "upper bound" in fig._suptitle.get_text()
    assert any("(at most)" in a.get_ylabel() for a in fig.axes)


def test_projection_of_a_seven_axis_set_costs_one_pass_over_its_boxes():
    from scenarios.platoon import Platoon

    sc = Platoon("idm", vehicles=4, followers=1)
    rng = np.random.default_rng(0)
    centres = sc.lower + rng.random((20000, sc.n)) * (sc.upper - sc.lower)
    safe_set = SafeSet(centres, np.full((20000, sc.n), 0.01), sc.state_names, disjoint=True)
    xs, ys, share = plots.projected_share(sc, safe_set, 0, sc.state_names.index("p10"), res=30)
    # each box's hidden share: prod of 0.02 / range over 5 hidden axes; summed where covered
    assert share.max() < 1e-6 and share.sum() > 0


def test_figures_say_what_the_state_names_mean():
    sc, safe_set = fleet3_set()
    for fig in (plots.slices_figure(sc, safe_set), plots.surface_figure(sc, safe_set),
                plots.projections_figure(sc, safe_set)):
        assert "v0: the SV's speed" in fig._suptitle.get_text()
