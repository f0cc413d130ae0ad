"""lead-follow with an artificial per-step cost: stands in for a slow black-box simulator
(a real one spends milliseconds per step in C++ or on a GPU, not in our process)."""

import time

from scenarios.lead_follow import LeadFollow

STEP_COST_S = 20e-6  # per run and step, like a simulator stepping every vehicle


class SlowLeadFollow(LeadFollow):
    name = "slow-lead-follow"

    def step(self, states, actions, noise):
        time.sleep(STEP_COST_S * len(states))
        return super().step(states, actions, noise)
