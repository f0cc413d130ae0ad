"""The SUMO back end: the SV is a real SUMO vehicle driven by SUMO's own car-following
model, a true black box (shared/spec/scenarios.md, section "sumo back end").

``make_sumo_scenario`` checks the config first (no simulation needed for that), then
loads the SV's vType once into this process's SUMO simulation, so that a value SUMO
refuses is reported at configuration time, not in the middle of a campaign.
See docs/backends.md.
"""

from __future__ import annotations

from scenarios.sumo.config import SumoConfig, parse_config

SCENARIOS = ("lead-follow", "fleet3")
SV_POLICIES = ("sumo",)


def make_sumo_scenario(name: str, sv_policy: str = "sumo", disturbance: float = 0.0,
                       failure_facets=None, sumo: dict | None = None):
    if name not in SCENARIOS:
        raise ValueError(f"scenario.name: the sumo back end supports {', '.join(SCENARIOS)}; got {name!r}")
    if sv_policy not in SV_POLICIES:
        raise ValueError(f"scenario.sv_policy: the sumo back end's SV is SUMO's own car-following model; "
                         f"allowed: {', '.join(SV_POLICIES)} (got {sv_policy!r})")
    if float(disturbance) != 0.0:
        raise ValueError("scenario.disturbance: the sumo back end supports only 0")
    config = parse_config(sumo)
    # Imported only now: these import libsumo.
    from scenarios.sumo.scenarios import SumoFleet3, SumoLeadFollow
    from scenarios.sumo.simulation import world

    cls = SumoLeadFollow if name == "lead-follow" else SumoFleet3
    scenario = cls(config, failure_facets)
    world().ensure(1, 0.0, config.vtype_id, config.vtype_attributes())  # SUMO's own check of the vType
    return scenario


__all__ = ["make_sumo_scenario", "parse_config", "SumoConfig"]
