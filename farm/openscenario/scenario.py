"""OpenSCENARIO scenario definitions: a recorded run as a concrete scenario, and the
logical scenario a parameter distribution samples.

Both put the vehicles on the straight road of ``road.py`` (lane -1 of road 1) as
``layout.py`` places them, and name the SV (entity ``sv``) as the controller under test:

- its ``ObjectController`` is a ``Controller`` named ``controller_under_test`` (with the
  property ``esminiController = ExternalController``, esmini's name for "an outside
  program drives this entity"), and its ``Properties`` carry ``type = ego_vehicle``
  (how CARLA ScenarioRunner finds the ego);
- the parameter ``SvDriver`` says who drives it: ``controller_under_test`` (default:
  the controller is activated at t = 0, so the tool's ADS drives the SV),
  ``recorded`` (concrete scenarios only: the SV replays the speeds the tested SV had,
  to watch the recorded failure), or ``none`` (nothing is activated; the tool's own
  ego handling decides).

The environment's vehicles (``lead``, ``follower``) get their recorded speeds step by
step: at t = k dt a ``SpeedAction`` takes each one linearly, over dt, to its speed at
step k + 1, which is the farm's constant acceleration within the step. A vehicle that
stops inside a step (v + a dt < 0) ramps to 0 over the whole step instead of stopping
early: at most |a| dt^2 / 8 (9 mm at 7 m/s^2) further than the farm moved it. After the
recorded steps every vehicle keeps its last speed; the storyboard stops at the farm's
horizon or at a collision of the SV.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from farm.openscenario.elements import AUTHOR, el, now, num
from farm.openscenario.layout import FRONT_OVERHANG, HEIGHT, REAR_OVERHANG, WIDTH, Layout
from farm.openscenario.road import LANE_ID, ROAD_ID

SV = "sv"
SV_DRIVER = "SvDriver"
UNDER_TEST, RECORDED = "controller_under_test", "recorded"  # SvDriver values ("none": neither)
CONTROLLER = "controller_under_test"
EARLY = 1e-3  # [s] time conditions fire this much before k dt, so a tool's float clock never delays them a frame
MAX_SPEED = 70.0  # [m/s] the vehicles' declared performance
MIN_ACCEL = 10.0  # [m/s^2]


def header(root: ET.Element, rev_minor: int, description: str, properties: dict | None = None) -> ET.Element:
    head = el(root, "FileHeader", revMajor=1, revMinor=rev_minor, date=now(), description=description, author=AUTHOR)
    if properties:  # FileHeader Properties exist from OpenSCENARIO 1.1 on
        props = el(head, "Properties")
        for name, value in properties.items():
            el(props, "Property", name=name, value=str(value))
    return head


def concrete_scenario(layout: Layout, trajectory: np.ndarray, *, horizon: int, description: str, road_file: str,
                      sv_policy: str) -> ET.Element:
    """A recorded run ((L, n) states from its start) as an OpenSCENARIO 1.0 scenario."""
    s, v = layout.place(np.asarray(trajectory, dtype=float))
    root = el(None, "OpenSCENARIO")
    header(root, 0, description)
    _parameters(root, {SV_DRIVER: ("string", UNDER_TEST)})
    _world(root, layout, road_file, sv_policy)
    board = el(root, "Storyboard")
    _init(board, layout, [num(x) for x in s[0]], [num(x) for x in v[0]])
    story = el(board, "Story", name="recorded_run")
    _environment_act(story, layout, v)
    _sv_acts(story, v[:, 0], layout.dt)
    _stop(board, layout, horizon)
    return root


def logical_scenario(layout: Layout, *, horizon: int, description: str, road_file: str, sv_policy: str,
                     defaults: np.ndarray, actions: np.ndarray) -> ET.Element:
    """The scenario whose parameters are the state variables (OpenSCENARIO 1.2: positions
    and speeds are expressions of them), the environment holding ``actions`` (m,) from
    t = 0: the scenario a ParameterValueDistribution over start states refers to."""
    sc = layout.scenario
    A, a, B, b = layout.affine()
    root = el(None, "OpenSCENARIO")
    header(root, 2, description)
    params = {name: ("double", num(x)) for name, x in zip(sc.state_names, defaults)}
    params[SV_DRIVER] = ("string", UNDER_TEST)
    _parameters(root, params)
    _world(root, layout, road_file, sv_policy)
    board = el(root, "Storyboard")
    _init(board, layout, [_expression(row, c, sc.state_names) for row, c in zip(A, a)],
          [_expression(row, c, sc.state_names) for row, c in zip(B, b)])
    story = el(board, "Story", name="held_actions")
    act = el(story, "Act", name="environment")
    held = [(role, float(u)) for role, u in zip(layout.roles[1:], actions) if u != 0.0]
    for role, u in held:  # without an action a vehicle holds its speed
        private = _event(_maneuver(act, role), f"{role}_holds_action", "hold", -EARLY)
        _speed(private, 0.0 if u < 0 else MAX_SPEED, "linear", "rate", abs(u))
    if not held:
        _maneuver(act, layout.roles[-1])
    _start_at(act, -EARLY)
    _sv_acts(story, None, layout.dt)
    _stop(board, layout, horizon)
    return root


# -- pieces ----------------------------------------------------------------------------------
def _expression(coefficients, constant: float, names) -> str:
    """c . sigma + constant as an OpenSCENARIO 1.1+ expression of the state parameters
    (a bare ``$name`` when it is one of them, a number when none enters)."""
    terms = [(float(c), name) for c, name in zip(coefficients, names) if c != 0.0]
    if not terms:
        return num(constant)
    if len(terms) == 1 and terms[0][0] == 1.0 and constant == 0.0:
        return f"${terms[0][1]}"
    parts = []
    for c, name in terms:
        term = f"${name}" if abs(c) == 1.0 else f"{num(abs(c))} * ${name}"
        parts.append(("- " if c < 0 else "+ ") + term)
    if constant != 0.0:
        parts.append(("- " if constant < 0 else "+ ") + num(abs(constant)))
    text = " ".join(parts)
    return "${" + (text[2:] if text.startswith("+ ") else text) + "}"


def _parameters(root, params: dict) -> None:
    decl = el(root, "ParameterDeclarations")
    for name, (kind, value) in params.items():
        el(decl, "ParameterDeclaration", name=name, parameterType=kind, value=value)


def _world(root, layout: Layout, road_file: str, sv_policy: str) -> None:
    el(root, "CatalogLocations")
    el(el(root, "RoadNetwork"), "LogicFile", filepath=road_file)
    entities = el(root, "Entities")
    sc = layout.scenario
    accel = max(MIN_ACCEL, float(np.max(np.abs([sc.action_lower, sc.action_upper]))), float(sc.sv_accel_bound))
    for role in layout.roles:
        obj = el(entities, "ScenarioObject", name=role)
        vehicle = el(obj, "Vehicle", name=role, vehicleCategory="car")
        el(vehicle, "ParameterDeclarations")
        box = el(vehicle, "BoundingBox")
        el(box, "Center", x=layout.length / 2 - REAR_OVERHANG, y=0.0, z=HEIGHT / 2)
        el(box, "Dimensions", width=WIDTH, length=layout.length, height=HEIGHT)
        el(vehicle, "Performance", maxSpeed=MAX_SPEED, maxAcceleration=accel, maxDeceleration=accel)
        axles = el(vehicle, "Axles")
        wheel = {"maxSteering": 0.5, "wheelDiameter": 0.6, "trackWidth": 1.6, "positionZ": 0.3}
        el(axles, "FrontAxle", positionX=layout.length - REAR_OVERHANG - FRONT_OVERHANG, **wheel)
        el(axles, "RearAxle", positionX=0.0, **{**wheel, "maxSteering": 0.0})
        props = el(vehicle, "Properties")
        el(props, "Property", name="type", value="ego_vehicle" if role == SV else "simulation")
        el(props, "Property", name="scenario_farm_role", value=role)
        if role == SV:
            controller = el(el(obj, "ObjectController"), "Controller", name=CONTROLLER)
            cprops = el(controller, "Properties")
            el(cprops, "Property", name="esminiController", value="ExternalController")
            el(cprops, "Property", name="scenario_farm_role", value="controller under test")
            el(cprops, "Property", name="scenario_farm_sv_policy", value=sv_policy)


def _init(board, layout: Layout, positions: list[str], speeds: list[str]) -> None:
    actions = el(el(board, "Init"), "Actions")
    for role, s, v in zip(layout.roles, positions, speeds):
        private = el(actions, "Private", entityRef=role)
        pos = el(el(el(private, "PrivateAction"), "TeleportAction"), "Position")
        el(pos, "LanePosition", roadId=ROAD_ID, laneId=str(LANE_ID), offset=0.0, s=s)
        _speed(el(private, "PrivateAction"), v, "step", "time", 0.0)


def _speed(private_action, target: str | float, shape: str, dimension: str, value: float) -> None:
    speed = el(el(private_action, "LongitudinalAction"), "SpeedAction")
    el(speed, "SpeedActionDynamics", dynamicsShape=shape, value=value, dynamicsDimension=dimension)
    el(el(speed, "SpeedActionTarget"), "AbsoluteTargetSpeed", value=target)


def _maneuver(act, role: str):
    group = el(act, "ManeuverGroup", maximumExecutionCount=1, name=f"{role}_group")
    el(el(group, "Actors", selectTriggeringEntities=False), "EntityRef", entityRef=role)
    return el(group, "Maneuver", name=f"{role}_maneuver")


def _event(maneuver, name: str, action: str, at: float) -> ET.Element:
    """An event of one action that starts once simulation time exceeds ``at``; -> the
    action's (empty) PrivateAction."""
    event = el(maneuver, "Event", name=name, priority="overwrite", maximumExecutionCount=1)
    private = el(el(event, "Action", name=action), "PrivateAction")
    _start_at(event, at)
    return private


def _start_at(parent, at: float) -> None:
    _condition(el(parent, "StartTrigger"), "start", "SimulationTimeCondition", value=round(at, 9), rule="greaterThan")


def _condition(trigger, name: str, kind: str, **attrs) -> None:
    cond = el(el(trigger, "ConditionGroup"), "Condition", name=name, delay=0.0, conditionEdge="none")
    el(el(cond, "ByValueCondition"), kind, **attrs)


def _speed_steps(maneuver, role: str, speeds: np.ndarray, dt: float) -> None:
    for k in range(len(speeds) - 1):
        private = _event(maneuver, f"{role}_step_{k}", f"{role}_speed_{k + 1}", k * dt - EARLY)
        _speed(private, float(speeds[k + 1]), "linear", "time", dt)


def _environment_act(story, layout: Layout, speeds: np.ndarray) -> None:
    act = el(story, "Act", name="environment")
    for r, role in enumerate(layout.roles[1:], start=1):
        _speed_steps(_maneuver(act, role), role, speeds[:, r], layout.dt)
    _start_at(act, -EARLY)


def _sv_acts(story, recorded: np.ndarray | None, dt: float) -> None:
    act = el(story, "Act", name="sv_controller_under_test")
    private = _event(_maneuver(act, SV), "activate_controller_under_test", "activate", -EARLY)
    el(private, "ActivateControllerAction", longitudinal=True, lateral=True)
    _condition(el(act, "StartTrigger"), "sv_driver", "ParameterCondition", parameterRef=SV_DRIVER, value=UNDER_TEST,
               rule="equalTo")
    if recorded is None:
        return
    act = el(story, "Act", name="sv_recorded")
    _speed_steps(_maneuver(act, SV), SV, recorded, dt)
    _condition(el(act, "StartTrigger"), "sv_driver", "ParameterCondition", parameterRef=SV_DRIVER, value=RECORDED,
               rule="equalTo")


def _stop(board, layout: Layout, horizon: int) -> None:
    trigger = el(board, "StopTrigger")
    _condition(trigger, "horizon", "SimulationTimeCondition", value=round((horizon - 1) * layout.dt, 9),
               rule="greaterThan")
    cond = el(el(trigger, "ConditionGroup"), "Condition", name="sv_collision", delay=0.0, conditionEdge="rising")
    by_entity = el(cond, "ByEntityCondition")
    el(el(by_entity, "TriggeringEntities", triggeringEntitiesRule="any"), "EntityRef", entityRef=SV)
    el(el(el(by_entity, "EntityCondition"), "CollisionCondition"), "ByType", type="vehicle")
