"""OpenSCENARIO in: a logical scenario's parameter ranges as the claimed domain of
``validate``.

``[validate.openscenario]`` names a ParameterValueDistribution file (OpenSCENARIO 1.1 or
later) and a table mapping state variables to its parameters::

    [validate.openscenario]
    file = "cut_in_distribution.xosc"
    map = { v0 = "EgoSpeed", v1 = "LeadSpeed", p10 = "Gap" }

Each mapped parameter's range becomes that state variable's interval of the claimed box
(the other state variables keep Sigma's bounds): ``DistributionRange``,
``UniformDistribution`` and the ``Range`` of a normal, log-normal or Poisson
distribution give [lowerLimit, upperLimit]; a ``Histogram`` its bins' hull; a
``DistributionSet``, ``ProbabilityDistributionSet`` or ``ValueSetDistribution`` the
hull of the values it lists. Parameters the table does not name are left alone.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from coordinator.domain import DomainError

FIELD = "validate.openscenario"
_BOUNDED = ("UniformDistribution", "NormalDistribution", "LogNormalDistribution", "PoissonDistribution")


def parameter_ranges(path, only=None) -> dict[str, tuple[float, float]]:
    """{parameter: (low, high)} of the parameters a ParameterValueDistribution file
    distributes (of those in ``only``, if given: others may be non-numeric, e.g. a
    weather). Raises DomainError (one line) for a file that is not one."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise DomainError(f"{FIELD}.file: {path}: no such file") from None
    except IsADirectoryError:
        raise DomainError(f"{FIELD}.file: {path}: is a directory, not an OpenSCENARIO file") from None
    except ET.ParseError as exc:
        raise DomainError(f"{FIELD}.file: {path}: not XML ({exc})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DomainError(f"{FIELD}.file: {path}: cannot read it ({type(exc).__name__})") from None
    for node in root.iter():  # a namespace, if a tool wrote one, is not part of the names
        if isinstance(node.tag, str) and node.tag.startswith("{"):
            node.tag = node.tag.split("}", 1)[1]
    pvd = root.find("ParameterValueDistribution")
    if root.tag != "OpenSCENARIO" or pvd is None:
        what = (f"root element <{root.tag}>" if root.tag != "OpenSCENARIO" else
                "a scenario definition" if root.find("Storyboard") is not None else
                "a catalog" if root.find("Catalog") is not None else "no <ParameterValueDistribution>")
        raise DomainError(f"{FIELD}.file: {path}: not an OpenSCENARIO ParameterValueDistribution ({what}); give the "
                          f"distribution file of a logical scenario (OpenSCENARIO 1.1 or later)")
    # parameter -> the (element, attribute) pairs holding its values, or an error to raise if asked for it
    found: dict[str, list] = {}
    for dist in list(pvd.iter("StochasticDistribution")) + list(pvd.iter("DeterministicSingleParameterDistribution")):
        name = dist.get("parameterName") or ""
        kind = next(iter(dist), None)
        tag = kind.tag if kind is not None else "nothing"
        if tag in ("DistributionRange", *_BOUNDED) and kind.find("Range") is not None:
            items = [(kind.find("Range"), "lowerLimit"), (kind.find("Range"), "upperLimit")]
        elif tag in _BOUNDED:
            items = f"has a <{tag}> without a <Range>: unbounded; give it a Range"
        elif tag == "Histogram":
            items = [(r, a) for r in kind.iter("Range") for a in ("lowerLimit", "upperLimit")]
        elif tag in ("DistributionSet", "ProbabilityDistributionSet"):
            items = [(e, "value") for e in kind.iter("Element")]
        else:
            items = (f"has a <{tag}>, which has no range to read; supported: DistributionRange, DistributionSet, "
                     f"UniformDistribution, NormalDistribution/LogNormalDistribution/PoissonDistribution with a "
                     f"Range, Histogram, ProbabilityDistributionSet, ValueSetDistribution")
        _add(found, name, items)
    for assignment in pvd.iter("ParameterAssignment"):
        _add(found, assignment.get("parameterRef") or "", [(assignment, "value")])
    if not found:
        raise DomainError(f"{FIELD}.file: {path}: the ParameterValueDistribution distributes no parameter")
    out = {}
    for name, items in found.items():
        if only is not None and name not in only:
            continue
        if isinstance(items, str):
            raise DomainError(f"{FIELD}.file: {path}: parameter {name!r} {items}")
        values = [_number(path, name, node, attr) for node, attr in items]
        if not values:
            raise DomainError(f"{FIELD}.file: {path}: parameter {name!r} is given no value")
        out[name] = (min(values), max(values))
    return out


def _add(found: dict, name: str, items) -> None:
    before = found.get(name)
    if isinstance(before, list) and isinstance(items, list):
        before.extend(items)  # e.g. a parameter of several value sets
    elif before is None or isinstance(items, str):
        found[name] = items


def parameter_names(path) -> list[str]:
    """The names of the parameters a ParameterValueDistribution file distributes."""
    root = ET.parse(path).getroot()
    names = {n.get("parameterName") for n in root.iter() if str(n.tag).endswith("Distribution") and n.get("parameterName")}
    names |= {n.get("parameterRef") for n in root.iter() if str(n.tag).endswith("ParameterAssignment")}
    return sorted(n for n in names if n)


def _number(path: Path, name: str | None, node: ET.Element, attr: str) -> float:
    text = node.get(attr)
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise DomainError(f"{FIELD}.file: {path}: parameter {name!r}: {attr}={text!r} is not a number (references "
                          f"to other parameters and expressions are not resolved)") from None
    if not math.isfinite(value):
        raise DomainError(f"{FIELD}.file: {path}: parameter {name!r}: {attr}={text!r} is not finite")
    return value


def claimed_box(path, mapping: dict[str, str], scenario) -> dict[str, list[float]]:
    """The ``[validate] domain`` table ({state: [low, high]}) that ``mapping`` ({state:
    parameter}) makes of the file's ranges, checked against Sigma."""
    names = list(scenario.state_names)
    for state in mapping:
        if state not in names:
            raise DomainError(f"{FIELD}.map.{state}: unknown state variable; allowed: {', '.join(names)}")
    ranges = parameter_ranges(path, only=set(mapping.values()))
    box = {}
    for state, parameter in mapping.items():
        if parameter not in ranges:
            have = ", ".join(sorted(parameter_names(path)))
            raise DomainError(f"{FIELD}.map.{state}: parameter {parameter!r} is not distributed in {path} "
                              f"(it distributes: {have})")
        low, high = ranges[parameter]
        i = names.index(state)
        lo, hi = float(scenario.lower[i]), float(scenario.upper[i])
        if not low < high:
            raise DomainError(f"{FIELD}.map.{state}: parameter {parameter!r} takes the single value {low:g} in "
                              f"{path}; a claimed domain needs an interval with low < high")
        if not (lo <= low and high <= hi):
            raise DomainError(f"{FIELD}.map.{state}: parameter {parameter!r} ranges over [{low:g}, {high:g}] in "
                              f"{path}, outside Sigma; allowed {lo:g} <= low < high <= {hi:g}")
        box[state] = [low, high]
    return box


def validate_section(v, scenario) -> dict:
    """A ``[validate]`` section (ValidateConfig) as ``Domain.from_config`` reads it, with
    ``openscenario`` made into the ``domain`` table it claims."""
    section = v.model_dump()
    source = section.pop("openscenario", None)
    if source:
        section["domain"] = claimed_box(source["file"], source["map"], scenario)
    return section
