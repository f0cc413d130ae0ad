"""Campaign configuration: TOML in, a checked, normalized, hashable dict out.

The key names are a public interface (scripts outside this repository read them).
Every field is checked here, once, with a one-line error that names the field and the
allowed range; nothing downstream re-validates user input.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from scenarios.version import __version__


class ConfigError(ValueError):
    """Bad user input: printed as one line, exit code 2."""


@dataclass(frozen=True)
class Field:
    default: Any
    check: Callable[[str, Any], Any]
    affects_result: bool = True


def _type_name(value) -> str:
    return type(value).__name__


def number(lo=-math.inf, hi=math.inf, lo_open=False, hi_open=False):
    def check(name, v):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{name}: expected a number, got {_type_name(v)} {v!r}")
        v = float(v)
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
            raise ConfigError(f"{name}: {v!r} is out of range; allowed {rng}")
        return v

    return check


def integer(lo=-(2**63), hi=2**63 - 1):
    def check(name, v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"{name}: expected an integer, got {_type_name(v)} {v!r}")
        if v < lo or v > hi:
            raise ConfigError(f"{name}: {v} is out of range; allowed [{lo}, {hi}]")
        return v

    return check


def choice(*options):
    def check(name, v):
        if v not in options:
            raise ConfigError(f"{name}: {v!r} is not allowed; allowed: {', '.join(map(str, options))}")
        return v

    return check


def boolean(name, v):
    if not isinstance(v, bool):
        raise ConfigError(f"{name}: expected true or false, got {v!r}")
    return v


def string(name, v):
    if not isinstance(v, str) or not v:
        raise ConfigError(f"{name}: expected a non-empty string, got {v!r}")
    return v


def optional(check):
    def wrapped(name, v):
        return None if v is None else check(name, v)

    return wrapped


def anything(name, v):
    return v


def string_list(name, v):
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise ConfigError(f"{name}: expected a list of strings, got {v!r}")
    return list(v)


def table(name, v):
    if not isinstance(v, dict):
        raise ConfigError(f"{name}: expected a table {{ ... }}, got {v!r}")
    return dict(v)


SEED_RANGE = integer(0, 2**63 - 1)

SCHEMA: dict[str, dict[str, Field]] = {
    "scenario": {
        "name": Field("lead-follow", string),
        "backend": Field("numpy", choice("numpy", "sumo")),
        "sv_policy": Field("idm", string),
        "disturbance": Field(0.0, number(0.0, 100.0)),
        "failure_facets": Field(None, optional(string_list)),
        "sumo": Field(None, optional(table)),
    },
    "actions": {
        "mode": Field("uniform", choice("uniform", "adversarial", "constant", "feedback")),
        "value": Field(None, anything),
        "policy": Field(None, optional(string)),
    },
    "validate": {
        "algorithm": Field("eps-delta", choice("delta", "eps", "eps-delta")),
        "epsilon": Field(0.001, number(0.0, 1.0, lo_open=True, hi_open=True)),
        "beta": Field(0.01, number(0.0, 1.0, lo_open=True, hi_open=True)),
        "delta": Field(1.0, number(0.0, lo_open=True)),
        "horizon": Field(50, integer(2, 100_000)),
        "boundary": Field(False, boolean),
        "domain": Field(None, optional(table)),
        "constraints": Field(None, anything),
        "domain_set": Field(None, optional(string)),
        "domain_predicate": Field(None, optional(string)),
    },
    "quantify": {
        "algorithm": Field("spe", choice("spe", "ae", "delta-pruning", "vs")),
        "epsilon": Field(0.001, number(0.0, 1.0, lo_open=True, hi_open=True)),
        "beta": Field(0.1, number(0.0, 1.0, lo_open=True, hi_open=True)),
        "delta0": Field(2.0, number(0.0, lo_open=True)),
        "gamma": Field(0.5, number(0.0, 1.0, lo_open=True, hi_open=True)),
        "delta_min": Field(0.5, number(0.0, lo_open=True)),
        "horizon": Field(50, integer(2, 100_000)),
        "budget": Field(2_000_000, integer(1, 10**12)),
        "prioritized": Field(True, boolean),
        "alpha": Field("identity", choice("identity", "square", "sqrt")),
        "replay": Field(True, boolean),
        "replay_capacity": Field(20_000_000, integer(0, 10**10)),
        "boundary": Field(False, boolean),
        "reachable": Field("undirected", choice("undirected", "ancestors")),
        "sides": Field(None, optional(boolean)),
    },
    "farm": {
        "executor": Field("local", choice("ray", "local"), affects_result=False),
        "workers": Field(2, integer(1, 4096), affects_result=False),
        "address": Field("local", string, affects_result=False),
        "batch_size": Field(1024, integer(1, 10_000_000)),
        "pipeline_depth": Field(2, integer(1, 64)),
        "seed": Field(0, SEED_RANGE),
        "checkpoint_every": Field(30.0, number(0.0, 1e9), affects_result=False),
        "max_retries": Field(3, integer(0, 100), affects_result=False),
    },
    "record": {
        "quantify_runs": Field(64, integer(0, 10**7), affects_result=False),
        "counterexamples": Field(True, boolean, affects_result=False),
    },
}


def _did_you_mean(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f"; did you mean {close[0]!r}?" if close else f"; allowed: {', '.join(sorted(options))}"


def normalize(raw: dict) -> dict:
    """Check a raw config dict and fill defaults. Raises ConfigError (one line)."""
    if not isinstance(raw, dict):
        raise ConfigError("config: expected a TOML table at the top level")
    out: dict[str, dict] = {}
    for section in raw:
        if section not in SCHEMA:
            raise ConfigError(f"unknown section [{section}]{_did_you_mean(section, SCHEMA)}")
    for section, fields in SCHEMA.items():
        given = raw.get(section, {})
        if not isinstance(given, dict):
            raise ConfigError(f"[{section}]: expected a table")
        for key in given:
            if key not in fields:
                raise ConfigError(f"{section}.{key}: unknown key{_did_you_mean(key, fields)}")
        out[section] = {key: (f.check(f"{section}.{key}", given[key]) if key in given else f.default)
                        for key, f in fields.items()}
    q = out["quantify"]
    if q["delta_min"] > q["delta0"]:
        raise ConfigError(f"quantify.delta_min: {q['delta_min']} exceeds quantify.delta0 = {q['delta0']}; allowed (0, delta0]")
    return out


def load(path: str | Path, overrides: dict | None = None) -> dict:
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    cfg = normalize(raw)
    for dotted, value in (overrides or {}).items():
        if value is None:
            continue
        section, key = dotted.split(".")
        cfg[section][key] = SCHEMA[section][key].check(f"--{key.replace('_', '-')}", value)
    return cfg


def result_view(cfg: dict) -> dict:
    """The part of a config that can change a result (hash input, resume check)."""
    return {
        section: {k: v for k, v in values.items() if SCHEMA[section][k].affects_result}
        for section, values in cfg.items()
    }


def config_hash(cfg: dict) -> str:
    canonical = json.dumps(result_view(cfg), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()[:16]


def changed_fields(old: dict, new: dict) -> list[str]:
    """Result-relevant fields that differ between two normalized configs."""
    a, b = result_view(old), result_view(new)
    return [f"{s}.{k}" for s in a for k in a[s] if a[s].get(k) != b.get(s, {}).get(k)]


def stamp() -> dict:
    return {"scenario_farm_version": __version__}
