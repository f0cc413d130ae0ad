"""A config's validation error as one line: the field, what was given, what is allowed."""

from __future__ import annotations

import difflib
import math
from typing import get_args

from pydantic import BaseModel, ValidationError

from coordinator.algorithm_settings import SPESettings

_SPE = SPESettings()

_KINDS = {"float_type": "a number", "int_type": "an integer", "bool_type": "true or false",
          "string_type": "a string", "dict_type": "a table { ... }", "list_type": "a list [ ... ]",
          "model_type": "a table { ... }", "int_from_float": "an integer"}


def did_you_mean(word: str, options) -> str:
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


def _field_info(loc, root: type[BaseModel]):
    """The pydantic FieldInfo an error location points to (None past a nested model)."""
    model: type[BaseModel] | None = root
    info = None
    keyed = None  # the model of a table of tables ([estimate.axes.<name>]): the next item is a key
    for item in loc:
        if keyed is not None:
            model, keyed = keyed, None
            continue
        if not isinstance(item, str) or model is None or item not in model.model_fields:
            break
        info = model.model_fields[item]
        annotation = info.annotation
        model = annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None
        keyed = _table_of_models(annotation)
    return info


def _table_of_models(annotation) -> type[BaseModel] | None:
    """M for an annotation dict[str, M] (or dict[str, M] | None), else None."""
    for option in (annotation, *get_args(annotation)):
        args = get_args(option)
        if len(args) == 2 and isinstance(args[1], type) and issubclass(args[1], BaseModel):
            return args[1]
    return None


def _model_at(loc, root: type[BaseModel]) -> type[BaseModel]:
    """The config model of the table at ``loc`` (e.g. ("validate", "openscenario"))."""
    model: type[BaseModel] = root
    keyed = None
    for item in loc:
        if keyed is not None:  # a key of a table of tables
            model, keyed = keyed, None
            continue
        info = model.model_fields.get(item) if isinstance(item, str) else None
        if info is None:
            break
        keyed = _table_of_models(info.annotation)
        inner = [a for a in (info.annotation, *get_args(info.annotation))
                 if isinstance(a, type) and issubclass(a, BaseModel)]
        if not inner and keyed is None:
            break
        model = inner[0] if inner else model
    return model


def _constraints(loc, root) -> dict:
    info = _field_info(loc, root)
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


def one_line(exc: ValidationError, raw: dict, flags: dict, root: type[BaseModel]) -> str:
    """``exc`` (validating ``raw`` into ``root``) as one line; ``flags``: field -> the
    command-line flag that set it (named instead)."""
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
        fields = _model_at(table, root).model_fields
        return f"{_field_name(table)}.{key}: unknown key{did_you_mean(str(key), fields)}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number"):
        shown = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
            and "float" in str(_annotation(loc, root)) else value
        return f"{field}: {shown!r} is out of range; allowed {_range(_constraints(loc, root))}"
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


def _annotation(loc, root):
    info = _field_info(loc, root)
    return info.annotation if info is not None else None
