"""Scenario systems and their back ends.

``make_scenario(name, backend, ...)`` is the one entry point; back ends that need heavy
imports (SUMO) are imported only when chosen, like Ray Tune's lazy search registry.
"""

from __future__ import annotations

from scenarios.base import Scenario

BUILTIN = {
    "lead-follow": ("scenarios.lead_follow", "LeadFollow"),
    "fleet3": ("scenarios.fleet3", "Fleet3"),
    "toy": ("scenarios.toy", "Toy"),
}
BACKENDS = ("numpy", "sumo")


def scenario_class(name: str) -> type[Scenario]:
    import importlib

    from scenarios.actions import load_object

    if name in BUILTIN:
        module, attr = BUILTIN[name]
        return getattr(importlib.import_module(module), attr)
    if ":" in name:
        cls = load_object(name, "scenario.name")
        if not (isinstance(cls, type) and issubclass(cls, Scenario)):
            raise ValueError(f"scenario.name: {name!r} is not a subclass of scenarios.base.Scenario")
        return cls
    raise ValueError(f"scenario.name: unknown scenario {name!r}; allowed: {', '.join(BUILTIN)} or 'package.module:Class'")


def make_scenario(
    name: str,
    backend: str = "numpy",
    sv_policy: str = "idm",
    disturbance: float = 0.0,
    failure_facets=None,
    sumo: dict | None = None,
) -> Scenario:
    if backend not in BACKENDS:
        raise ValueError(f"scenario.backend: unknown back end {backend!r}; allowed: {', '.join(BACKENDS)}")
    if backend == "sumo":
        from scenarios.sumo import make_sumo_scenario  # imports libsumo: only now

        return make_sumo_scenario(name, sv_policy=sv_policy, disturbance=disturbance,
                                  failure_facets=failure_facets, sumo=sumo or {})
    cls = scenario_class(name)
    return cls(sv_policy=sv_policy, failure_facets=failure_facets, disturbance=disturbance)
