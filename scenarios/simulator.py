"""What a worker holds: a scenario on a back end, an action policy, the horizon and the
campaign seed. Built from ``SimSpec``, plain data that is cheap to ship to a process."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios.action_modes import make_action_policy
from scenarios.actions import PolicyError
from scenarios.errors import ScenarioError
from scenarios.registry import make_backend
from scenarios.rollout import RunBatch, run_scenario
from scenarios.streams import RunStreams


@dataclass(frozen=True)
class SimSpec:
    """Everything a worker needs to simulate: plain data, cheap to ship."""

    scenario: dict  # the [scenario] config section
    actions: dict  # the [actions] config section
    horizon: int
    seed: int
    deep_margins: bool = False  # failed runs' margins as deep as the runs would go (scenarios/rollout.py)


class Simulator:
    """Simulates batches of runs ``first_index, first_index + 1, ...`` from given starts.

    Every simulator checks the scenario's ``step_bound()`` against the steps it observes
    in its first batch (and in every batch when ``check_step_bound``): a wrong sigma-bar
    would silently break the boundary-band guarantees (Theorem 3)."""

    def __init__(self, spec: SimSpec, check_step_bound: bool = False):
        self.spec = spec
        self.backend = make_backend(spec.scenario)
        self.scenario = self.backend.scenario
        act = spec.actions
        self.policy = make_action_policy(act.get("mode", "uniform"), self.scenario, act.get("value"),
                                         act.get("policy"))
        self.check_step_bound = check_step_bound
        self._checked = False

    @property
    def deterministic(self) -> bool:
        """A run is a function of its start state alone (one action, no disturbance)."""
        return self.policy.deterministic and self.scenario.disturbance == 0 and self.backend.deterministic

    def simulate(self, first_index: int, starts: np.ndarray, indices: np.ndarray | None = None,
                 actions: dict | None = None, rest_follows: bool = False) -> RunBatch:
        """Runs ``first_index, first_index + 1, ...`` (or the given sample ``indices``)
        from ``starts``. ``actions``: the policy's adaptive state (``policy.state()``, e.g.
        the search mixture's weight schedule) as the coordinator has it now; None keeps
        the last one given. ``rest_follows``: these are the first runs of a batch whose
        rest the next call simulates (an executor's one-run probe): the check of the step
        bound in the first batch then covers the whole batch, not the probe alone."""
        if actions is not None:
            self.policy.load(actions)
        if indices is None:
            indices = np.arange(first_index, first_index + len(starts), dtype=np.uint64)
        indices = np.asarray(indices, dtype=np.uint64)
        check = self.check_step_bound or not self._checked
        try:
            batch = run_scenario(self.backend, starts, self.spec.horizon, self.policy,
                                 RunStreams.of(self.spec.seed, indices), check_step_bound=check,
                                 deep_margins=self.spec.deep_margins)
        except PolicyError as exc:  # the feedback policy raised: name the run, as for a scenario
            raise self._culprit(indices, starts, exc) from None
        except ScenarioError:
            raise
        except (Exception, SystemExit) as exc:  # a user scenario raised (or sys.exit): name the run, not the batch
            raise self._culprit(indices, starts, exc) from None
        self._checked = self._checked or not rest_follows
        keep = int(batch.lengths.max()) if len(batch) else 1  # only the rows some run used
        return RunBatch(batch.indices, np.ascontiguousarray(batch.trajectories[:keep]), batch.lengths,
                        batch.outcomes, batch.exits, batch.margins)

    def _culprit(self, indices, starts, exc) -> ScenarioError:
        """Bisect the batch (runs depend on their own key only) down to the first run that
        raises on its own."""
        lo, hi = 0, len(starts)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            try:
                run_scenario(self.backend, starts[lo:mid], self.spec.horizon, self.policy,
                             RunStreams.of(self.spec.seed, indices[lo:mid]))
                lo = mid
            except (Exception, SystemExit):  # noqa: BLE001 - any error narrows the search
                hi = mid
        policy = isinstance(exc, PolicyError)
        method = _method_left(self.scenario, exc)
        what = str(exc) if policy else (f"scenario {self.scenario.error_name!r}{f': {method}()' if method else ''} "
                                        f"raised {type(exc).__name__}: {exc}")
        return (PolicyError if policy else ScenarioError)(f"{what} on sample index {int(indices[lo])} (start state "
                                                          f"{starts[lo].tolist()})")


def _method_left(scenario, exc: BaseException) -> str | None:
    """The scenario's method that ``exc`` left (the innermost frame of the scenario's own
    in its traceback: a user's ``step``, not the run loop's ``step_into`` around it), or None."""
    method, tb = None, exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_locals.get("self") is scenario:
            method = tb.tb_frame.f_code.co_name
        tb = tb.tb_next
    return method
