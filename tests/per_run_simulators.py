"""Per-run simulators (scenarios/per_run.py) for tests, loaded as 'per_run_simulators:Class'.

``RowByRow`` is the scenario's own numpy step, one scene at a time: through the per-run
contract it must give what the numpy back end gives, bit for bit. The others break the
contract on purpose."""

import sys
import time

import numpy as np

from scenarios.per_run import RunSimulator


class RowByRow(RunSimulator):
    """The scenario's functional step on one state: a per-run simulator with a model."""

    sv_policy = "idm-row-by-row"

    def __init__(self, scenario, options=None):
        super().__init__(scenario, options)
        from scenarios.registry import make_scenario

        # the numpy twin of the declared scenario, with the SV policy the options name
        self.model = make_scenario(scenario.name, (options or {}).get("policy", "idm"))
        self.resets = 0

    def reset(self, state, key):
        self.resets += 1
        self.state = state.copy()
        return self.state

    def step(self, action):
        self.state = self.model.step(self.state[None, :], action[None, :], None)[0]
        return self.state


class Remembers(RowByRow):
    """Forgets to forget: the previous run's last gap leaks into the next run's steps."""

    def reset(self, state, key):
        self.carried = getattr(self, "state", state)[-1]
        return super().reset(state, key)

    def step(self, action):
        state = super().step(action)
        state[-1] += 1e-6 * self.carried
        return state


class Misplaces(RowByRow):
    """Cannot place the scene where asked (a simulator's insertion rules)."""

    def reset(self, state, key):
        return super().reset(state, key) + np.r_[np.zeros(len(state) - 1), 0.5]


class Keyed(RowByRow):
    """Draws a disturbance of its own from the run's key: runs depend on the key."""

    stochastic = True

    def reset(self, state, key):
        self.rng = key.generator()
        return super().reset(state, key)

    def step(self, action):
        return super().step(np.clip(action + self.rng.uniform(-0.5, 0.5, action.shape), -5.0, 3.0))


class Unfinished(RunSimulator):
    def reset(self, state, key):
        return state


class Still(RunSimulator):
    """Nothing moves: the cost of the per-run machinery alone (benchmarks)."""

    def reset(self, state, key):
        self.state = state
        return state

    def step(self, action):
        return self.state


def _hang():
    while True:  # a simulator that never answers (a lost socket, a deadlock)
        time.sleep(0.05)


class HangsInReset(RowByRow):
    def reset(self, state, key):
        _hang()


class HangsInStep(RowByRow):
    def step(self, action):
        _hang()


class HangsInClose(RowByRow):
    def close(self):
        _hang()


class RaisesInClose(RowByRow):
    def close(self):
        raise RuntimeError("the licence server went away")


class RaisesInStep(RowByRow):
    def step(self, action):
        raise ValueError("sim boom")


class ExitsInStep(RowByRow):
    def step(self, action):
        sys.exit(0)
