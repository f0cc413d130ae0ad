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

from __future__ import annotations

import difflib
import hashlib
import json
import math
import os
import tomllib
import warnings
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from coordinator.certification import MARGIN as CERTIFY_MARGIN
from coordinator.spe import SPESettings
from scenarios.errors import ConfigError

_SPE = SPESettings()  # the algorithm's defaults are the config's: written once
MAX_DEPTH = 32  # tables and lists nested deeper than this are no config of ours
# [s] farm.checkpoint_every below this is raised to it, with a warning; the environment
# variable lowers it for tests that interrupt a campaign at many moments
MIN_CHECKPOINT_S = 1.0
MIN_CHECKPOINT_ENV = "SCENARIO_FARM_MIN_CHECKPOINT_S"

__all__ = ["Config", "ConfigError", "ConfigWarning", "load", "normalize", "parse", "read_text", "schema"]


class ConfigWarning(UserWarning):
    """A config value that was accepted after a change (the CLI prints it as one line)."""


def _fixed(description: str = "") -> dict:
    """Field metadata for a key that cannot change a result (hash, resume check)."""
    return {"json_schema_extra": {"affects_result": False}, "description": description}


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


Probability = Annotated[float, Field(gt=0.0, lt=1.0)]
# N_eps = ln(beta) / ln(1 - epsilon) runs in a row (Lemma 2), and beta is split further over
# certification attempts: below these bounds a split beta underflows to 0 and N_eps to
# infinity (found only when the certification starts), or N_eps exceeds 10^12 runs, more
# than any quantify.budget.
Epsilon = Annotated[float, Field(ge=1e-9, lt=1.0)]
Beta = Annotated[float, Field(ge=1e-100, lt=1.0)]
Positive = Annotated[float, Field(gt=0.0)]
Horizon = Annotated[int, Field(ge=2, le=100_000, description="K: states per run, the start included")]


class ScenarioConfig(Section):
    """[scenario]: the system under test."""

    model_config = ConfigDict(extra="allow", strict=True, frozen=True, allow_inf_nan=False)
    name: Annotated[str, Field(min_length=1, description="lead-follow | fleet3 | platoon | lead-follow-params | toy | 'package.module:Class'")]
    backend: Annotated[str, Field(min_length=1, description="numpy | sumo | a registered back end")] = "numpy"
    sv_policy: Annotated[str | None, Field(description="the SV policy (brake | idm; sumo: 'sumo'); default: "
                                                       "the scenario's first")] = None
    disturbance: Annotated[float, Field(ge=0.0, le=100.0, description="bound w [m/s^2]")] = 0.0
    failure_facets: list[str] | None = None
    # options of scenarios that take them (platoon); unset keys leave existing hashes alone
    vehicles: Annotated[int | None, Field(ge=3, le=8, description="platoon: cars k (2k - 1 state variables)",
                                          json_schema_extra={"hashed_when_unset": False})] = None
    followers: Annotated[int | None, Field(ge=1, le=6, description="platoon: followers r behind the SV",
                                           json_schema_extra={"hashed_when_unset": False})] = None
    sumo: Annotated[dict | None, Field(description="[scenario.sumo]: the SUMO back end's options")] = None

    @model_validator(mode="after")
    def _backend_tables_only(self):
        # a back end's own options live in [scenario.<backend>]; anything else is a typo
        for key, value in (self.model_extra or {}).items():
            if key != self.backend or not isinstance(value, dict):
                raise ValueError(f"unknown key {key!r}")
        return self

    def options(self) -> dict | None:
        """The chosen back end's options table, if any."""
        return getattr(self, self.backend, None) if self.backend != "numpy" else None


class ActionsConfig(Section):
    """[actions]: how the scenario's actions u are chosen."""

    mode: Literal["uniform", "adversarial", "constant", "feedback", "search"] = "uniform"
    value: Annotated[float | list[float] | None, Field(description="constant action (one number per action)")] = None
    policy: Annotated[str | None, Field(description="feedback policy 'package.module:function'")] = None


class Constraint(Section):
    a: dict[str, float]
    b: float


class OpenScenarioDomain(Section):
    """[validate.openscenario]: the claimed domain from a logical scenario's parameter
    ranges (farm/openscenario/ranges.py)."""

    file: Annotated[str, Field(min_length=1, description="an OpenSCENARIO ParameterValueDistribution file")]
    map: Annotated[dict[str, str], Field(min_length=1, description="state variable -> parameter name")]


class ValidateConfig(Section):
    """[validate]: certify a claimed domain Phi."""

    algorithm: Literal["delta", "eps", "eps-delta"] = "eps-delta"
    epsilon: Epsilon = 0.001
    beta: Beta = 0.01
    delta: Positive = 1.0
    horizon: Horizon = 50
    boundary: bool = False
    domain: dict[str, list[float]] | None = None
    constraints: list[Constraint] | None = None
    domain_set: Annotated[str | None, Field(min_length=1)] = None
    domain_predicate: Annotated[str | None, Field(min_length=1)] = None
    openscenario: Annotated[OpenScenarioDomain | None, Field(json_schema_extra={"hashed_when_unset": False})] = None

    @model_validator(mode="after")
    def _one_domain_source(self):
        if self.openscenario is not None and (self.domain or self.domain_set):
            raise ValueError("OPENSCENARIO_AND_DOMAIN")
        return self


class QuantifyConfig(Section):
    """[quantify]: find the maximal safe sub-domain."""

    algorithm: Literal["spe", "ae", "delta-pruning", "vs"] = "spe"
    epsilon: Epsilon = 0.001
    beta: Beta = 0.1
    delta0: Positive = _SPE.delta0
    gamma: Probability = _SPE.gamma
    delta_min: Positive = _SPE.delta_min
    horizon: Horizon = 50
    budget: Annotated[int, Field(ge=1, le=10**12)] = 2_000_000
    prioritized: bool = _SPE.prioritized
    alpha: Literal["identity", "square", "sqrt"] = _SPE.alpha
    replay: bool = _SPE.replay
    replay_capacity: Annotated[int, Field(ge=0, le=10**10, description=(
        "visited states kept for experience replay, duplicates included: the bound on the replay buffer's "
        "memory, n * 8 bytes per state where the states are held (the workers, or the process with the local "
        "executor) and ~50 bytes per kept run on the coordinator; runs of the final round are not kept"))] = \
        _SPE.replay_capacity
    boundary: bool = _SPE.boundary
    reachable: Literal["undirected", "ancestors"] = _SPE.reachable
    refine: Annotated[Literal["band", "all"], Field(description=(
        "which boxes a round end splits (spe): all of them, or only those within sigma-bar + delta of the "
        "set's failure-side boundary (Theorem 3; the others keep their size)"),
        json_schema_extra={"hashed_when_default": False})] = _SPE.refine
    sides: bool | None = None
    certify: Annotated[bool, Field(description="end with a certification round (spe): the exported set "
                                               "passes validate")] = True
    certify_margin: Annotated[float, Field(ge=1.0, le=1e6, description=(
        "sampled certification: closing rounds end after N_eps(eps / (margin x band share)) quiet runs near "
        "the failure-side boundary, so that a check (N_eps at eps, beta split over checks) usually passes "
        "at once (docs/certification.md)"), json_schema_extra={"hashed_when_default": False})] = CERTIFY_MARGIN

    @model_validator(mode="after")
    def _delta_order(self):
        if self.delta_min > self.delta0:
            raise ValueError("DELTA_ORDER")
        return self

    def settings(self) -> SPESettings:
        return SPESettings(delta0=self.delta0, gamma=self.gamma, delta_min=self.delta_min,
                           prioritized=self.prioritized, alpha=self.alpha, replay=self.replay,
                           replay_capacity=self.replay_capacity, reachable=self.reachable, boundary=self.boundary,
                           refine=self.refine)


class VirtualConfig(Section):
    """[farm.virtual]: the simulated clock of the virtual farm (farm.executor = "virtual")."""

    run_time: Annotated[float, Field(gt=0.0, le=1e5, description="mean seconds of a full-horizon run")] = 1.0
    jitter: Annotated[float, Field(ge=0.0, le=5.0, description="lognormal sigma of a run's duration")] = 0.0
    call_cost: Annotated[float, Field(ge=0.0, le=60.0, description="seconds a chunk's call costs the "
                                                                    "coordinator and its worker")] = 0.001


class FarmConfig(Section):
    """[farm]: where and how runs are simulated."""

    executor: Annotated[Literal["ray", "local", "virtual"], Field(**_fixed())] = "local"
    workers: Annotated[int, Field(ge=1, le=4096, **_fixed("Ray actors (a local Ray: at most 4 per CPU), or the virtual farm's simulated workers"))] = 2
    address: Annotated[str, Field(min_length=1, **_fixed(
        "'local', 'auto', 'host:port' or 'ray://host:port' (must answer within 3 s)"))] = "local"
    batch_size: Annotated[int, Field(ge=1, le=10_000_000, description="runs per drawn batch")] = 1024
    pipeline_depth: Annotated[int, Field(ge=1, le=64, description="batches drawn ahead")] = 2
    counting: Annotated[Literal["sequential", "deferred"], Field(description=(
        "coupled counting: a mispredicted run's replacement is waited for at the head (sequential: one "
        "result at any batch_size and pipeline_depth) or applied "
        "batch_size x pipeline_depth indices later (deferred: no waiting)"))] = "sequential"
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = 0
    checkpoint_every: Annotated[float, Field(ge=0.0, le=1e9, **_fixed("seconds (below 1: 1, with a warning)"))] = 30.0
    max_retries: Annotated[int, Field(ge=0, le=100, **_fixed())] = 3
    chunk_timeout: Annotated[float, Field(ge=0.0, le=1e6, **_fixed(
        "seconds a chunk may take on its worker before it is retried elsewhere (0: 10x its expected time, "
        "measured, plus 5 s)"))] = 0.0
    virtual: Annotated[VirtualConfig, Field(**_fixed("the virtual farm's clock"))] = VirtualConfig()
    max_memory_gb: Annotated[float | None, Field(gt=0.0, le=1e6, **_fixed(
        "refuse a campaign whose worst-case memory estimate exceeds this (default: 3/4 of this machine's "
        "memory)"))] = None

    @field_validator("checkpoint_every")
    @classmethod
    def _not_every_chunk(cls, seconds: float) -> float:
        # a checkpoint costs a Parquet segment, an npz and their fsyncs; at every chunk that
        # is most of the campaign's time (docs/benchmarks.md)
        least = float(os.environ.get(MIN_CHECKPOINT_ENV, MIN_CHECKPOINT_S))
        if seconds < least:
            warnings.warn(f"farm.checkpoint_every: {seconds:g} s is below the minimum; checkpointing every "
                          f"{least:g} s instead (more often costs more time than a kill can lose)",
                          ConfigWarning, stacklevel=2)
            return least
        return seconds


class RecordConfig(Section):
    """[record]: which runs are written to MCAP recordings."""

    quantify_runs: Annotated[int, Field(ge=0, le=10**7, **_fixed())] = 64
    counterexamples: Annotated[bool, Field(**_fixed())] = True


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

        def with_overrides(self, overrides: dict[str, Any]) -> "Config":
            """A copy with ``{"farm.workers": 4, ...}`` applied (None values skipped), checked."""
            raw = self.model_dump()
            for dotted, value in overrides.items():
                if value is not None:
                    section, key = dotted.split(".")
                    raw[section][key] = value
            return normalize(raw, flags={k: f"--{k.split('.')[1].replace('_', '-')}" for k in overrides})


# -- reading --------------------------------------------------------------------------------
def normalize(raw: dict, flags: dict[str, str] | None = None, where: str = "config") -> Config:
    """Check a raw config dict and fill defaults. Raises ConfigError (one line)."""
    if isinstance(raw, Config):
        return raw
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: expected a TOML table at the top level")
    depth = _depth(raw)
    if depth > MAX_DEPTH:
        raise ConfigError(f"{where}: nested {depth} levels deep; allowed at most {MAX_DEPTH}")
    for section in raw:
        if section not in Config.model_fields:
            raise ConfigError(f"unknown section [{section}]{_did_you_mean(section, Config.model_fields)}")
    try:
        return Config(**raw)
    except ValidationError as exc:
        raise ConfigError(_one_line(exc, raw, flags or {})) from None


def load(source, overrides: dict | None = None) -> Config:
    """A config from a TOML file (str or Path), a TOML string, a dict or a Config."""
    if isinstance(source, Config):
        cfg = source
    elif isinstance(source, dict):
        cfg = normalize(source)
    elif isinstance(source, Path) or (isinstance(source, str) and "\n" not in source and "=" not in source):
        cfg = parse(read_text(source), str(source))
    else:
        cfg = parse(str(source))
    return cfg.with_overrides(overrides) if overrides else cfg


def read_text(path) -> str:
    """A config file's text, read once (it may be a stream: ``quantify <(cat c.toml)``),
    without a UTF-8 byte-order mark. Raises ConfigError (one line)."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8-sig") as fh:  # -sig: a byte-order mark is no TOML
            return fh.read()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a directory, not a config file") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason}); a config is a UTF-8 TOML "
                          f"file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config ({exc.strerror or type(exc).__name__})") from None


def parse(text: str, where: str = "config") -> Config:
    """A checked config from TOML text; ``where`` names it in errors (the file)."""
    text = text.removeprefix("\ufeff")
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML ({exc})") from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply to read; allowed at most {MAX_DEPTH} levels") from None
    return normalize(raw, where=where)


def _depth(value) -> int:
    """How deeply tables and lists nest in ``value`` (without recursion: any depth)."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is not None:
            deepest = max(deepest, level + 1)
            stack.extend((child, level + 1) for child in children)
    return deepest


def to_toml(cfg: Config) -> str:
    """The normalized config as TOML (a campaign started from Python has no file)."""
    lines = []
    for section, values in cfg.model_dump(mode="json", exclude_none=True).items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()]
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for {value!r}")


# -- hashing and resume --------------------------------------------------------------------------
WINDOW = ("batch_size", "pipeline_depth")  # the runs in flight: result-relevant only for deferred counting


def result_view(cfg: Config) -> dict:
    """The part of a config that can change a result (hash input, resume check). With
    sequential counting the runs in flight change no result (the committed sequence is
    the one-run-at-a-time campaign's), so resume may change them."""
    out = {}
    for section, values in cfg.model_dump(mode="json").items():
        fields = type(getattr(cfg, section)).model_fields
        out[section] = {k: v for k, v in values.items() if _affects_result(fields.get(k))
                        and not (v is None and _extra(fields.get(k)).get("hashed_when_unset") is False)
                        and not (_extra(fields.get(k)).get("hashed_when_default") is False
                                 and v == fields[k].default)}
    if cfg.farm.counting == "sequential":
        for key in WINDOW:
            out["farm"].pop(key)
    return out


def _extra(field) -> dict:
    return getattr(field, "json_schema_extra", None) or {}


def _affects_result(field) -> bool:
    return _extra(field).get("affects_result", True)


def config_hash(cfg: Config) -> str:
    canonical = json.dumps(result_view(cfg), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()[:16]


def changed_fields(old: Config, new: Config) -> list[str]:
    """Result-relevant fields that differ between two configs."""
    a, b = result_view(old), result_view(new)
    return [f"{s}.{k}" for s in a for k in a[s] if a[s].get(k) != b.get(s, {}).get(k)]


def schema() -> dict:
    """JSON Schema of the config (for editors: `scenario-farm schema`)."""
    out = Config.model_json_schema()
    out["title"] = "Scenario Farm campaign config"
    return out


# -- one-line errors -------------------------------------------------------------------------
_KINDS = {"float_type": "a number", "int_type": "an integer", "bool_type": "true or false",
          "string_type": "a string", "dict_type": "a table { ... }", "list_type": "a list [ ... ]",
          "model_type": "a table { ... }", "int_from_float": "an integer"}


def _did_you_mean(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f"; did you mean {close[0]!r}?" if close else f"; allowed: {', '.join(sorted(options))}"


def _field_name(loc) -> str:
    parts = []
    for item in loc:
        if isinstance(item, int):
            parts[-1] += f"[{item}]"
        elif item in ("float", "int", "list[float]", "str", "dict[str,float]") or "[" in str(item):
            continue  # a branch of a union type, not a key
        else:
            parts.append(str(item))
    return ".".join(parts)


def _field_info(loc):
    """The pydantic FieldInfo an error location points to (None past a nested model)."""
    model: type[BaseModel] | None = Config
    info = None
    for item in loc:
        if not isinstance(item, str) or model is None or item not in model.model_fields:
            break
        info = model.model_fields[item]
        annotation = info.annotation
        model = annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None
    return info


def _model_at(loc) -> type[BaseModel]:
    """The config model of the table at ``loc`` (e.g. ("validate", "openscenario"))."""
    model: type[BaseModel] = Config
    for item in loc:
        info = model.model_fields.get(item) if isinstance(item, str) else None
        if info is None:
            break
        inner = [a for a in (info.annotation, *get_args(info.annotation))
                 if isinstance(a, type) and issubclass(a, BaseModel)]
        if not inner:
            break
        model = inner[0]
    return model


def _constraints(loc) -> dict:
    info = _field_info(loc)
    out = {}
    for meta in getattr(info, "metadata", []) if info is not None else []:
        for key in ("gt", "ge", "lt", "le"):
            if getattr(meta, key, None) is not None:
                out[key] = getattr(meta, key)
    return out


def _range(c: dict) -> str:
    lo = "(" if "gt" in c else "["
    hi = ")" if "lt" in c else "]"
    low = c.get("gt", c.get("ge", -math.inf))
    high = c.get("lt", c.get("le", math.inf))
    text = [str(v) if isinstance(v, int) else f"{v:g}" for v in (low, high)]
    return f"{lo}{text[0]}, {text[1]}{hi}"


def _one_line(exc: ValidationError, raw: dict, flags: dict) -> str:
    err = exc.errors()[0]
    loc, kind, value = err["loc"], err["type"], err.get("input")
    field = _field_name(loc)
    field = flags.get(field, field)
    if kind == "missing":
        if field in ("scenario", "scenario.name"):
            return 'scenario.name: required (e.g. [scenario] name = "lead-follow")'
        return f"{field}: required"
    if kind == "extra_forbidden" or (kind == "value_error" and "unknown key" in err["msg"]):
        table = loc[:-1] if kind == "extra_forbidden" else loc[:1]
        key = loc[-1] if kind == "extra_forbidden" else err["msg"].split("'")[1]
        fields = _model_at(table).model_fields
        return f"{_field_name(table)}.{key}: unknown key{_did_you_mean(str(key), fields)}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number"):
        shown = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
            and "float" in str(_annotation(loc)) else value
        return f"{field}: {shown!r} is out of range; allowed {_range(_constraints(loc))}"
    if kind == "literal_error":
        allowed = err["ctx"]["expected"].replace("'", "").replace(" or ", ", ")
        return f"{field}: {value!r} is not allowed; allowed: {allowed}"
    if kind in ("string_too_short",):
        return f"{field}: expected a non-empty string, got {value!r}"
    if kind == "too_short":
        return f"{field}: must not be empty (got {value!r})"
    if kind in _KINDS:
        return f"{field}: expected {_KINDS[kind]}, got {type(value).__name__} {value!r}"
    if kind == "value_error" and "OPENSCENARIO_AND_DOMAIN" in err["msg"]:
        return "validate.openscenario: give either openscenario, domain or domain_set, not two of them"
    if kind == "value_error" and "DELTA_ORDER" in err["msg"]:
        q = raw.get("quantify", {})
        return (f"quantify.delta_min: {float(q.get('delta_min', _SPE.delta_min))} exceeds quantify.delta0 = "
                f"{float(q.get('delta0', _SPE.delta0))}; allowed (0, delta0]")
    return f"{field}: {err['msg']} (got {value!r})"


def _annotation(loc):
    info = _field_info(loc)
    return info.annotation if info is not None else None
