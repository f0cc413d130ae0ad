"""Which part of a config can change a result: the config hash, and what resume may change."""

from __future__ import annotations

import hashlib
import json

from farm.config.model import Config

WINDOW = ("batch_size", "pipeline_depth")  # the runs in flight: result-relevant only for deferred counting


def result_view(cfg: Config) -> dict:
    """The part of a config that can change a result (hash input, resume check). With
    sequential counting the runs in flight change no result (the committed sequence is
    the one-run-at-a-time campaign's), so resume may change them."""
    out = {}
    for section, values in cfg.model_dump(mode="json").items():
        if not _affects_result(type(cfg).model_fields[section]):
            continue  # a section of another job ([estimate]): it changes no campaign's result
        fields = type(getattr(cfg, section)).model_fields
        out[section] = {k: v for k, v in values.items() if _affects_result(fields.get(k))
                        and not (v is None and _extra(fields.get(k)).get("hashed_when_unset") is False)
                        and not (_extra(fields.get(k)).get("hashed_when_default") is False
                                 and v == fields[k].default)}
    if cfg.farm.counting == "sequential":
        for key in WINDOW:
            out["farm"].pop(key)
    # the refinement as it resolves: "all" (the old default) leaves a config's hash as it
    # was; "auto" resolving to margin refinement changes the result, so the hash too
    out["quantify"].pop("refine", None)
    if cfg.refinement() != "all":
        out["quantify"]["refine"] = cfg.refinement()
    return out


def result_sections() -> list[str]:
    """The sections that can change a result: every frozen config (config.json) holds them."""
    return [name for name, field in Config.model_fields.items() if _affects_result(field)]


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
