"""The whole config (``Config``: one model per section) and the one place a raw dict is
checked into it (``normalize``)."""

from __future__ import annotations

import warnings
from typing import Annotated, Any

from pydantic import Field, ValidationError

from farm.config.errors import one_line, did_you_mean
from farm.config.estimate_section import EstimateConfig
from farm.config.sections import (ActionsConfig, FarmConfig, QuantifyConfig, RecordConfig, ScenarioConfig, Section,
                                  ValidateConfig)
from scenarios.errors import ConfigError

MAX_DEPTH = 32  # tables and lists nested deeper than this are no config of ours


with warnings.catch_warnings():
    # "validate" is a key of the public config format; BaseModel.validate is a deprecated
    # classmethod it shadows (instances read the field)
    warnings.filterwarnings("ignore", message='Field name "validate"')

    class Config(Section):
        scenario: ScenarioConfig
        actions: ActionsConfig = ActionsConfig()
        validate: ValidateConfig = ValidateConfig()
        quantify: QuantifyConfig = QuantifyConfig()
        farm: FarmConfig = FarmConfig()
        record: RecordConfig = RecordConfig()
        # read by `estimate` only: no campaign's hash or resume check sees it (farm/config/hashing.py)
        estimate: Annotated[EstimateConfig, Field(json_schema_extra={"affects_result": False})] = EstimateConfig()

        def refinement(self) -> str:
            """quantify.refine with "auto" resolved: margin refinement for SPE on a
            deterministic system (one adversarial action, no disturbance), else "all"."""
            q = self.quantify
            if q.refine != "auto":
                return q.refine
            deterministic = self.actions.mode == "adversarial" and self.scenario.disturbance == 0.0
            return "margin" if deterministic and q.algorithm == "spe" else "all"

        def with_overrides(self, overrides: dict[str, Any]) -> "Config":
            """A copy with ``{"farm.workers": 4, ...}`` applied (None values skipped), checked."""
            raw = self.model_dump()
            for dotted, value in overrides.items():
                if value is not None:
                    section, key = dotted.split(".")
                    raw[section][key] = value
            return normalize(raw, flags={k: f"--{k.split('.')[1].replace('_', '-')}" for k in overrides})


def normalize(raw: dict, flags: dict[str, str] | None = None, where: str = "config") -> Config:
    """Check a raw config dict and fill defaults. Raises ConfigError (one line)."""
    if isinstance(raw, Config):
        return raw
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: expected a TOML table at the top level")
    levels = depth(raw)
    if levels > MAX_DEPTH:
        raise ConfigError(f"{where}: nested {levels} levels deep; allowed at most {MAX_DEPTH}")
    for section in raw:
        if section not in Config.model_fields:
            raise ConfigError(f"unknown section [{section}]{did_you_mean(section, Config.model_fields)}")
    try:
        return Config(**raw)
    except ValidationError as exc:
        raise ConfigError(one_line(exc, raw, flags or {}, Config)) from None


def depth(value) -> int:
    """How deeply tables and lists nest in ``value`` (without recursion: any depth)."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is not None:
            deepest = max(deepest, level + 1)
            stack.extend((child, level + 1) for child in children)
    return deepest


def schema() -> dict:
    """JSON Schema of the config (for editors: `scenario-farm schema`)."""
    out = Config.model_json_schema()
    out["title"] = "Scenario Farm campaign config"
    return out
