"""The ``scenario.sumo`` config: which SUMO car-following model drives the SV and with
which vType attributes. Checked here, before SUMO sees it, because SUMO silently
ignores unknown vType attributes and reports bad values only as "Invalid parsing
embedded VType". The allowed models and attributes (with their value types) are read
from the XSD schema shipped with SUMO, so they follow the installed SUMO version.

No libsumo import here: the config can be checked in a process without a simulation.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from scenarios.errors import ConfigError

_XSD = "{http://www.w3.org/2001/XMLSchema}"
DEFAULT_MODEL = "Krauss"
CONFIG_KEYS = ("car_follow_model", "params", "allow_nondeterministic")

# Measured with libsumo 1.28 (docs/backends.md): the same batch run twice in one process
# gives different trajectories with these models, even with sigma = 0 (they draw from
# SUMO's global random generator or depend on the simulation clock). A run would then
# depend on its batch-mates and on the process's history, not on its (seed, index) key.
NONDETERMINISTIC_MODELS = ("EIDM", "PWagner2009", "BKerner", "Wiedemann", "W99")

# Used only if SUMO's schema cannot be found (values are then checked by SUMO alone).
_FALLBACK_MODELS = ("IDM", "IDMM", "EIDM", "Krauss", "KraussPS", "KraussOrig1", "SmartSK", "Daniel1",
                    "PWagner2009", "BKerner", "Wiedemann", "W99", "ACC", "CACC", "CC")

# Set by the back end, not by the user: the vehicle length is part of the state
# geometry (fleet3's front-to-front positions assume 5 m cars), ids are internal.
RESERVED = {
    "id": "set by the back end",
    "refId": "set by the back end",
    "carFollowModel": "use scenario.sumo.car_follow_model",
    "length": "fixed at 5 m by the scenario geometry",
    "probability": "not meaningful for a single vType",
    "scale": "not meaningful: the back end inserts exactly one SV per run",
}

# A run must depend on its (seed, index) key only. These attributes make SUMO draw from
# its own global random number generator, whose state depends on every vehicle simulated
# before in the process, so they are allowed only at their deterministic values.
_MUST_BE_ZERO = ("sigma", "speedDev")

# Deterministic defaults for the SV; the user's params override them. SUMO's passenger
# defaults are sigma = 0.5 (Krauss dawdling) and speedFactor ~ normc(1, 0.1): random.
SV_DEFAULTS = {"sigma": 0.0, "speedFactor": 1.0, "speedDev": 0.0}


@dataclass(frozen=True)
class SumoConfig:
    car_follow_model: str = DEFAULT_MODEL
    params: dict = field(default_factory=dict)
    allow_nondeterministic: bool = False

    def vtype_attributes(self) -> dict[str, str]:
        """All attributes of the SV vType (strings, as written into the route file)."""
        attrs = {"carFollowModel": self.car_follow_model, **SV_DEFAULTS, **self.params}
        return {k: _to_text(v) for k, v in attrs.items()}

    @property
    def vtype_id(self) -> str:
        """A stable id per distinct vType, so that scenarios with different SV models can
        share the process's one simulation."""
        text = repr(sorted(self.vtype_attributes().items()))
        return "sv_" + hashlib.sha1(text.encode()).hexdigest()[:12]


def parse_config(sumo: dict | None) -> SumoConfig:
    sumo = dict(sumo or {})
    unknown = sorted(set(sumo) - set(CONFIG_KEYS))
    if unknown:
        raise ConfigError(f"scenario.sumo: unknown key {unknown[0]!r}; allowed: {', '.join(CONFIG_KEYS)}")
    model = sumo.get("car_follow_model", DEFAULT_MODEL)
    models = schema()[0]
    if not isinstance(model, str) or model not in models:
        raise ConfigError(f"scenario.sumo.car_follow_model: unknown model {model!r}; allowed: {', '.join(models)}")
    allow = sumo.get("allow_nondeterministic", False)
    if not isinstance(allow, bool):
        raise ConfigError(f"scenario.sumo.allow_nondeterministic: expected true or false, got {allow!r}")
    if model in NONDETERMINISTIC_MODELS and not allow:
        good = [m for m in models if m not in NONDETERMINISTIC_MODELS and m != "CC"]
        raise ConfigError(f"scenario.sumo.car_follow_model: {model!r} is not reproducible in SUMO (the same run "
                          f"repeated gives another trajectory), which breaks the (seed, index) contract; "
                          f"reproducible: {', '.join(good)}; or set scenario.sumo.allow_nondeterministic = true")
    params = sumo.get("params") or {}
    if not isinstance(params, dict):
        raise ConfigError(f"scenario.sumo.params: expected a table of vType attributes, got {type(params).__name__}")
    checked = {}
    for name, value in params.items():
        checked[name] = _check_param(str(name), value, allow)
    return SumoConfig(model, checked, allow)


def _check_param(name: str, value, allow_nondeterministic: bool = False):
    field_name = f"scenario.sumo.params.{name}"
    if name in RESERVED:
        raise ConfigError(f"{field_name}: not settable ({RESERVED[name]})")
    attributes = schema()[1]
    if attributes and name not in attributes:
        close = [a for a in attributes if a.lower() == name.lower()]
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"{field_name}: not a SUMO vType attribute{hint}")
    kind = attributes.get(name, "string")
    if kind == "string":
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise ConfigError(f"{field_name}: expected a string or number, got {value!r}")
        if name == "speedFactor" and not _is_number(value) and not allow_nondeterministic:
            raise ConfigError(f"{field_name}: must be a number; a distribution would draw from SUMO's "
                              "global random generator and break per-run reproducibility")
        out = value
    elif kind == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{field_name}: expected true or false, got {value!r}")
        out = value
    else:  # numeric: (lower, lower_inclusive, upper)
        lower, inclusive, upper = kind
        if isinstance(value, bool) or not _is_number(value):
            raise ConfigError(f"{field_name}: expected a number, got {value!r}")
        out = float(value)
        if not math.isfinite(out):
            raise ConfigError(f"{field_name}: must be finite, got {value!r}")
        if lower is not None and (out < lower or (out == lower and not inclusive)):
            raise ConfigError(f"{field_name}: must be {'>=' if inclusive else '>'} {lower:g}, got {value!r}")
        if upper is not None and out > upper:
            raise ConfigError(f"{field_name}: must be <= {upper:g}, got {value!r}")
    if allow_nondeterministic:
        return out
    if name in _MUST_BE_ZERO and float(out) != 0.0:
        raise ConfigError(f"{field_name}: must be 0 for this back end; SUMO draws it from its global random "
                          "generator, so a run would depend on its batch-mates, not on its (seed, index) key")
    if name == "hasDriverState" and out:
        raise ConfigError(f"{field_name}: must be false (the driver state draws random perception errors)")
    return out


def _is_number(value) -> bool:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return True
    try:
        float(value)
        return True
    except (TypeError, ValueError):
        return False


def _to_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)  # shortest exact round trip
    return str(value)


# -- SUMO's schema ---------------------------------------------------------------------
def _schema_path() -> str | None:
    homes = []
    spec = importlib.util.find_spec("sumo_data")
    if spec and spec.submodule_search_locations:
        homes.append(list(spec.submodule_search_locations)[0])
    if os.environ.get("SUMO_HOME"):
        homes.append(os.environ["SUMO_HOME"])
    for home in homes:
        path = os.path.join(home, "data", "xsd", "types", "route.xsd")
        if os.path.exists(path):
            return path
    return None


_NUMERIC = {
    "positiveFloatType": (0.0, False, None),
    "nonNegativeFloatType": (0.0, True, None),
    "nonNegativeFloatTypeWithErrorValue": (0.0, True, None),
    "floatType": (None, True, None),
    "xsd:float": (None, True, None),
    "xsd:nonNegativeInteger": (0.0, True, None),
}


@functools.lru_cache(maxsize=1)
def schema() -> tuple[tuple[str, ...], dict]:
    """(car-following model names, {vType attribute: kind}) from SUMO's route.xsd.
    kind is "string", "bool" or a numeric range (lower, lower_inclusive, upper)."""
    path = _schema_path()
    if path is None:
        return _FALLBACK_MODELS, {}
    root = ET.parse(path).getroot()
    models = tuple(e.get("name")[len("carFollowing-"):] for e in root.iter(f"{_XSD}element")
                   if (e.get("name") or "").startswith("carFollowing-"))
    base = next(t for t in root.iter(f"{_XSD}complexType") if t.get("name") == "vTypeBaseType")
    attributes = {}
    for attr in base.findall(f"{_XSD}attribute"):
        attributes[attr.get("name")] = _kind(attr)
    return models or _FALLBACK_MODELS, attributes


def _kind(attr):
    typ = attr.get("type")
    if typ == "boolType":
        return "bool"
    if typ in _NUMERIC:
        return _NUMERIC[typ]
    restriction = attr.find(f"{_XSD}simpleType/{_XSD}restriction")
    if restriction is not None and restriction.get("base") == "xsd:float":
        lo = restriction.find(f"{_XSD}minInclusive")
        hi = restriction.find(f"{_XSD}maxInclusive")
        return (float(lo.get("value")) if lo is not None else None, True,
                float(hi.get("value")) if hi is not None else None)
    return "string"
