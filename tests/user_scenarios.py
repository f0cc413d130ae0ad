"""User scenarios loaded by 'package.module:Class' in tests: broken on purpose."""

import os
import time
from pathlib import Path

import numpy as np

from scenarios.base import Scenario
from scenarios.lead_follow import LeadFollow


class UnitSquare(Scenario):
    """A 2-D box whose step is left to the subclasses."""

    state_names = ("a", "b")
    lower = np.array([0.0, 0.0])
    upper = np.array([1.0, 1.0])
    failure_sides = {"a": False}
    action_names = ("u",)
    action_lower = np.array([0.0])
    action_upper = np.array([1.0])
    adversarial_actions = np.array([[1.0]])


class NaNScenario(UnitSquare):
    """Produces NaN for states with a > 0.5."""

    name = "nan"

    def step(self, states, actions, noise):
        out = states.copy()
        out[states[:, 0] > 0.5, 1] = np.nan
        return out


class Raising(UnitSquare):
    """Raises for any batch holding a state with a > 0.5 (the farm's error path)."""

    name = "raising"

    def step(self, states, actions, noise):
        if (states[:, 0] > 0.5).any():
            raise ValueError("boom")
        return states


HANG_MARKER = "FARM_TEST_HANG"  # environment: a file that, while it exists, makes Hanging hang


class Hanging(LeadFollow):
    """Lead-follow whose step sleeps for ever (a hung simulator) on a batch holding a state
    in the corner v0 > 19, v1 < 1 (the start state [19.5, 0.5, 68] is one), while the file
    named by $FARM_TEST_HANG exists (unset: always). When it starts to hang it creates that
    file's name + ".hung", so a test knows it hangs.

    The corner is wide enough that a run the small campaign of tests/farm/test_hangs.py
    must commit starts in it (sample index 551 of 1,805): with p10 > 66 as well it held
    only run 1937, drawn ahead past the campaign's end, which a Ray worker may never start
    before the campaign is done (a loaded machine: exit 0, not 4). Not in the first batch
    either (0-255, which the in-process executor runs before any run time is measured,
    under a limit of 10 minutes)."""

    name = "hanging"

    def step_into(self, states, actions, noise, out):
        corner = (states[:, 0] > 19.0) & (states[:, 1] < 1.0)
        if corner.any():
            marker = os.environ.get(HANG_MARKER)
            if marker:
                Path(marker + ".hung").touch()
            while marker is None or os.path.exists(marker):
                time.sleep(0.05)
        return super().step_into(states, actions, noise, out)


class Unbounded(UnitSquare):
    """Declares an infinite upper bound for b: no finite box Sigma."""

    name = "unbounded"
    upper = np.array([1.0, np.inf])

    def step(self, states, actions, noise):
        return states


def raising_policy(states):
    """A lead-follow feedback policy that raises once a run's v0 passes 18 m/s (after the
    config check, which calls it on states a quarter in from Sigma's corners)."""
    if (states[:, 0] > 18.0).any():
        raise ValueError("policy boom")
    return np.zeros((len(states), 1))


class BrokenInit(UnitSquare):
    """Its constructor fails, as one needing a licence server might."""

    name = "broken-init"

    def __init__(self, **kwargs):
        raise RuntimeError("no licence server")

    def step(self, states, actions, noise):
        return states


class NoBounds(Scenario):
    """Forgets Sigma's bounds."""

    name = "no-bounds"
    state_names = ("a",)
    failure_sides = {"a": False}
    action_names = ("u",)
    action_lower = np.array([0.0])
    action_upper = np.array([1.0])
    adversarial_actions = np.array([[1.0]])

    def step(self, states, actions, noise):
        return states


class HalfLead(LeadFollow):
    """Rewrites step() alone (not LeadFollow's vectorized step_into): the lead accelerates
    half as hard. The farm must simulate this step, not the parent's dynamics."""

    name = "half-lead"

    def step(self, states, actions, noise):
        return super().step(states, 0.5 * actions, noise)


class ExitsInStep(LeadFollow):
    """Calls sys.exit(0) in its step: no verdict can come of that."""

    name = "exits"

    def step_into(self, states, actions, noise, out):
        raise SystemExit(0)


class JumpsHigh(UnitSquare):
    """Its step_bound() holds below a = 0.5 only: a run started higher jumps 0.4 along b
    per step, four times the bound (a wrong sigma-bar that the first batch's check catches)."""

    name = "jumps-high"

    def step_bound(self):
        return 0.1

    def step(self, states, actions, noise):
        out = states.copy()
        out[:, 1] += np.where(states[:, 0] > 0.5, 0.4, 0.01)
        return out
