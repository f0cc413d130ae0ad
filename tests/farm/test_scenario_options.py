"""[scenario] options of scenarios that take them (platoon's vehicles, followers): checked
on load, passed through to the constructor, refused by scenarios without them."""

import pytest

from farm.execution.process import spec_of
from farm.config import ConfigError, config_hash, load, result_view
from scenarios.registry import scenario_state_names
from scenarios.simulator import Simulator


def test_out_of_range_options_are_one_line_errors():
    with pytest.raises(ConfigError, match=r"^scenario\.vehicles: 2 is out of range; allowed \[3, 8\]$"):
        load({"scenario": {"name": "platoon", "vehicles": 2}})
    with pytest.raises(ConfigError, match=r"^scenario\.followers: 0 is out of range; allowed \[1, 6\]$"):
        load({"scenario": {"name": "platoon", "followers": 0}})


def test_options_reach_the_scenario():
    cfg = load({"scenario": {"name": "platoon", "vehicles": 5, "followers": 2, "sv_policy": "brake"},
                "actions": {"mode": "adversarial"}})
    scenario = Simulator(spec_of(cfg)).scenario
    assert (scenario.n, scenario.vehicles, scenario.followers) == (9, 5, 2)
    assert scenario_state_names(cfg.scenario.model_dump()) == scenario.state_names
    assert result_view(cfg)["scenario"]["vehicles"] == 5


def test_a_scenario_without_the_option_refuses_it_in_one_line():
    cfg = load({"scenario": {"name": "lead-follow", "vehicles": 4}})
    with pytest.raises(ConfigError, match=r"^scenario\.vehicles: scenario 'lead-follow' takes no option 'vehicles'; "
                                          r"leave it unset \(its options: none\)$"):
        Simulator(spec_of(cfg))


def test_unset_options_leave_the_config_hash_alone():
    cfg = load({"scenario": {"name": "fleet3"}})
    assert "vehicles" not in result_view(cfg)["scenario"] and "followers" not in result_view(cfg)["scenario"]
    assert config_hash(cfg) == config_hash(load({"scenario": {"name": "fleet3", "vehicles": None}}))
