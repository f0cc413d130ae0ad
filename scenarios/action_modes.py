"""The action policy a config's ``[actions]`` section names (``actions.mode``): the
basic policies of scenarios/actions.py and the search mixture of scenarios/search.py,
which builds on them."""

from __future__ import annotations

from scenarios.actions import (ActionPolicy, AdversarialActions, ConstantActions, FeedbackActions, UniformActions,
                               check_action)
from scenarios.base import Scenario
from scenarios.errors import ConfigError
from scenarios.search import SearchActions


def make_action_policy(mode: str, scenario: Scenario, value=None, policy: str | None = None) -> ActionPolicy:
    if mode == "uniform":
        return UniformActions()
    if mode == "adversarial":
        return AdversarialActions(deterministic=len(scenario.adversarial_actions) == 1)
    if mode == "constant":
        if value is None:
            raise ConfigError("actions.value: required for mode = 'constant'")
        values = value if isinstance(value, list) else [value]
        vals = check_action(values, scenario, "actions.value")
        return ConstantActions(vals)
    if mode == "search":
        return SearchActions(scenario)
    if mode == "feedback":
        if not policy:
            raise ConfigError("actions.policy: required for mode = 'feedback' ('package.module:function')")
        feedback = FeedbackActions(policy)
        feedback.check(scenario)
        return feedback
    raise ConfigError(f"actions.mode: unknown mode {mode!r}; allowed: uniform, adversarial, constant, feedback, search")
