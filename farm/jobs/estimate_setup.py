"""One place that turns a campaign and its [estimate] section into an estimate's parts:
the scenario distribution D, the strata, what each controller's workers simulate, the
action law (the campaign's: Gamma*, uniform, or the adversary search's final mixture) and
the stopping rule. Everything a config can get wrong is refused here, in one line naming
the field, before any file is written."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from coordinator.estimation import EstimateSettings, Strata, estimate_seed, set_strata, whole_strata
from coordinator.estimation.allocation import FLOOR, smallest_stage
from coordinator.safe_set import SafeSet
from farm.config import Config
from farm.config.hashing import config_hash
from farm.directory.files import read_json, sha256_file
from farm.execution.process import build_simulator
from scenarios.distributions import ProductLaw, Uniform, axis_law, empirical_law
from scenarios.errors import ConfigError
from scenarios.simulator import SimSpec

LAW_PARAMETERS = {"uniform": (), "normal": ("mean", "std"), "lognormal": ("mu", "sigma")}
# what may change on resume: the stopping rule and the interval's level (no run depends on
# them but through where the runs stop)
STOPPING_KEYS = ("runs", "relative_error", "confidence")


@dataclass(frozen=True)
class EstimateSetup:
    """An estimate's parts: ``specs`` one per controller (the campaign's, then the
    second of a comparison), ``labels`` their names, ``actions`` the action policy's state
    for every chunk (the search's final mixture) or None."""

    cfg: Config
    scenario: object
    law: object
    strata: Strata
    specs: tuple[SimSpec, ...]
    labels: tuple[str, ...]
    actions: dict | None
    settings: EstimateSettings
    seed: int
    set_hash: str | None
    estimate_hash: str

    @property
    def paired(self) -> bool:
        return len(self.specs) == 2


def setup(cfg: Config, campaign: Path) -> EstimateSetup:
    """The parts of the estimate ``cfg.estimate`` of the finished campaign in ``campaign``."""
    e, q, farm_cfg = cfg.estimate, cfg.quantify, cfg.farm
    seed = e.seed if e.seed is not None else estimate_seed(farm_cfg.seed)
    horizon = e.horizon or q.horizon
    spec = SimSpec(cfg.scenario.model_dump(), cfg.actions.model_dump(), horizon, seed)
    simulator = build_simulator(spec)
    scenario = simulator.scenario
    law = distribution(cfg, scenario)
    set_hash = None
    if e.strata == "set":
        safe_set = SafeSet.from_parquet(campaign / "safe_set.parquet", scenario.state_names)
        strata = set_strata(law, scenario.lower, scenario.upper, safe_set, e.band)
        set_hash = safe_set.result_hash
    else:
        strata = whole_strata(law, scenario.lower, scenario.upper)
    if e.runs < smallest_stage(len(strata)):
        raise ConfigError(f"estimate.runs: {e.runs} is too few for {len(strata)} strata of {FLOOR} runs each; allowed "
                          f">= {smallest_stage(len(strata))}")
    specs, labels = [spec], [controller_label(cfg.scenario.model_dump(), scenario)]
    if e.versus is not None:
        other = {**cfg.scenario.model_dump(), **e.versus.model_dump(exclude_none=True)}
        if other == cfg.scenario.model_dump():
            raise ConfigError("estimate.versus: names no other controller; allowed: sv_policy or name differing from "
                              "the campaign's [scenario]")
        versus = replace(spec, scenario=other)
        specs.append(versus)
        labels.append(controller_label(other, build_simulator(versus).scenario, cfg.scenario.name))
    settings = EstimateSettings(runs=e.runs, relative_error=e.relative_error, confidence=e.confidence,
                                pilot=e.pilot, batch_size=farm_cfg.batch_size, pipeline_depth=farm_cfg.pipeline_depth)
    ident = {"campaign_config_hash": config_hash(cfg), "set": set_hash, "distribution": law.digest,
             "estimate": {k: v for k, v in e.model_dump(mode="json").items() if k not in STOPPING_KEYS},
             "seed": seed, "horizon": horizon}
    digest = hashlib.sha256(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return EstimateSetup(cfg, scenario, law, strata, tuple(specs), tuple(labels),
                         final_actions(cfg, campaign), settings, seed, set_hash, digest)


def controller_label(scenario_section: dict, scenario, campaign_scenario: str | None = None) -> str:
    """How a controller is named in estimate.json: its SV policy, after its scenario's name
    when that is not the campaign's (another version of a user's controller)."""
    policy = str(scenario_section.get("sv_policy") or getattr(scenario, "sv_policy_name", "") or "")
    if campaign_scenario is None or scenario_section["name"] == campaign_scenario:
        return policy or scenario.name
    return f"{scenario.name}.{policy}" if policy else scenario.name


def distribution(cfg: Config, scenario):
    """D from [estimate]: uniform over Sigma, per-axis laws, or recorded start states."""
    e, names = cfg.estimate, tuple(scenario.state_names)
    lower, upper = scenario.lower.astype(float), scenario.upper.astype(float)
    if e.distribution != "axes" and e.axes:
        raise ConfigError(f"estimate.axes: given with distribution = {e.distribution!r}; allowed: distribution = "
                          f"'axes' to use them")
    if e.distribution != "empirical" and e.data:
        raise ConfigError(f"estimate.data: given with distribution = {e.distribution!r}; allowed: distribution = "
                          f"'empirical' to use it")
    if e.distribution == "empirical":
        return _recorded(e.data, names, lower, upper)
    axes = dict(e.axes or {})
    if e.distribution == "axes" and not axes:
        raise ConfigError(f"estimate.axes: required for distribution = 'axes' (a law per state variable: "
                          f"{', '.join(names)})")
    for name in axes:
        if name not in names:
            raise ConfigError(f"estimate.axes.{name}: unknown state variable; allowed: {', '.join(names)}")
    laws = []
    for i, name in enumerate(names):
        if name not in axes:
            laws.append(Uniform(lower[i], upper[i]))
            continue
        table = axes[name].model_dump()
        field = f"estimate.axes.{name}"
        wanted = LAW_PARAMETERS[table["law"]]
        for key in wanted:
            if table[key] is None:
                raise ConfigError(f"{field}.{key}: required for law {table['law']!r} (it takes "
                                  f"{', '.join(wanted)})")
        for key in ("mean", "std", "mu", "sigma"):
            if table[key] is not None and key not in wanted:
                raise ConfigError(f"{field}.{key}: not a parameter of law {table['law']!r}; allowed: "
                                  f"{', '.join(wanted) or 'low, high only'}")
        laws.append(axis_law(field, table["law"], table, lower[i], upper[i]))
    return ProductLaw(tuple(laws), names)


def _recorded(data: str | None, names, lower, upper):
    if not data:
        raise ConfigError("estimate.data: required for distribution = 'empirical' (a Parquet file of start states, "
                          f"columns {', '.join(names)})")
    path = Path(data).expanduser()
    try:
        table = pq.read_table(path)
    except FileNotFoundError:
        raise ConfigError(f"estimate.data: {path}: no such file") from None
    except (pa.ArrowException, OSError) as exc:
        raise ConfigError(f"estimate.data: {path}: not a readable Parquet file ({' '.join(str(exc).split())})") \
            from None
    missing = [n for n in names if n not in table.column_names]
    if missing:
        raise ConfigError(f"estimate.data: {path} lacks column(s) {', '.join(missing)}; needs one per state "
                          f"variable: {', '.join(names)}")
    try:
        points = np.column_stack([table.column(n).to_numpy(zero_copy_only=False).astype(float) for n in names])
    except (TypeError, ValueError, pa.ArrowException) as exc:
        raise ConfigError(f"estimate.data: {path}: the state columns must be numbers ({exc})") from None
    source = {"file": str(path), "sha256": sha256_file(path)}
    return empirical_law("estimate.data", points, names, lower, upper, source)


def final_actions(cfg: Config, campaign: Path) -> dict | None:
    """The action law the campaign ended with: for the adversary search its last round's
    mixture (adversary.json), as the policy's state; None for the other modes (their law
    is fixed by the config)."""
    if cfg.actions.mode != "search":
        return None
    report = read_json(campaign / "adversary.json", ("families",),
                       missing=f"{campaign}: no adversary.json; the search campaign has not finished")
    return {"schedule": [[0, [float(f["weight"]) for f in report["families"]]]]}
