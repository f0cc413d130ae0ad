"""Scenario action policies pi(sigma, t) for ``run_scenario`` (paper Alg. 1).

Each policy maps a batch of states and the runs' own streams to actions (B, m). Random
policies draw from each run's stream at counter ``t``, so a run's actions depend only on
its key (seed, index), never on its batch-mates.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field

import numpy as np

from scenarios.streams import PURPOSE_ACTION, RunStreams
from scenarios.base import Scenario
from scenarios.errors import ConfigError, ScenarioError
from scenarios.registry import load_object


class PolicyError(ScenarioError):
    """A feedback policy (user code) raised or returned the wrong shape during a run."""


class ActionPolicy:
    deterministic: bool = False
    description: str = ""

    def words(self, scenario: Scenario) -> str:
        """The actions in plain words, for the guarantee: 'with ... ' completes it."""
        return f"with actions {self.description}"

    def state(self) -> dict | None:
        """Adaptive state the coordinator ships with each batch (None: the policy is fixed
        by the config)."""
        return None

    def load(self, state: dict) -> None:
        """Take the coordinator's adaptive state (see ``state``)."""

    def __call__(self, scenario: Scenario, states: np.ndarray, t: int, streams: RunStreams) -> np.ndarray:
        """(B, m) actions of step ``t`` for runs in ``states`` (B, n) with ``streams``."""
        raise NotImplementedError


def describe_action(scenario: Scenario, values) -> str:
    """'the lead vehicle's acceleration at -5 m/s^2 and ...' for one action vector."""
    parts = []
    for name, value in zip(scenario.action_names, np.asarray(values, dtype=float).ravel()):
        unit = scenario.action_units.get(name, "")
        parts.append(f"{scenario.action_words.get(name, name)} at {value:g}{' ' + unit if unit else ''}")
    return " and ".join(parts)



@dataclass
class UniformActions(ActionPolicy):
    """u ~ U(Gamma), i.i.d. over steps and runs."""

    description: str = "u ~ U(Gamma)"

    def words(self, scenario):
        ranges = []
        for i, name in enumerate(scenario.action_names):
            unit = scenario.action_units.get(name, "")
            ranges.append(f"{scenario.action_words.get(name, name)} drawn uniformly from "
                          f"[{scenario.action_lower[i]:g}, {scenario.action_upper[i]:g}]{' ' + unit if unit else ''}")
        return "with " + " and ".join(ranges) + " at every step"

    def __call__(self, scenario, states, t, streams):
        u = streams.uniform(t, PURPOSE_ACTION, scenario.m)
        u *= scenario.action_span  # in place: runs every step
        u += scenario.action_lower
        return u


@dataclass
class AdversarialActions(ActionPolicy):
    """u ~ U(Gamma*), Gamma* the scenario's finite adversarial set (Definition 7)."""

    description: str = "u ~ U(Gamma*)"
    deterministic: bool = False  # True when Gamma* is a single action
    _rows: tuple | None = field(default=None, init=False, repr=False, compare=False)  # see _constant

    def words(self, scenario):
        options = scenario.adversarial_actions
        if len(options) == 1:
            return f"with {describe_action(scenario, options[0])} throughout (the worst case, Gamma*)"
        return ("with, at every step, one of " + "; ".join(describe_action(scenario, o) for o in options)
                + " drawn at random (the worst cases, Gamma*)")

    def __call__(self, scenario, states, t, streams):
        options = scenario.adversarial_actions
        if len(options) == 1:
            return self._constant(options, len(states))
        pick = np.minimum((streams.uniform(t, PURPOSE_ACTION, 1)[:, 0] * len(options)).astype(int), len(options) - 1)
        return options[pick]

    def _constant(self, options: np.ndarray, rows: int) -> np.ndarray:
        """``rows`` copies of the one action in ``options`` (a scenario's Gamma*), read-only:
        rows of an array kept for that Gamma* (this runs once per step; a fresh broadcast
        view costs more than the step's arithmetic on small batches)."""
        if self._rows is None or self._rows[0] is not options or len(self._rows[1]) < rows:
            tiled = np.tile(np.asarray(options[0], dtype=float), (max(rows, 1024), 1))
            tiled.flags.writeable = False
            self._rows = (options, tiled)
        return self._rows[1][:rows]


@dataclass
class ConstantActions(ActionPolicy):
    value: tuple[float, ...] = ()
    deterministic: bool = True

    @property
    def description(self) -> str:  # type: ignore[override]
        return f"u = {list(self.value)} (constant)"

    def words(self, scenario):
        return f"with {describe_action(scenario, self.value)} throughout"

    def __call__(self, scenario, states, t, streams):
        return np.broadcast_to(np.asarray(self.value, dtype=float), (len(states), scenario.m))


@dataclass
class FeedbackActions(ActionPolicy):
    """A deterministic feedback policy u = pi(sigma) (paper Problem 2), loaded from
    ``package.module:function``; the function maps (B, n) states to (B, m) actions."""

    target: str = ""
    deterministic: bool = True

    def __post_init__(self):
        self._fn = load_callable(self.target, "actions.policy", "states (B, n) -> actions (B, m)")

    @property
    def description(self) -> str:  # type: ignore[override]
        return f"u = pi(sigma), pi = {self.target}"

    def words(self, scenario):
        return f"with the actions chosen by the feedback policy {self.target}"

    def check(self, scenario: Scenario) -> None:
        """Call the policy on two start states now, so that a function of another shape
        (e.g. ``os:system``) is named in the config's terms, not as the scenario failing."""
        check_output(self._fn, self.target, "actions.policy", "states (B, n) -> actions (B, m)",
                     probe_states(scenario.lower, scenario.upper), scenario.m)

    def __call__(self, scenario, states, t, streams):
        try:
            u = np.asarray(self._fn(states), dtype=float).reshape(len(states), scenario.m)
        except Exception as exc:  # noqa: BLE001 - the user's policy: named as such, with the run
            raise PolicyError(f"actions.policy: {self.target!r} raised {type(exc).__name__}: {exc}") from None
        return np.clip(u, scenario.action_lower, scenario.action_upper)


def check_action(values, scenario: Scenario, field: str) -> tuple[float, ...]:
    """One action vector in Gamma: ``scenario.m`` numbers inside the bounds, or a one-line
    error naming ``field`` and the allowed range."""
    names = ", ".join(scenario.action_names)
    if not all(isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) for v in values):
        raise ConfigError(f"{field}: expected {scenario.m} number(s) ({names}), got {list(values)!r}")
    vals = tuple(float(v) for v in values)
    if len(vals) != scenario.m:
        raise ConfigError(f"{field}: expected {scenario.m} number(s) ({names}), got {list(vals)}")
    for v, lo, hi, name in zip(vals, scenario.action_lower, scenario.action_upper, scenario.action_names):
        if not lo <= v <= hi:
            raise ConfigError(f"{field}: {name} = {v:g} outside Gamma; allowed range [{lo:g}, {hi:g}]")
    return vals


def load_callable(target: str, field: str, signature: str):
    """A plugin function: import it and check it is a callable taking one argument."""
    fn = load_object(target, field)
    if not callable(fn) or isinstance(fn, type):
        raise ConfigError(f"{field}: {target!r} is not a function; expected a function {signature}")
    try:
        inspect.signature(fn).bind(None)
    except TypeError:
        raise ConfigError(f"{field}: {target!r} does not take one argument; expected a function {signature}") from None
    except ValueError:  # builtins without a signature: let the call decide
        pass
    return fn


def probe_states(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(2, n) start states inside [lo, hi] to try a plugin function on."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    return np.stack([0.75 * lo + 0.25 * hi, 0.25 * lo + 0.75 * hi])


def check_output(fn, target: str, field: str, signature: str, states: np.ndarray, per_state: int | None) -> None:
    """Call a plugin function on ``states`` (B, n) and check it answers B rows (of
    ``per_state`` numbers each; None: one value per state), or a one-line ConfigError."""
    shape = f"({len(states)}, {states.shape[1]})"
    try:
        out = np.asarray(fn(states), dtype=float)
    except Exception as exc:  # noqa: BLE001 - the user's function on plain start states
        raise ConfigError(f"{field}: {target!r} raised {type(exc).__name__} on a {shape} array of start states "
                          f"({' '.join(str(exc).split())}); expected a function {signature}") from None
    want = len(states) * (per_state or 1)
    if out.size != want or (per_state is None and out.shape != (len(states),)):
        raise ConfigError(f"{field}: {target!r} returned shape {out.shape} for a {shape} array of start states; "
                          f"expected a function {signature}")
