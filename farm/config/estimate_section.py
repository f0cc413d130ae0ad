"""[estimate]: a failure rate beside the set (``scenario-farm estimate DIR``): the scenario
distribution D over Sigma, the strata, the stopping rule and a second controller to
compare. Checks that need the scenario (state names, Sigma's bounds, the data file's
columns) run when the estimate is set up (farm/jobs/estimate_setup.py)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from farm.config.sections import Probability, Section


class AxisLawConfig(Section):
    """[estimate.axes.<state variable>]: one axis of a product law, truncated to [low, high]
    (default: Sigma's bounds on that axis)."""

    law: Annotated[Literal["uniform", "normal", "lognormal"], Field(description="the axis's law")]
    mean: Annotated[float | None, Field(description="normal: mean, in the state variable's unit")] = None
    std: Annotated[float | None, Field(gt=0.0, description="normal: standard deviation")] = None
    mu: Annotated[float | None, Field(description="lognormal: mean of ln x (median e^mu)")] = None
    sigma: Annotated[float | None, Field(gt=0.0, description="lognormal: standard deviation of ln x")] = None
    low: Annotated[float | None, Field(description="truncation: lower end, inside Sigma")] = None
    high: Annotated[float | None, Field(description="truncation: upper end, inside Sigma")] = None


class VersusConfig(Section):
    """[estimate.versus]: the second controller of a paired comparison: the campaign's
    [scenario] with these keys replaced, run on the same starts and streams."""

    sv_policy: Annotated[str | None, Field(min_length=1, description="another SV policy (brake | idm | ...)")] = None
    name: Annotated[str | None, Field(min_length=1, description="another version of your scenario "
                                                                "('package.module:Class')")] = None


class EstimateConfig(Section):
    """[estimate]: P(failure) of runs started from D, with an interval."""

    distribution: Annotated[Literal["uniform", "axes", "empirical"], Field(description=(
        "uniform over Sigma | axes: independent per-axis laws ([estimate.axes]) | empirical: recorded start "
        "states (estimate.data)"))] = "uniform"
    axes: Annotated[dict[str, AxisLawConfig] | None, Field(description=(
        "per state variable its law (distribution = 'axes'); unnamed variables are uniform over Sigma"))] = None
    data: Annotated[str | None, Field(min_length=1, description=(
        "a Parquet file of recorded start states, one column per state variable (distribution = 'empirical')"))] = None
    strata: Annotated[Literal["set", "none"], Field(description=(
        "set: strata inside, across the boundary of and outside the campaign's safe set; none: plain Monte "
        "Carlo"))] = "set"
    band: Annotated[int, Field(ge=1, le=16, description="layers of grid cells on each side of the set's boundary, "
                                                        "each a stratum")] = 2
    runs: Annotated[int, Field(ge=1, le=10**12, description="the budget: runs at most")] = 100_000
    relative_error: Annotated[float | None, Field(gt=0.0, lt=1.0, description=(
        "stop at the first stage end where the interval's half-width is at most this share of the estimate"))] = None
    confidence: Annotated[Probability, Field(description="the interval's level")] = 0.95
    pilot: Annotated[int, Field(ge=1, le=10**9, description="runs of the first stage (split equally among the "
                                                            "strata)")] = 1000
    horizon: Annotated[int | None, Field(ge=2, le=100_000, description="K states per run (default: "
                                                                       "quantify.horizon)")] = None
    seed: Annotated[int | None, Field(ge=0, le=2**63 - 1, description=(
        "the estimate's streams (default: derived from farm.seed, apart from the campaign's)"))] = None
    versus: Annotated[VersusConfig | None, Field(description="a second controller, compared on the same runs")] = None
