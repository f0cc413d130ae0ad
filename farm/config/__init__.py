"""Campaign configuration: one typed model, defaults once, one error format.

A config is TOML (a file or a string) or a dict, read into ``Config``: frozen pydantic
models, one per section. The key names are a public interface (scripts outside this
repository read them): keep them. Every value is checked on load; a bad one is a
``ConfigError`` of one line that names the field and the allowed range, e.g.
``quantify.epsilon: 1.5 is out of range; allowed (0, 1)``. Checks that need the scenario
(state names, SV policies, the back end's options) run in ``farm.api.check`` before
anything is written. ``scenario-farm schema`` prints the JSON Schema (for editors).

A config is code: ``scenario.name = "module:Class"``, ``actions.policy`` and
``validate.domain_predicate`` import and run Python objects. Configs are as trusted as
the code they name.
"""

from farm.config.hashing import changed_fields, config_hash, result_sections, result_view
from farm.config.estimate_section import AxisLawConfig, EstimateConfig, VersusConfig
from farm.config.model import Config, normalize, schema
from farm.config.reading import load, parse, parse_tables, read_text, to_toml
from farm.config.sections import (MIN_CHECKPOINT_ENV, MIN_CHECKPOINT_S, ActionsConfig, ConfigWarning, FarmConfig,
                                  QuantifyConfig, RecordConfig, ScenarioConfig, ValidateConfig, VirtualConfig)
from scenarios.errors import ConfigError

__all__ = ["ActionsConfig", "AxisLawConfig", "Config", "ConfigError", "ConfigWarning", "EstimateConfig", "FarmConfig", "MIN_CHECKPOINT_ENV",
           "MIN_CHECKPOINT_S", "QuantifyConfig", "RecordConfig", "ScenarioConfig", "ValidateConfig", "VirtualConfig",
           "changed_fields", "config_hash", "load", "normalize", "parse", "parse_tables", "read_text", "result_sections", "result_view", "schema",
           "to_toml", "VersusConfig"]
