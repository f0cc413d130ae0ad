"""The config's sections: frozen pydantic models, one per TOML table, defaults once."""

from __future__ import annotations

import os
import warnings
from dataclasses import fields as dataclass_fields
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, create_model, field_validator, model_validator

from coordinator.algorithm_settings import SPESettings
from coordinator.certification import MARGIN as CERTIFY_MARGIN, TOLERANCE as CERTIFY_TOLERANCE

# [s] farm.checkpoint_every below this is raised to it, with a warning; the environment
# variable lowers it for tests that interrupt a campaign at many moments
MIN_CHECKPOINT_S = 1.0
MIN_CHECKPOINT_ENV = "SCENARIO_FARM_MIN_CHECKPOINT_S"


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
    name: Annotated[str, Field(min_length=1, description="lead-follow | fleet3 | platoon | lead-follow-params | toy | "
                                                         "'package.module:Class'")]
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


class _QuantifyBase(Section):
    """[quantify]: find the maximal safe sub-domain. The algorithm's settings (delta0,
    gamma, delta_min, prioritized, alpha, replay, replay_capacity, reachable, boundary,
    refine) are added from ``coordinator.algorithm_settings.SPESettings``, where each is
    declared once."""

    algorithm: Literal["spe", "ae", "delta-pruning", "vs"] = "spe"
    epsilon: Epsilon = 0.001
    beta: Beta = 0.1
    horizon: Horizon = 50
    budget: Annotated[int, Field(ge=1, le=10**12)] = 2_000_000
    sides: Annotated[bool | None, Field(description=(
        "quantify the scenario's named sides (fleet3's lead and rear) too, each a campaign of its own beside the "
        "total (runs_committed sums them); default: when the scenario declares sides"))] = None
    holdout_runs: Annotated[int, Field(ge=0, le=10**8, json_schema_extra={"affects_result": False}, description=(
        "fresh runs from uniform starts in Sigma against the finished set (summary.json holdout: overclaims "
        "and misses with Clopper-Pearson intervals); 0: none"))] = 1000
    certify: Annotated[bool, Field(description="end with a certification round (spe): the exported set is "
                                               "checked as validate checks a set, eps and beta kept over all "
                                               "its checks (docs/guarantee.md)")] = True
    certify_margin: Annotated[float, Field(ge=1.0, le=1e6, description=(
        "sampled certification: closing rounds end after N_eps(eps / (margin x edge share)) quiet runs near "
        "the failure-side boundary, so that a check (N_eps at eps, beta split over checks) usually passes "
        "at once (docs/certification.md)"), json_schema_extra={"hashed_when_default": False})] = CERTIFY_MARGIN
    certify_tolerance: Annotated[int, Field(ge=0, le=20, description=(
        "sampled certification: violations a check may see and still pass (the binomial test: its runs grow so "
        "that a set above eps passes with probability at most beta_i; 0: N_eps in a row, as validate). The "
        "checked set is exported unchanged (docs/certification.md)"),
        json_schema_extra={"hashed_when_default": False})] = CERTIFY_TOLERANCE

    @model_validator(mode="after")
    def _delta_order(self):
        if self.delta_min > self.delta0:
            raise ValueError("DELTA_ORDER")
        return self

    def settings(self) -> SPESettings:
        return SPESettings(**{name: getattr(self, name) for name in SPESettings.names()})


def _setting_field(f) -> tuple:
    """A pydantic field for one of the algorithm's settings (its declaration's type,
    choices, bounds and meaning)."""
    meta = f.metadata
    kind = Literal[meta["choices"]] if meta["choices"] else {"float": float, "int": int, "bool": bool,
                                                             "str": str}[str(f.type)]
    extra = {} if meta["hashed_when_default"] else {"json_schema_extra": {"hashed_when_default": False}}
    return Annotated[kind, Field(description=meta["doc"], **meta["bounds"], **extra)], f.default


QuantifyConfig = create_model("QuantifyConfig", __base__=_QuantifyBase, __module__=__name__,
                              **{f.name: _setting_field(f) for f in dataclass_fields(SPESettings)})


class VirtualConfig(Section):
    """[farm.virtual]: the simulated clock of the virtual farm (farm.executor = "virtual")."""

    run_time: Annotated[float, Field(gt=0.0, le=1e5, description="mean seconds of a full-horizon run")] = 1.0
    jitter: Annotated[float, Field(ge=0.0, le=5.0, description="lognormal sigma of a run's duration")] = 0.0
    call_cost: Annotated[float, Field(ge=0.0, le=60.0, description="seconds a chunk's call costs the "
                                                                    "coordinator and its worker")] = 0.001


class FarmConfig(Section):
    """[farm]: where and how runs are simulated."""

    executor: Annotated[Literal["ray", "local", "virtual"], Field(**_fixed())] = "local"
    workers: Annotated[int, Field(ge=1, le=4096, **_fixed("Ray actors (a local Ray: at most 4 per CPU, unless "
                                                          "farm.waiting), or the virtual farm's simulated workers"))] = 2
    waiting: Annotated[bool, Field(**_fixed(
        "the simulator waits on something else (a remote simulator server, a hardware-in-the-loop rig) "
        "rather than computing: a local Ray may then hold more than 4 actors per CPU, as many as "
        "farm.max_memory_gb allows"))] = False
    address: Annotated[str, Field(min_length=1, **_fixed(
        "'local', 'auto', 'host:port' or 'ray://host:port' (must answer within 3 s)"))] = "local"
    batch_size: Annotated[int, Field(ge=1, le=10_000_000, description="runs per drawn batch")] = 1024
    pipeline_depth: Annotated[int, Field(ge=1, le=64, description=(
        "batches drawn ahead, at most (fewer where runs are fast and come back before the head needs them)"))] = 2
    counting: Annotated[Literal["sequential", "deferred"], Field(description=(
        "coupled counting: a mispredicted run's replacement is waited for at the head (sequential: one "
        "result at any batch_size and pipeline_depth) or applied "
        "batch_size x pipeline_depth indices later (deferred: no waiting; its result depends on the window)"))] = \
        "sequential"
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
