"""Scenario distributions D over Sigma: the law of a run's start state when a failure rate
is estimated (the traffic the controller will meet).

- ``ProductLaw``: independent per-axis laws (``Uniform``, ``Normal``, ``LogNormal``), each
  truncated to an interval inside Sigma. The mass of a box is the product of per-axis CDF
  differences, exactly; a draw inside a box is a per-axis inverse-CDF draw restricted to
  it, so a stratum made of grid cells is sampled exactly, without rejection.
- ``EmpiricalLaw``: recorded start states (naturalistic data), every row the same weight.

Draws take uniforms from the caller (the runs' keyed streams), so a start depends on
(seed, sample index) alone. Normal tails are computed on the side of the mean they lie
(``ndtr(-z)`` beyond it), so a cell 8 standard deviations out still has an accurate mass.
"""

from __future__ import annotations

import hashlib
import json
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

from scenarios.errors import ConfigError

MIN_MASS = 1e-12  # a law whose mass inside its interval is below this is refused (all of it lies outside Sigma)


class AxisLaw(ABC):
    """One state variable's law, truncated to ``[low, high]`` (inside Sigma)."""

    kind = ""

    def __init__(self, low: float, high: float):
        self.low, self.high = float(low), float(high)

    @abstractmethod
    def _base_mass(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """P(a <= X <= b) under the untruncated law (a <= b)."""

    @abstractmethod
    def _base_between(self, u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The untruncated law's inverse CDF restricted to [a, b] at ``u`` in [0, 1)."""

    @abstractmethod
    def parameters(self) -> dict:
        """The law's own parameters (for estimate.json and the hash)."""

    def total(self) -> float:
        """The untruncated law's mass inside [low, high] (what truncation divides by)."""
        return float(self._base_mass(np.array([self.low]), np.array([self.high]))[0])

    def masses(self, edges: np.ndarray) -> np.ndarray:
        """(m,) the truncated law's mass of each cell [edges[k], edges[k + 1]]; sums to 1
        when the edges span [low, high]."""
        a = np.clip(edges[:-1], self.low, self.high)
        b = np.clip(edges[1:], self.low, self.high)
        return np.where(b > a, self._base_mass(a, b), 0.0) / self.total()

    def between(self, u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(B,) draws of the truncated law restricted to [a, b] (per row), from ``u`` (B,)."""
        a = np.clip(a, self.low, self.high)
        b = np.clip(b, self.low, self.high)
        return np.clip(self._base_between(u, a, b), a, b)

    def describe(self) -> dict:
        return {"law": self.kind, **self.parameters(), "low": self.low, "high": self.high}


class Uniform(AxisLaw):
    kind = "uniform"

    def _base_mass(self, a, b):
        return np.maximum(b - a, 0.0)

    def _base_between(self, u, a, b):
        return a + u * (b - a)

    def parameters(self) -> dict:
        return {}


def _phi_interval(za: np.ndarray, zb: np.ndarray) -> np.ndarray:
    """P(za <= Z <= zb) for a standard normal Z, on the tail side of the interval."""
    with np.errstate(invalid="ignore"):
        return np.where(za > 0, ndtr(-za) - ndtr(-zb), ndtr(zb) - ndtr(za))


def _phi_between(u: np.ndarray, za: np.ndarray, zb: np.ndarray) -> np.ndarray:
    """The standard normal's inverse CDF restricted to [za, zb] at ``u`` (mirrored beyond
    the mean, where 1 - Phi has the digits Phi lacks)."""
    upper = za > 0
    lo = np.where(upper, ndtr(-zb), ndtr(za))
    hi = np.where(upper, ndtr(-za), ndtr(zb))
    z = ndtri(np.where(upper, hi - u * (hi - lo), lo + u * (hi - lo)))  # increasing in u on both sides
    return np.clip(np.where(upper, -z, z), za, zb)


class Normal(AxisLaw):
    kind = "normal"

    def __init__(self, mean: float, std: float, low: float, high: float):
        super().__init__(low, high)
        self.mean, self.std = float(mean), float(std)

    def _z(self, x):
        return (x - self.mean) / self.std

    def _base_mass(self, a, b):
        return _phi_interval(self._z(a), self._z(b))

    def _base_between(self, u, a, b):
        return self.mean + self.std * _phi_between(u, self._z(a), self._z(b))

    def parameters(self) -> dict:
        return {"mean": self.mean, "std": self.std}


class LogNormal(AxisLaw):
    """ln X ~ N(mu, sigma^2): median e^mu."""

    kind = "lognormal"

    def __init__(self, mu: float, sigma: float, low: float, high: float):
        super().__init__(low, high)
        self.mu, self.sigma = float(mu), float(sigma)

    def _z(self, x):
        with np.errstate(divide="ignore"):
            return (np.log(np.maximum(x, 0.0)) - self.mu) / self.sigma

    def _base_mass(self, a, b):
        return _phi_interval(self._z(a), self._z(b))

    def _base_between(self, u, a, b):
        return np.exp(self.mu + self.sigma * _phi_between(u, self._z(a), self._z(b)))

    def parameters(self) -> dict:
        return {"mu": self.mu, "sigma": self.sigma}


def _digest(description: dict, extra: bytes = b"") -> str:
    text = json.dumps(description, sort_keys=True, separators=(",", ":")).encode()
    return hashlib.sha256(text + extra).hexdigest()[:16]


@dataclass(frozen=True)
class ProductLaw:
    """Independent axes: D = law_1 x ... x law_n, each truncated to its [low, high]."""

    axes: tuple[AxisLaw, ...]
    state_names: tuple[str, ...]

    @property
    def low(self) -> np.ndarray:
        return np.array([a.low for a in self.axes])

    @property
    def high(self) -> np.ndarray:
        return np.array([a.high for a in self.axes])

    def draw_in_boxes(self, u: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(B, n) draws of D restricted to the boxes [lo, hi] (one per row), from ``u`` (B, n)."""
        return np.column_stack([law.between(u[:, i], lo[:, i], hi[:, i]) for i, law in enumerate(self.axes)])

    def sample(self, u: np.ndarray) -> np.ndarray:
        """(B, n) draws of D from ``u`` (B, n)."""
        b = len(u)
        return self.draw_in_boxes(u, np.broadcast_to(self.low, (b, len(self.axes))),
                                  np.broadcast_to(self.high, (b, len(self.axes))))

    def describe(self) -> dict:
        return {"kind": "product", "axes": {name: law.describe() for name, law in zip(self.state_names, self.axes)}}

    @property
    def digest(self) -> str:
        return _digest(self.describe())


@dataclass(frozen=True, eq=False)
class EmpiricalLaw:
    """Recorded start states ``points`` (R, n), each drawn with probability 1/R;
    ``source``: where they came from (file, sha256), for estimate.json."""

    points: np.ndarray
    state_names: tuple[str, ...]
    source: dict

    def sample(self, u: np.ndarray) -> np.ndarray:
        """(B, n) rows drawn from ``u`` (B,) or (B, k) (its first column)."""
        u0 = u[:, 0] if u.ndim == 2 else u
        rows = np.minimum((u0 * len(self.points)).astype(np.int64), len(self.points) - 1)
        return self.points[rows]

    def describe(self) -> dict:
        return {"kind": "empirical", "rows": len(self.points), **self.source}

    @property
    def digest(self) -> str:
        return _digest(self.describe(), np.ascontiguousarray(self.points, dtype=np.float64).tobytes())


def axis_law(field: str, law: str, params: dict, lower: float, upper: float) -> AxisLaw:
    """The law of one axis from its config table (``field``, e.g. "estimate.axes.v0", names
    it in errors), truncated to its ``low``/``high`` (default Sigma's [lower, upper])."""
    low = float(params.get("low", lower) if params.get("low") is not None else lower)
    high = float(params.get("high", upper) if params.get("high") is not None else upper)
    if not lower <= low < high <= upper:
        raise ConfigError(f"{field}: [low, high] = [{low:g}, {high:g}] is not an interval inside Sigma; allowed "
                          f"{lower:g} <= low < high <= {upper:g}")
    if law == "uniform":
        made = Uniform(low, high)
    elif law == "normal":
        made = Normal(params["mean"], params["std"], low, high)
    elif law == "lognormal":
        made = LogNormal(params["mu"], params["sigma"], low, high)
    else:
        raise ConfigError(f"{field}.law: {law!r} is not allowed; allowed: uniform, normal, lognormal")
    if not made.total() >= MIN_MASS:
        shown = ", ".join(f"{k} = {v:g}" for k, v in made.parameters().items())
        raise ConfigError(f"{field}: the {law} law ({shown}) puts no mass inside [{low:g}, {high:g}] (below "
                          f"{MIN_MASS:g}); move it into Sigma")
    return made


def empirical_law(field: str, points: np.ndarray, state_names, lower, upper, source: dict) -> EmpiricalLaw:
    """Recorded start states, refused in one line if empty, not finite or outside Sigma."""
    points = np.asarray(points, dtype=float)
    if len(points) == 0:
        raise ConfigError(f"{field}: {source.get('file', 'the data')} holds no rows; allowed: at least one start state")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ConfigError(f"{field}: row {row} of {source.get('file')} is not finite ({points[row].tolist()})")
    outside = (points < lower) | (points > upper)
    if outside.any():
        row, axis = (int(i[0]) for i in np.nonzero(outside))
        raise ConfigError(f"{field}: {int(outside.any(axis=1).sum())} of {len(points)} rows of {source.get('file')} "
                          f"lie outside Sigma (row {row}: {state_names[axis]} = {points[row, axis]:g}); allowed "
                          f"{state_names[axis]} in [{lower[axis]:g}, {upper[axis]:g}]")
    return EmpiricalLaw(points, tuple(state_names), source)
