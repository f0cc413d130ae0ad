"""``run_scenario`` (paper Alg. 1) for a batch of runs, with classification.

Every step's new states are classified continue / truncated / failure (failure wins);
a run ends at its first non-continue state or after K states (the start counts as the
first). The returned trajectories hold every state of every run, the terminal one
included, so a run can be checked and replayed state by state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios.streams import PURPOSE_DISTURBANCE, RunStreams
from scenarios.actions import ActionPolicy
from scenarios.base import CONTINUE, FAILURE, HORIZON, Scenario, ScenarioError


# Compact the stepped rows once fewer than this share of them still run.
COMPACT_BELOW = 0.75


@dataclass
class RunBatch:
    """Results of a batch of runs.

    indices       (B,) uint64 global sample indices (the runs' stream keys with the seed)
    trajectories  (K, B, n) states; entries past a run's length are meaningless
    lengths       (B,) int32 number of states in each run (start included, >= 1)
    outcomes      (B,) int8 FAILURE / TRUNCATED / HORIZON
    """

    indices: np.ndarray
    trajectories: np.ndarray
    lengths: np.ndarray
    outcomes: np.ndarray

    @property
    def starts(self) -> np.ndarray:
        return self.trajectories[0]

    @property
    def steps(self) -> int:
        return int(self.lengths.sum() - len(self.lengths))

    def __len__(self) -> int:
        return len(self.indices)

    def trajectory(self, row: int) -> np.ndarray:
        """(length, n) states of one run."""
        return self.trajectories[: self.lengths[row], row]

    def take(self, rows) -> "RunBatch":
        rows = np.asarray(rows)
        k = int(self.lengths[rows].max()) if len(rows) else 1
        return RunBatch(self.indices[rows], self.trajectories[:k, rows], self.lengths[rows], self.outcomes[rows])


def run_scenario(
    scenario: Scenario,
    starts: np.ndarray,
    horizon: int,
    policy: ActionPolicy,
    streams: RunStreams,
) -> RunBatch:
    """Run a batch from ``starts`` (B, n) for up to ``horizon`` states each.

    A back end whose SV keeps internal state (a real simulator) provides its own
    ``rollout`` with these semantics; the functional ``step`` loop below is for the rest."""
    if horizon < 2:
        raise ValueError(f"horizon: K must be >= 2, got {horizon}")
    rollout = getattr(scenario, "rollout", None)
    if rollout is not None:
        return rollout(np.asarray(starts, dtype=float), horizon, policy, streams)
    starts = np.asarray(starts, dtype=float)
    batch, n = starts.shape
    if n != scenario.n:
        raise ScenarioError(f"start states have {n} columns, scenario {scenario.name!r} has {scenario.n}")
    # Stored as (K, n, B) so that each step writes n contiguous rows; exposed as (K, B, n).
    store = np.empty((horizon, n, batch))
    store[0] = starts.T
    lengths = np.full(batch, horizon, dtype=np.int32)
    outcomes = np.full(batch, HORIZON, dtype=np.int8)
    disturbed = scenario.disturbance > 0.0 and scenario.noise_width > 0
    rows = np.arange(batch)  # batch rows still being stepped (some may have ended)
    running = np.ones(batch, dtype=bool)  # ... of which these have not ended
    full = True  # rows == arange(batch)
    row_streams = streams
    states = starts
    for t in range(1, horizon):
        actions = policy(scenario, states, t, row_streams)
        noise = row_streams.uniform(t, PURPOSE_DISTURBANCE, scenario.noise_width) if disturbed else None
        # all rows stepped: straight into the store; after compaction: scattered there
        slab = store[t] if full else np.empty((n, len(rows)))
        scenario.step_into(states, actions, noise, slab)
        nxt = slab.T
        status = scenario.classify(nxt)
        if not full:
            store[t][:, rows] = slab
        ended = running & (status != CONTINUE)
        # one pass: a sum is finite iff every term is (or it overflowed, which the exact
        # per-row check below then clears); the per-row search only on error
        if not np.isfinite(np.add.reduce(slab, axis=None)):
            bad = ~np.isfinite(nxt).all(axis=1) & running
            if bad.any():
                _raise_bad_state(scenario, nxt, rows, bad, streams, starts, t)
        if ended.any():
            done = rows[ended]
            outcomes[done] = status[ended]
            lengths[done] = t + 1
            running &= ~ended
            alive = int(running.sum())
            if alive == 0:
                break
            # Ended rows keep being stepped (cheaper than a gather every step) until they
            # are a share of the rows: then compact.
            if alive < COMPACT_BELOW * len(rows):
                # gathered as (n, k) rows, so that the states stay column-contiguous: a
                # row-major (k, n) gather would make every later column op strided
                rows, nxt = rows[running], np.compress(running, nxt.T, axis=1).T
                row_streams = row_streams.subset(running)
                running = np.ones(len(rows), dtype=bool)
                full = False
        states = nxt
    return RunBatch(streams.indices, store.transpose(0, 2, 1), lengths, outcomes)


def _raise_bad_state(scenario, nxt, rows, bad, streams, starts, t):
    row = int(np.nonzero(bad)[0][0])
    run = int(rows[row])
    raise ScenarioError(
        f"scenario {scenario.name!r} produced a non-finite state at step {t} of sample index "
        f"{int(streams.indices[run])} (start state {starts[run].tolist()}): {nxt[row].tolist()}"
    )


def failed(batch: RunBatch) -> np.ndarray:
    return batch.outcomes == FAILURE
