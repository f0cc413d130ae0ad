"""Where scenarios and back ends are found by name: one dict each, lazy imports.

A new scenario or back end is one file plus one registration (a back end may also be a
per-run simulator, ``scenarios.per_run.RunSimulator``):

    register_scenario("my-scenario", "mypackage.scenarios:MyScenario")
    register_backend("carla", "mypackage.carla:CarlaBackend")

or, for an installed package, an entry point in the groups ``scenario_farm.scenarios`` /
``scenario_farm.backends``. A config may also name any class directly as
``"package.module:Class"`` (imported from the working directory too). Heavy back ends
(SUMO) are imported only when chosen, like Ray Tune's lazy search registry.

A config is code: naming ``module:Class`` imports and runs that module. Only the kind of
object is checked (a Scenario subclass, a back-end class); configs are as trusted as
the code they name.
"""

from __future__ import annotations

import importlib
import inspect
from importlib.metadata import entry_points

from scenarios.base import EXTERNAL_SV, Scenario
from scenarios.per_run import RunSimulator, per_run_backend
from scenarios.errors import ConfigError, FarmError, ScenarioError

SCENARIOS: dict[str, str | type] = {
    "lead-follow": "scenarios.lead_follow:LeadFollow",
    "fleet3": "scenarios.fleet3:Fleet3",
    "platoon": "scenarios.platoon:Platoon",
    "lead-follow-params": "scenarios.lead_follow_params:LeadFollowParams",
    "toy": "scenarios.toy:Toy",
}
BACKENDS: dict[str, str | type] = {
    "numpy": "scenarios.backend:NumpyBackend",
    "sumo": "scenarios.sumo.backend:SumoBackend",
}
_GROUPS = {"scenario": "scenario_farm.scenarios", "backend": "scenario_farm.backends"}
# [scenario] keys that are options of the scenario's constructor (``Scenario.config_options``)
SCENARIO_OPTION_KEYS = ("vehicles", "followers")


def register_scenario(name: str, target: str | type) -> None:
    SCENARIOS[name] = target


def register_backend(name: str, target: str | type) -> None:
    BACKENDS[name] = target


def load_object(target: str, field: str):
    """Import ``package.module:attr``; a one-line error naming ``field`` otherwise."""
    module_name, sep, attr = target.partition(":")
    if not sep or not module_name or not attr:
        raise ConfigError(f"{field}: expected 'package.module:Name', got {target!r}")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"{field}: cannot import module {module_name!r} ({exc}); is it on the path or in the "
                          f"working directory?") from None
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's module raised while importing
        raise ConfigError(f"{field}: importing {module_name!r} raised {type(exc).__name__}: {exc}") from None
    try:
        return getattr(module, attr)
    except AttributeError:
        raise ConfigError(f"{field}: module {module_name!r} has no attribute {attr!r}") from None


def _lookup(kind: str, table: dict, name: str, field: str):
    target = table.get(name)
    if target is None:
        for ep in entry_points(group=_GROUPS[kind]):
            if ep.name == name:
                target = ep.value
    if target is None and ":" in name:
        target = name
    if target is None:
        raise ConfigError(f"{field}: unknown {kind} {name!r}; allowed: {', '.join(table)} or 'package.module:Class'")
    return load_object(target, field) if isinstance(target, str) else target


def scenario_class(name: str) -> type[Scenario]:
    cls = _lookup("scenario", SCENARIOS, name, "scenario.name")
    if not (isinstance(cls, type) and issubclass(cls, Scenario)):
        raise ConfigError(f"scenario.name: {name!r} is not a subclass of scenarios.Scenario")
    if inspect.isabstract(cls):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        raise ConfigError(f"scenario.name: {name!r} does not implement {missing}")
    return cls


def backend_class(name: str) -> type:
    """The back-end class named ``name``; a per-run simulator class (a
    ``scenarios.per_run.RunSimulator``) comes wrapped in its adapter."""
    cls = _lookup("backend", BACKENDS, name, "scenario.backend")
    if isinstance(cls, type) and issubclass(cls, RunSimulator):
        if inspect.isabstract(cls):
            missing = ", ".join(sorted(cls.__abstractmethods__))
            raise ConfigError(f"scenario.backend: {name!r} (class {cls.__name__}) does not implement {missing}; a "
                              f"per-run simulator defines reset(state, key) and step(action) (scenarios/per_run.py)")
        return per_run_backend(cls)
    if not isinstance(cls, type) or not all(callable(getattr(cls, m, None)) for m in ("insert", "step", "keep", "clear")):
        raise ConfigError(f"scenario.backend: {name!r} is not a back end (a class with insert, step, keep, clear) "
                          f"nor a per-run simulator (a scenarios.per_run.RunSimulator)")
    return cls


def scenario_options(section: dict) -> dict:
    """The constructor options a ``[scenario]`` section sets (unset keys left out)."""
    return {key: section[key] for key in SCENARIO_OPTION_KEYS if section.get(key) is not None}


def make_scenario(name: str, sv_policy: str | None = None, failure_facets=None, disturbance: float = 0.0,
                  options: dict | None = None) -> Scenario:
    """``options``: the scenario's own constructor options (``scenario_options``); one it
    does not take is a one-line ConfigError naming the key."""
    cls = scenario_class(name)
    options = dict(options or {})
    for key in options:
        if key not in cls.config_options:
            allowed = ", ".join(f"scenario.{k}" for k in cls.config_options) or "none"
            raise ConfigError(f"scenario.{key}: scenario {name!r} takes no option {key!r}; leave it unset "
                              f"(its options: {allowed})")
    try:
        return cls(sv_policy=sv_policy, failure_facets=failure_facets, disturbance=disturbance, **options)
    except FarmError:
        raise
    except TypeError as exc:
        raise ConfigError(f"scenario.name: {name!r} could not be constructed ({exc}); a Scenario subclass's __init__ "
                          f"must accept the keywords sv_policy, failure_facets and disturbance (or not be defined)") \
            from None
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's scenario class (sys.exit too): its attributes or __init__
        raise ScenarioError(f"scenario.name: constructing {name!r} raised {type(exc).__name__}: {exc}") from None


def scenario_state_names(scenario: dict) -> tuple[str, ...]:
    """The state variables of a ``[scenario]`` section's scenario (its options count: a
    platoon's k), without building the back end (no SUMO started to read a result)."""
    return make_scenario(scenario["name"], options=scenario_options(scenario)).state_names


def make_backend(scenario: dict):
    """The back end for a ``[scenario]`` config section (plain dict): builds the
    scenario and hands it to the back end with the back end's own options table
    ``[scenario.<backend>]``."""
    name = scenario.get("backend", "numpy")
    cls = backend_class(name)
    external = getattr(cls, "external_sv", None)  # the SV is the simulator's own model
    sv_policy = scenario.get("sv_policy")
    if external is not None:
        if sv_policy not in (None, external):
            raise ConfigError(f"scenario.sv_policy: the {name} back end's SV is the simulator's own model; "
                              f"allowed: {external} (got {sv_policy!r})")
        sv_policy = EXTERNAL_SV
    sc = make_scenario(scenario["name"], sv_policy, scenario.get("failure_facets"), scenario.get("disturbance", 0.0),
                       scenario_options(scenario))
    if external is not None:
        sc.sv_policy_name = external
    try:
        return cls(sc, scenario.get(name))
    except FarmError:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - a user's back end class (sys.exit too)
        raise ScenarioError(f"scenario.backend: constructing {name!r} raised {type(exc).__name__}: {exc}") from None
