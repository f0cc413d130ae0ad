"""Reading exported OpenSCENARIO files back in the tests: the ASAM schemas (vendored in
tests/asam_schemas/, see its README) with the registry's ``xmlschema``, and a minimal
player of the concrete scenarios this tool writes (step-wise SpeedActions)."""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

SCHEMAS = Path(__file__).resolve().parent / "asam_schemas"
EARLY = 1e-3  # farm/openscenario/scenario.py fires events this much before k dt


@functools.cache
def schema(name: str):
    import xmlschema

    return xmlschema.XMLSchema(str(SCHEMAS / name))


def osc10():
    return schema("OpenSCENARIO_1_0.xsd")


def osc12():
    return schema("OpenSCENARIO_1_2.xsd")


def odr15():
    return schema("OpenDRIVE_1_5M.xsd")


def schema_errors(xsd, path) -> list[str]:
    return [str(e).splitlines()[0] + " " + str(getattr(e, "path", "")) for e in xsd.iter_errors(str(path))]


def play(path, dt: float, sv_driver: str = "recorded") -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Entity -> (reference-point positions s, speeds) at t = k dt, k = 0..K, of a
    concrete scenario: Init places and sets speeds; an event of an active act whose
    SimulationTimeCondition fires at k dt takes its entity linearly over dt to its
    target speed. Acts gated by a ParameterCondition on SvDriver run when it matches."""
    root = ET.parse(path).getroot()
    params = {p.get("name"): p.get("value") for p in root.iter("ParameterDeclaration")}
    params["SvDriver"] = sv_driver
    s0, v0 = {}, {}
    for private in root.find("Storyboard/Init/Actions").iter("Private"):
        name = private.get("entityRef")
        s0[name] = float(private.find(".//LanePosition").get("s"))
        v0[name] = float(private.find(".//AbsoluteTargetSpeed").get("value"))
    targets: dict[str, dict[int, float]] = {name: {} for name in s0}
    for act in root.iter("Act"):
        cond = act.find("StartTrigger//ParameterCondition")
        if cond is not None and params.get(cond.get("parameterRef")) != cond.get("value"):
            continue
        for group in act.iter("ManeuverGroup"):
            entity = group.find("Actors/EntityRef").get("entityRef")
            for event in group.iter("Event"):
                speed = event.find(".//SpeedAction")
                if speed is None:
                    continue
                dyn = speed.find("SpeedActionDynamics")
                assert dyn.get("dynamicsShape") == "linear" and dyn.get("dynamicsDimension") == "time"
                assert float(dyn.get("value")) == dt
                k = round((float(event.find(".//SimulationTimeCondition").get("value")) + EARLY) / dt)
                targets[entity][k] = float(speed.find(".//AbsoluteTargetSpeed").get("value"))
    steps = max((max(t) + 1 for t in targets.values() if t), default=0)
    out = {}
    for name in s0:
        v = np.empty(steps + 1)
        s = np.empty(steps + 1)
        v[0], s[0] = v0[name], s0[name]
        for k in range(steps):
            v[k + 1] = targets[name].get(k, v[k])
            s[k + 1] = s[k] + (v[k] + v[k + 1]) / 2 * dt
        out[name] = (s, v)
    return out
