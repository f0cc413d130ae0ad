"""What a figure shows and says: the scenario's views and slices, axis labels, titles."""

from __future__ import annotations

import textwrap

import numpy as np

from farm.reports.plots.membership import _axis, _held
from farm.reports.plots.style import LEVELS


LABEL_CHARS = 34  # an axis label's line: a panel's width of a 4-inch panel at 9-10 points


def _label(scenario, axis: int) -> str:
    """Axis label with what the state is and its unit (scenarios/base.py ``Scenario.label``:
    "v0 (the SV's speed, m/s)"), wrapped to a panel's width."""
    return "\n".join(textwrap.wrap(scenario.label(scenario.state_names[axis]), LABEL_CHARS))


def _setting(scenario, axis: int, value: float) -> str:
    """A held coordinate in words, "v1 = 6.67 m/s"."""
    name = scenario.state_names[axis]
    unit = getattr(scenario, "units", {}).get(name)
    return f"{name} = {value:.3g}" + (f" {unit}" if unit else "")


def _settings(scenario, held: dict[int, float]) -> str:
    return ", ".join(_setting(scenario, a, v) for a, v in held.items())


def _title(scenario, safe_set, summary=None) -> str:
    """"<scenario> / <SV policy> / <algorithm>: <M> boxes, half-width <w>"; ``summary``
    (farm.reports.summary.Summary, optional) names them as the campaign did."""
    parts = [summary.scenario if summary else scenario.name,
             (summary.sv_policy if summary else "") or getattr(scenario, "sv_policy_name", None),
             summary.algorithm if summary else None]
    return f"{' / '.join(str(p) for p in parts if p)}: {len(safe_set)} boxes, {safe_set.describe_widths()}"


def _key(scenario, width: int = 150) -> str:
    """What the state names mean, "v0: the SV's speed; ...", wrapped into lines of
    ``width`` characters; "" for a scenario that does not say (``state_words``)."""
    words = getattr(scenario, "state_words", {})
    parts = [f"{name}: {words[name]}" for name in scenario.state_names if name in words]
    return "\n".join(textwrap.wrap("; ".join(parts), width)) if parts else ""


CHARS_PER_INCH = 12  # a 10-point title line: about 12 characters per inch of figure


def _with_key(title: str, scenario, fig=None) -> str:
    """A figure's title, then the key of the state names (figures must say what v0 is),
    each line wrapped to the figure's width (``fig``; 80 characters without one)."""
    key = _key(scenario)
    text = f"{title}\n{key}" if key else title
    width = int(fig.get_figwidth() * CHARS_PER_INCH) if fig is not None else 80
    return "\n".join(textwrap.fill(line, max(width, 40)) for line in text.split("\n"))


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


def held_values(scenario, hold: dict[str, float] | None) -> dict[int, float]:
    """A user's held values (state name -> value) checked against the scenario -> axis
    -> value; ValueError naming the axis and its range on an unknown name or a value
    outside Sigma."""
    out = {}
    for name, value in (hold or {}).items():
        if name not in scenario.state_names:
            raise ValueError(f"hold: unknown axis {name!r}; the axes are {', '.join(scenario.state_names)}")
        a = list(scenario.state_names).index(name)
        lo, hi = float(scenario.lower[a]), float(scenario.upper[a])
        if not lo <= float(value) <= hi:
            raise ValueError(f"hold: {name} = {value:g} is out of range; allowed [{lo:g}, {hi:g}]")
        out[a] = float(value)
    return out


def _cuts(scenario, spec, hold: dict[int, float] | None = None) -> list[tuple[int, int, dict[int, float]]]:
    """A Slices hint -> panels (x, y, held coordinates): one per level of ``varied``;
    the coordinates shown in none are held at ``hold`` (axis -> value), else mid-range."""
    x, y = _axis(scenario, spec.x), _axis(scenario, spec.y)
    if spec.varied is None:
        return [(x, y, _held(scenario, (x, y), hold))]
    v = _axis(scenario, spec.varied)
    # the varied coordinate first: it is what changes along a row, so it leads the title
    return [(x, y, {v: float(level), **_held(scenario, (x, y, v), hold)})
            for level in np.linspace(scenario.lower[v], scenario.upper[v], LEVELS)]


def _planes(scenario) -> list[tuple[int, int]]:
    """The distinct (x, y) planes of the scenario's slices (fleet3: (v0, p10), (v0, p20))."""
    planes = []
    for spec in _slices(scenario):
        plane = (_axis(scenario, spec.x), _axis(scenario, spec.y))
        if plane not in planes:
            planes.append(plane)
    return planes


def _panel_title(scenario, held: dict[int, float]) -> str:
    return _settings(scenario, held) if held else "the whole state plane"
