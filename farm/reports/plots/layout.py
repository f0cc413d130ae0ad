"""What a figure shows and says: the scenario's views and slices, axis labels, titles."""

from __future__ import annotations

import numpy as np

from farm.reports.plots.membership import _axis, _held
from farm.reports.plots.style import LEVELS


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


def _title(scenario, safe_set, summary=None) -> str:
    """"<scenario> / <SV policy> / <algorithm>: <M> boxes, half-width <w>"; ``summary``
    (farm.reports.summary.Summary, optional) names them as the campaign did."""
    parts = [summary.scenario if summary else scenario.name,
             (summary.sv_policy if summary else "") or getattr(scenario, "sv_policy_name", None),
             summary.algorithm if summary else None]
    return f"{' / '.join(str(p) for p in parts if p)}: {len(safe_set)} boxes, {safe_set.describe_widths()}"


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
