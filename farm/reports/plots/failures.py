"""Failing runs over the safe set's projection (``plots/failures.png``)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from farm.reports.plots.layout import _label, _planes, _with_key
from farm.reports.plots.membership import Boxes, _samples, _set_member
from farm.reports.plots.slices import _extent, _paint
from farm.reports.plots.style import HIDDEN_SAMPLES, RESOLUTION, SAFE_COLOUR, _save


MANY_RUNS = 8  # more runs than Dark2's distinct colours: a gradient instead


def _projection(scenario, safe_set, x, y):
    """The safe set's shadow on the plane (x, y) as a grid: a run's projected start lies
    in it whatever its other coordinates, which no single slice could promise."""
    lo, hi = scenario.lower[[x, y]], scenario.upper[[x, y]]
    member = Boxes(safe_set.centres[:, [x, y]], safe_set.axis_half_widths[:, [x, y]], 2)
    xs, ys = _samples(lo[0], hi[0], RESOLUTION), _samples(lo[1], hi[1], RESOLUTION)
    return xs, ys, member.grid({0: xs, 1: ys}, {})


def _limits(lo, hi, trajectories, axis):
    """Sigma's range widened to the runs (a failing run leaves Sigma), with a margin."""
    values = [lo, hi] + [v for t in trajectories for v in (t[:, axis].min(), t[:, axis].max())]
    a, b = min(values), max(values)
    pad = 0.03 * (b - a or 1.0)
    return a - pad, b + pad


def _core(scenario, safe_set, x, y, xs, ys, samples: int = HIDDEN_SAMPLES):
    """Where on the grid (xs, ys) of the plane (x, y) every sampled value of the other
    coordinates is safe (``samples`` in all per hidden coordinate, Sigma's ends
    included): a state there is safe whatever its hidden coordinates."""
    hidden = [a for a in range(scenario.n) if a not in (x, y)]
    if not hidden:
        return None
    per_axis = max(2, int(round(samples ** (1 / len(hidden)))))
    values = [np.linspace(scenario.lower[a], scenario.upper[a], per_axis) for a in hidden]

    # one 2-D cut per sampled value of the hidden coordinates, each painted from the boxes
    # that hold it: the boxes are narrowed one hidden axis at a time, shared by the cuts
    # below (a grid over every axis at once paints each box at its 2^n corners)
    def safe_everywhere(boxes: Boxes, depth: int, held: dict) -> np.ndarray:
        if depth == len(hidden):
            return boxes.grid({x: xs, y: ys}, held)
        out = np.ones((len(xs), len(ys)), dtype=bool)
        for value in values[depth]:
            at = {**held, hidden[depth]: value}
            out &= safe_everywhere(boxes.near({hidden[depth]: value}), depth + 1, at)
            if not out.any():
                break  # (nothing left to be safe everywhere)
        return out

    return safe_everywhere(_set_member(scenario, safe_set), 0, {})


def _draw_runs(ax, trajectories, labels, x, y) -> list:
    """Each run a line from its start (circle) to its last state (cross); -> the colours."""
    # up to 8 runs: Dark2's distinct colours; more: the warm end of turbo (adjacent runs
    # differ); neither is the safe set's blue
    many = len(trajectories) > MANY_RUNS
    colours = plt.get_cmap("turbo")(np.linspace(0.55, 1.0, len(trajectories))) if many else \
        [plt.get_cmap("Dark2")(k) for k in range(len(trajectories))]
    for t, colour, label in zip(trajectories, colours, labels):
        ax.plot(t[:, x], t[:, y], color=colour, linewidth=1.3, label=label)
        ax.plot(t[0, x], t[0, y], "o", color=colour, markeredgecolor="black", markersize=6)
        ax.plot(t[-1, x], t[-1, y], "X", color=colour, markeredgecolor="black", markersize=7)
    return list(colours)


def _runs_key(trajectories, labels, named: bool) -> str | None:
    """The legend's line for runs not named one by one: how many, one colour each (and
    the first and last label, when there are labels)."""
    if named:
        return None
    n = len(trajectories)
    text = f"{n} failing run{'s' * (n != 1)}, one colour each"
    if labels is not None and n > MANY_RUNS:  # turbo's warm end, in the runs' order
        text += f":\n{labels[0]} yellow-green\nto {labels[-1]} dark red"
    return text


def failures_figure(scenario, safe_set, trajectories, labels=None):
    """Figure of ``failures`` (see draw_failures)."""
    trajectories = [np.asarray(t, dtype=float) for t in trajectories]
    for k, t in enumerate(trajectories):
        if t.ndim != 2 or t.shape[1] != scenario.n or not len(t):
            raise ValueError(f"failures: trajectory {k} has shape {t.shape}; expected (T >= 1, {scenario.n})")
    if labels is not None and len(labels) != len(trajectories):
        raise ValueError(f"failures: {len(labels)} labels for {len(trajectories)} trajectories")
    named = labels is not None and len(trajectories) <= 10  # a longer legend would bury the plot
    runs_key = _runs_key(trajectories, labels, named)
    labels = [str(s) for s in labels] if named else [None] * len(trajectories)
    planes = _planes(scenario)
    fig, axs = plt.subplots(1, len(planes), figsize=(6 * len(planes) + 1.8, 5.2), squeeze=False, layout="constrained")
    for ax, (x, y) in zip(axs[0], planes):
        xs, ys, shadow = _projection(scenario, safe_set, x, y)
        _paint(ax, shadow, _extent(scenario, x, y), SAFE_COLOUR, alpha=0.25)
        core = _core(scenario, safe_set, x, y, xs, ys)
        if core is not None:
            _paint(ax, core, _extent(scenario, x, y), SAFE_COLOUR, alpha=0.7)
        lo, hi = scenario.lower, scenario.upper
        ax.add_patch(Rectangle((lo[x], lo[y]), hi[x] - lo[x], hi[y] - lo[y], fill=False, linestyle="--",
                               edgecolor="0.3"))
        colours = _draw_runs(ax, trajectories, labels, x, y)
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
    if runs_key and trajectories:  # the runs' colours are keyed too, when they are too many to name
        handles.append(Line2D([], [], color=colours[len(colours) // 2], linewidth=1.3, label=runs_key))
    name = " / ".join(str(p) for p in (scenario.name, getattr(scenario, "sv_policy_name", None)) if p)
    fig.suptitle(_with_key(f"{name}: {len(trajectories)} failing run{'s' * (len(trajectories) != 1)} "
                           f"over the safe set ({len(safe_set)} boxes, {safe_set.describe_widths()})", scenario, fig),
                 fontsize=10)
    fig.legend(handles=handles, loc="outside right center", fontsize=9)
    return fig


def draw_failures(path, scenario, safe_set, trajectories, labels=None) -> Path:
    """Failing runs drawn over ``safe_set`` (a SafeSet).

    ``trajectories``: a list of (T, n) state arrays (e.g. the failing runs of a campaign
    recording, ``farm.directory.recording.read_recording(...)["runs"][i]["trajectory"]``);
    ``labels``: optional names, one per run, listed in the legend (when there are at most
    10 runs). One panel per plane of the scenario's slices (fleet3: (v0, p10) and
    (v0, p20)), on which the safe set is shown as its projection (shadow) along the other
    coordinates, Sigma dashed, each run as a line from its start (circle) to its last
    state (cross). Writes the PNG at ``path`` (parent directories created); -> ``path``.
    Raises ValueError on a trajectory of the wrong shape or a label count mismatch."""
    return _save(failures_figure(scenario, safe_set, trajectories, labels), path)
